"""The PDF report of every shipped scene prints as a document: A4 pages of one size, "page i
of N" on each, the running header (scene name, toolkit version, date; the scene file's
SHA-256 in the footer) on one line per box, the title page's contents and sign-off, numbered
sections and figures, the scene's parameter tables under their headings and the requirement
rows; no word of a table or text past the page's margins, no text of a figure past its frame
or over another, no page left holding one small figure, and the reference list at the end.
Each scene's report is written once for the session (``scene_report`` in conftest)."""

from __future__ import annotations

import hashlib
import html as html_lib
import re
import subprocess
from types import SimpleNamespace

import pytest

from servo_toolkit.core.version import __version__

from .conftest import SCENE_FILES, SCENES
from .pdf_words import PRINT_MARGINS_PT, outside_frame, poppler, require_poppler, words

#: page size in PostScript points (1/72 in)
A4_PT = (210 / 25.4 * 72, 297 / 25.4 * 72)
#: the page margins of the print stylesheet (pt): the running header above, the footer below
TOP_PT, BOTTOM_PT = PRINT_MARGINS_PT[0], PRINT_MARGINS_PT[2]


def _require_tools():
    require_poppler()
    from servo_toolkit.report.pdf_writer import paged_engine
    if paged_engine() is None:
        pytest.skip("WeasyPrint cannot load Pango here: the report writes the plain fallback PDF")


def _png_sizes(pdf, folder):
    """(width, height) in pixels of every page rendered by pdftoppm at 20 dpi."""
    subprocess.run(["pdftoppm", "-r", "20", "-png", str(pdf), str(folder / "page")], check=True, timeout=300)
    sizes = []
    for png in sorted(folder.glob("page*.png")):
        head = png.read_bytes()[16:24]  # the IHDR chunk: width and height
        sizes.append((int.from_bytes(head[:4], "big"), int.from_bytes(head[4:], "big")))
    return sizes


@pytest.fixture(scope="module", params=[p.stem for p in SCENE_FILES])
def typeset(request, scene_report, tmp_path_factory):
    """One shipped scene's report: its PDF read back page by page."""
    _require_tools()
    run = scene_report(request.param)
    pdf = run.folder / "report.pdf"
    assert pdf.exists(), (run.code, run.err[-2000:])
    html = (run.folder / "index.html").read_text(encoding="utf-8")
    text = poppler("pdftotext", "-layout", str(pdf), "-")
    pages = text.split("\f")
    if pages and not pages[-1].strip():
        pages = pages[:-1]
    return SimpleNamespace(name=request.param, run=run, pdf=pdf, html=html, pages=pages, words=words(pdf),
                           sizes=_png_sizes(pdf, tmp_path_factory.mktemp("pages")),
                           whole=" ".join(" ".join(pages).split()))


def test_every_page_is_a4_and_numbered(typeset):
    assert typeset.run.code in (0, 1), typeset.run.err[-2000:]
    n = len(typeset.pages)
    assert n >= 3 and len(typeset.sizes) == n == len(typeset.words)
    assert len(set(typeset.sizes)) == 1, "every page has the same size"
    (w, h), = set(typeset.sizes)
    assert w == pytest.approx(A4_PT[0] / 72 * 20, abs=1.5) and h == pytest.approx(A4_PT[1] / 72 * 20, abs=1.5)
    for width, height, _ in typeset.words:
        assert (width, height) == pytest.approx(A4_PT, abs=0.5)
    for i, page in enumerate(typeset.pages, 1):
        assert f"page {i} of {n}" in page, (typeset.name, i)


def test_running_header_and_footer_name_the_scene_on_one_line_per_box(typeset):
    digest = hashlib.sha256((SCENES / f"{typeset.name}.toml").read_bytes()).hexdigest()
    date = re.search(r"<tr><th>date</th><td>([^<]+)</td>", typeset.html).group(1)
    for i, (width, height, words) in enumerate(typeset.words, 1):
        head = [w for w in words if w[3] < TOP_PT]
        foot = [w for w in words if w[1] > height - BOTTOM_PT]
        head_text, foot_text = " ".join(w[4] for w in head), " ".join(w[4] for w in foot)
        assert typeset.name in head_text, (i, head_text)
        assert f"servo_toolkit {__version__}" in head_text and date in head_text, (i, head_text)
        assert f"SHA-256 {digest}" in foot_text and f"page {i} of {len(typeset.words)}" in foot_text, (i, foot_text)
        for box in (head, foot):  # one line: every word of a box on one baseline (a wrap is a line lower)
            left = [w for w in box if w[0] < width / 2]
            right = [w for w in box if w[0] >= width / 2]
            for part in (left, right):
                if part:
                    assert max(w[3] for w in part) - min(w[3] for w in part) < 2.0, (typeset.name, i, part)
            assert max(w[3] for w in box) - min(w[3] for w in box) < 3.0, (typeset.name, i, box)


def test_title_page_contents_sign_off_and_numbered_figures(typeset):
    first = typeset.pages[0]
    for words in ("Contents", "prepared", "checked", "approved", "signature", "scene file SHA-256"):
        assert words in first, (typeset.name, words)
    # every section numbered in the contents with the page it starts on
    titles = re.findall(r'<section id="[^"]+" data-status="[^"]+">\s*<h2>(\d+)\. ([^<]+)</h2>', typeset.html)
    assert titles and titles[0][1] == "Requirements"
    contents = " ".join(first.split()) + " " + " ".join(" ".join(p.split()) for p in typeset.pages[1:3])
    for number, title in titles:
        page = re.search(rf"{number}\. {re.escape(html_lib.unescape(title)[:30])}.*?\.{{3,}} ?(\d+)", contents)
        assert page, (typeset.name, number, title)
        start = int(page.group(1))
        assert f"{number}. {html_lib.unescape(title)[:30]}" in " ".join(typeset.pages[start - 1].split()), (
            typeset.name, number, title, start)
    figures = typeset.html.count('<img class="report-figure"')
    assert len(set(re.findall(r"Figure \d+\.\d+\.", typeset.whole))) == figures


def test_scene_tables_have_their_headings_and_the_requirement_rows(typeset):
    summary = re.search(r'<section id="scene".*?</section>', typeset.html, re.S).group(0)
    headings = [html_lib.unescape(h) for h in re.findall(r"<h3>([^<]+)</h3>", summary)]
    assert headings, typeset.name
    for heading in headings:
        assert " ".join(heading.split()) in typeset.whole, (typeset.name, heading)
    ids = re.findall(r'<table id="requirements-table">.*?</table>', typeset.html, re.S)
    rows = re.findall(r"<tr><td>([a-z0-9_]+)</td>", ids[0]) if ids else []
    for rid in rows:
        assert rid in typeset.whole, (typeset.name, rid)


def test_no_table_or_text_runs_past_the_margins(typeset):
    """Every word of the page's body within the left and right margins (the stiffness
    table's last column ran past the right edge) and within the page."""
    outside = outside_frame(typeset.words, PRINT_MARGINS_PT)
    assert not outside, (typeset.name, outside[:10])


def test_every_figure_keeps_its_text_within_its_frame(typeset):
    """Each figure is checked when its section is built (:func:`servo_toolkit.report.figures.
    layout_problems`: titles, labels, legends and annotations within the figure or their axes,
    none over another, no two legend entries drawn alike); the command names any it finds."""
    lines = [line for line in typeset.run.err.splitlines() if "servo-toolkit: layout of section" in line]
    assert not lines, (typeset.name, lines)


def test_no_page_holds_one_small_figure_alone(typeset):
    """A page whose body is one figure and its caption fills at least half the page: a small
    figure shares its page with the text around it."""
    for i, (width, height, found) in enumerate(typeset.words[1:], 2):
        body = [w for w in found if w[1] > TOP_PT and w[3] < height - BOTTOM_PT]
        captions = [w for w in body if re.fullmatch(r"Figure", w[4])]
        if len(captions) != 1:
            continue
        line = captions[0][3]
        if all(abs(w[3] - line) < 2.0 for w in body) and line < height / 2:
            raise AssertionError((typeset.name, i, "one small figure alone on the page"))


def test_methods_are_named_with_their_source_and_listed_at_the_end(typeset):
    whole = typeset.whole
    internal = re.search(r"\bseeds? 00\d|\bpaper scheme|LossyGear-like|of \d(\.\d+)?e[+-]\d+ ms", whole, re.I)
    assert not internal, (typeset.name, whole[max(0, internal.start() - 80):internal.end() + 80])
    last = " ".join(" ".join(p.split()) for p in typeset.pages[-2:]).replace("- ", "-")  # a title wrapped at its hyphen
    assert "References" in last and "LIU Hai, DUAN Xiao-shuai, HUANG Jian" in last, typeset.name
    for title in ("A Stiffness Calculation Method of Servo Mechanism", "Rigid-Body Dynamic Analysis of Multi-Stage"):
        assert title in last, (typeset.name, title)
