"""The report's tables and labels stay within their frames: a table of many columns wraps its
cells in narrow type within the page's margins, in the PDF and on the HTML page."""

from __future__ import annotations

import pytest

from servo_toolkit import load_scene
from servo_toolkit.report.builder import Report, run_section
from servo_toolkit.report.context import Context
from servo_toolkit.report.document import render
from servo_toolkit.report.sections_drivetrain import stiffness_chain

from .pdf_words import DEFAULT_MARGIN_PT, PRINT_MARGINS_PT, outside_frame, require_poppler, words


@pytest.fixture(scope="module")
def stiffness_section():
    section = run_section("stiffness", "Stiffness chain and compliance shares", stiffness_chain,
                          Context(load_scene()))
    assert section.status == "info", section.reason
    return section


#: the HTML page as a browser shows it: a window as wide as the page's widest body (1100 px)
SCREEN = "@page{size:1250px 1800px}"


def _typeset(section, target, path):
    from servo_toolkit.report.pdf_writer import paged_engine
    weasyprint = paged_engine()
    if weasyprint is None:
        pytest.skip("WeasyPrint cannot load Pango here")
    report = Report("ema_reference", "the stiffness table alone", (section,), ())
    sheets = [weasyprint.CSS(string=SCREEN)] if target == "html" else []
    weasyprint.HTML(string=render(report, target), base_url=".").write_pdf(str(path), stylesheets=sheets)
    return words(path)


@pytest.mark.parametrize("target, margins", [("pdf", PRINT_MARGINS_PT), ("html", (DEFAULT_MARGIN_PT,) * 4)])
def test_the_stiffness_table_stays_within_the_margins(stiffness_section, target, margins, tmp_path):
    """Eleven columns (three stroke points of stiffness and of share, the criterion's columns):
    every word of the table within the page's margins, its last column's heading whole."""
    require_poppler()
    assert '<div class="wide-table"><table id="stiffness-table">' in stiffness_section.html
    pages = _typeset(stiffness_section, target, tmp_path / f"{target}.pdf")
    assert not outside_frame(pages, margins), outside_frame(pages, margins)[:10]
    text = " ".join(w[4] for page in pages for w in page[2])
    for word in ("may", "be", "neglected", "series", "total"):
        assert word in text.split(), word
