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


def _panel_figure(title="A title long enough to run past its axes when a legend takes the right edge"):
    from servo_toolkit.report.figures import new_figure
    fig, ax = new_figure(size=(5.0, 3.0))
    ax.plot([0, 1], [0, 1], label="first curve with a long legend label")
    ax.plot([0, 1], [1, 0], label="second curve")
    ax.legend()
    ax.set_title(title)
    return fig, ax


def test_a_title_over_the_legend_or_past_the_figure_is_seen_and_wrapped():
    """The figure legend sits outside the axes at the right edge, beside a centred title: a
    title wider than its axes runs under the legend (or off the figure's left edge, as the
    controller's did). The check names it; :func:`finish` wraps the title so it fits."""
    from servo_toolkit.report.figures import finish, layout_problems, legends_outside
    fig, ax = _panel_figure()
    legends_outside(fig)
    problems = layout_problems(fig)
    assert any("title" in p and ("overlaps figure legend" in p or "outside the figure" in p) for p in problems), problems
    fig, ax = _panel_figure()
    assert finish(fig) == ()
    assert "\n" in ax.get_title()


def test_an_annotation_past_its_axes_and_curves_drawn_alike_are_seen():
    from servo_toolkit.report.figures import layout_problems, new_figure
    fig, (a, b) = new_figure(1, 2)
    a.plot([1, 2], [1, 2], "C0", label="feedback alone")
    b.plot([1, 2], [2, 1], "C0", label="fixed gains")  # another curve, the same colour and line
    a.annotate("GM 178.0 dB @ 3.76e+03 Hz", (1.95, 1.5))
    a.legend()
    b.legend()
    problems = layout_problems(fig)
    assert any("GM 178.0 dB" in p and "outside its axes" in p for p in problems), problems
    assert any("'feedback alone' and 'fixed gains' are drawn alike" in p for p in problems), problems


def test_a_log_axis_of_less_than_two_decades_has_plain_tick_labels():
    from servo_toolkit.report.figures import finish, new_figure
    fig, ax = new_figure()
    ax.semilogy([0, 1, 2], [0.2, 1.0, 2.3])
    finish(fig)
    labels = [t.get_text() for t in ax.get_yticklabels(which="both") if t.get_text()]
    assert labels and not any("10^" in t or "times" in t for t in labels), labels
    assert "1" in labels and "2" in labels


@pytest.fixture(scope="module")
def reference_sections():
    """The reference EMA's sections whose figures carried the legends over their titles, the
    controller's title past the left edge, the gain margin's label past the axes and the
    feedforward's curves drawn alike."""
    from servo_toolkit.report.builder import SECTIONS
    ctx = Context(load_scene())
    keys = ("stiffness", "plant", "controller", "loop", "stroke", "closed_loop", "poles", "command")
    return [run_section(key, title, build, ctx) for key, title, build in SECTIONS if key in keys]


def test_the_reference_figures_keep_every_text_within_its_frame(reference_sections):
    from servo_toolkit.report.figures import layout_problems
    assert len(reference_sections) == 8
    for section in reference_sections:
        assert section.status == "info", (section.title, section.reason)
        assert section.figures and section.layout == (), (section.title, section.layout)
        for spec in section.figures:
            assert layout_problems(spec.figure) == (), (section.title, spec.caption)


def test_the_gain_margin_bar_lies_within_the_magnitude_axes(reference_sections):
    """Every margin bar is drawn whole: the magnitude axes reach down to the bottom of the
    178 dB gain margin's bar at 3.76 kHz."""
    loop = next(s for s in reference_sections if s.key == "loop")
    am = loop.figures[0].figure.axes[0]
    lo, hi = am.get_ylim()
    bars = [line for line in am.lines if len(line.get_xdata()) == 2 and line.get_xdata()[0] == line.get_xdata()[1]]
    assert bars
    for bar in bars:
        assert lo <= min(bar.get_ydata()) and max(bar.get_ydata()) <= hi


def test_legend_entries_of_markers_only_are_compared_too():
    """A scatter's legend entry (a collection: a list of dash patterns, no line colour) is
    compared like a line's; two scatters of one colour under different names are seen."""
    from servo_toolkit.report.figures import finish, new_figure

    def scatters(*colours):
        fig, ax = new_figure()
        for k, colour in enumerate(colours):
            ax.scatter([1, 2], [k, k + 1], color=colour, label=f"set {k}")
        ax.plot([1, 2], [1, 1], "k--", label="limit")
        ax.legend()
        return finish(fig)
    assert scatters("C0", "C3") == ()
    assert any("'set 0' and 'set 1' are drawn alike" in p for p in scatters("C3", "C3"))


def _style_of(page: str, selector: str) -> dict:
    """The declarations the page's stylesheet gives ``selector`` (later rules win)."""
    import re
    css = re.search(r"<style>(.*?)</style>", page, re.S).group(1)
    css = re.sub(r"/\*.*?\*/", "", css, flags=re.S)
    found = {}
    for selectors, body in re.findall(r"([^{}]+)\{([^{}]*)\}", css):
        if selector in (s.strip() for s in selectors.split(",")):
            for decl in body.split(";"):
                if ":" in decl:
                    name, value = decl.split(":", 1)
                    found[name.strip()] = value.strip()
    return found


def test_a_wide_table_scrolls_in_its_wrapper_on_a_narrow_window_and_not_in_the_pdf(stiffness_section):
    """On the HTML page the stiffness table's wrapper scrolls sideways (its cells keep their
    numbers on one line, wider than a window below 900 px); in the PDF it stays whole within
    the page, as before."""
    import re
    report = Report("ema_reference", "the stiffness table alone", (stiffness_section,), ())
    html, pdf = render(report, "html"), render(report, "pdf")
    assert re.search(r'<div class="wide-table"><table id="stiffness-table">.*?</table></div>', html, re.S)
    screen = _style_of(html, ".wide-table")
    assert screen.get("overflow-x") == "auto" and screen.get("max-width") == "100%"
    printed = _style_of(pdf, ".wide-table")
    assert printed.get("overflow") == "visible" and printed.get("max-width") == "none"


def test_a_narrow_browser_window_scrolls_the_stiffness_table_not_the_page(stiffness_section, tmp_path):
    """Headless Chromium at 800 px: the page is no wider than the window, the table's wrapper
    is (so it scrolls) and holds the whole table."""
    import json
    import re
    import shutil
    import subprocess
    browser = next((shutil.which(n) for n in ("chromium", "chromium-browser", "google-chrome") if shutil.which(n)),
                   None)
    if browser is None:
        pytest.skip("no Chromium found (Debian package chromium)")
    probe = """<script>window.addEventListener('load', () => {
      const w = document.querySelector('.wide-table'), t = document.getElementById('stiffness-table');
      document.body.setAttribute('data-probe', JSON.stringify({window: window.innerWidth,
        page: document.documentElement.scrollWidth, wrapper: w.clientWidth, scroll: w.scrollWidth,
        table: t.getBoundingClientRect().width}));});</script>"""
    report = Report("ema_reference", "the stiffness table alone", (stiffness_section,), ())
    page = tmp_path / "narrow.html"
    page.write_text(render(report, "html").replace("</body>", probe + "</body>"), encoding="utf-8")
    cmd = [browser, "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run", "--disable-extensions",
           f"--user-data-dir={tmp_path / 'profile'}", "--window-size=800,1000", "--virtual-time-budget=5000",
           "--dump-dom", page.as_uri()]
    dom = subprocess.run(cmd, capture_output=True, text=True, timeout=120).stdout
    found = re.search(r"data-probe=\"([^\"]+)\"", dom)
    assert found, "the browser did not run the page's load handler"
    got = json.loads(found.group(1).replace("&quot;", '"'))
    assert got["window"] <= 800 and got["page"] <= got["window"], got
    assert got["scroll"] > got["wrapper"] and got["scroll"] >= got["table"] - 1, got


def test_a_report_figure_is_laid_out_once_and_saved_as_checked(monkeypatch):
    """:func:`finish` solves the constrained layout once for a figure whose titles fit, checks
    that drawing and keeps it: the documents' SVG draws the checked axes where they were,
    without solving the layout again, once for the page and the PDF."""
    import matplotlib.layout_engine as engines
    from servo_toolkit.report.document import figure_src
    from servo_toolkit.report.figures import finish, new_figure
    solves = []
    real = engines.do_constrained_layout
    monkeypatch.setattr(engines, "do_constrained_layout", lambda *a, **k: solves.append(1) or real(*a, **k))
    fig, (a, b) = new_figure(1, 2)
    a.plot([1, 2], [1, 2], label="one")
    b.semilogx([1, 10, 100], [2, 1, 0], label="two")
    a.set_title("short")
    assert finish(fig) == ()
    assert len(solves) == 1
    where = [ax.get_position().bounds for ax in fig.axes]
    sources = {}
    page = figure_src(fig, sources)
    assert figure_src(fig, sources) == page  # the PDF takes the page's rendering
    assert len(solves) == 1
    assert [ax.get_position().bounds for ax in fig.axes] == where
