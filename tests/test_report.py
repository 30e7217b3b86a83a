"""The report of the reference EMA: files, self-containment, sections, PDF, and a real browser."""

from __future__ import annotations

import base64
import json
import math
import re
import shutil
import subprocess

import numpy as np
import pytest

from servo_toolkit import load_scene
from servo_toolkit.report import SECTIONS

from .conftest import SCENES

BROWSERS = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")
CHROME_FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                "--disable-component-update", "--disable-sync", "--no-first-run", "--disable-extensions")


@pytest.fixture(scope="module")
def report_dir(scene_report):
    """The reference EMA's report (the built-in scene's file), written once for the session by
    the command line (light settings; shared with the other report tests)."""
    run = scene_report("ema_reference")
    assert run.code == 0, run.err[-2000:]
    return run.folder


@pytest.fixture(scope="module")
def html(report_dir):
    return (report_dir / "index.html").read_text(encoding="utf-8")


def test_files_written(report_dir):
    assert (report_dir / "index.html").stat().st_size > 10_000
    assert (report_dir / "report.pdf").read_bytes().startswith(b"%PDF")


def test_html_is_self_contained(html):
    # no external resource of any kind: every src is a data URI, no link/script to a URL
    assert not re.search(r"""(src|href)\s*=\s*["']?(https?:|//|file:)""", html)
    assert "<link" not in html and "@import" not in html
    srcs = re.findall(r'<img[^>]*src="([^"]+)"', html)
    assert srcs, "the reference report must contain figures"
    for src in srcs:  # vector figures, the same bytes as the PDF's
        assert src.startswith("data:image/svg+xml;base64,")
        assert b"<svg" in base64.b64decode(src.split(",", 1)[1])[:2000]


def test_requirements_table_first_then_sections_in_order(html):
    titles = re.findall(r"<h2>\d+\. ([^<]+)</h2>", html)
    assert titles[0] == "Requirements"
    assert html.index('id="requirements-table"') < html.index('id="scene"')
    keys = re.findall(r'<section id="([^"]+)"', html)
    assert keys == ["requirements"] + [k for k, _, _ in SECTIONS] + ["references"]  # the reference list closes it


def test_every_section_is_live_or_says_why(html):
    for key, status, body in re.findall(r'<section id="([^"]+)" data-status="([^"]+)">(.*?)</section>', html, re.S):
        if status == "unavailable":
            assert "not available: " in body, key
        else:
            assert status in ("info", "pass", "fail", "n/a"), key


def test_stiffness_table_matches_the_drivetrain_and_seed001_rule(html):
    """The table's numbers are the series sum of its own stage columns (seed 001, eq 8)."""
    block = re.search(r'<table id="stiffness-table">(.*?)</table>', html, re.S).group(1)
    rows = [re.findall(r"<td>([^<]*)</td>", r) for r in re.findall(r"<tr>(.*?)</tr>", block, re.S)]
    rows = [r for r in rows if r]
    stages, total = rows[:-1], rows[-1]
    assert total[0] == "series total"
    # columns 1..4 are the stiffness at -30, 0, +10, +30 deg
    for col in range(1, 5):
        parts = [float(r[col]) for r in stages]
        assert float(total[col]) == pytest.approx(1 / sum(1 / k for k in parts), rel=1e-5)
    # independent check of one entry: the housing is at the output (ratio 1), 1696.8 N*m/deg
    # in the scene, shown in N*m/rad as `design` shows stiffness
    assert "N*m/rad" in block and "N*m/deg" not in block
    housing = next(r for r in stages if r[0] == "housing")
    assert float(housing[1]) == pytest.approx(1696.8 * 180 / math.pi, rel=1e-5)
    # the gear stage is behind the largest ratio: seed 001 says it may be neglected
    gear = next(r for r in stages if r[0].startswith("spur gear"))
    assert gear[-1] == "yes"
    dt = load_scene().drivetrain
    chain = dt.stiffness(np.radians([10.0]))
    assert float(total[3]) == pytest.approx(chain.total[0], rel=1e-5)


def test_pdf_has_a_title_page_and_every_section_and_figure(report_dir, html):
    if shutil.which("pdfinfo") is None:
        pytest.skip("pdfinfo not found (Debian package poppler-utils; .ci/run installs it)")
    info = subprocess.run(["pdfinfo", str(report_dir / "report.pdf")], capture_output=True, text=True,
                          timeout=60).stdout
    pages = int(re.search(r"Pages:\s+(\d+)", info).group(1))
    sections = html.count("<section")
    assert 1 + sections // 2 <= pages  # a title page, then sections (each with its figures) on A4 pages


def _pdftotext(path, *args):
    if shutil.which("pdftotext") is None:
        pytest.skip("pdftotext not found (Debian package poppler-utils; .ci/run installs it)")
    return subprocess.run(["pdftotext", *args, str(path), "-"], capture_output=True, text=True, timeout=60).stdout


def _cells(html):
    """Text of every table cell of the HTML report."""
    from servo_toolkit.report.pdf_text import blocks
    return [cell for kind, value in blocks(html) if kind == "table" for row in value for cell in row if cell]


def test_pdf_alone_carries_every_number_of_the_html_tables(report_dir, html):
    """A reader of the PDF gets every table of the HTML as text: each number of every cell is
    found in pdftotext's output (wrapped cells may split across lines, numbers do not)."""
    text = " ".join(_pdftotext(report_dir / "report.pdf").split())
    cells = _cells(html)
    assert len(cells) > 150
    numbers = {n for cell in cells for n in re.findall(r"-?\d+(?:\.\d+)?(?:e[+-]?\d+)?", cell)}
    missing = sorted(n for n in numbers if n not in text)
    assert not missing, f"numbers of the HTML tables missing from the PDF text: {missing[:20]}"
    for title in ("Margins along the stroke", "Nichols", "Designed controller"):
        assert title in text
    assert "closed loop stable over the stroke (fraction of points)" in text  # wrapped, not clipped


def test_pdf_pages_render(report_dir, tmp_path):
    if shutil.which("pdftoppm") is None:
        pytest.skip("pdftoppm not found (Debian package poppler-utils; .ci/run installs it)")
    subprocess.run(["pdftoppm", "-r", "30", "-png", "-f", "1", "-l", "3", str(report_dir / "report.pdf"),
                    str(tmp_path / "page")], check=True, timeout=120)
    assert len(list(tmp_path.glob("page*.png"))) == 3


def _browser():
    for name in BROWSERS:
        path = shutil.which(name)
        if path:
            return path
    return None


PROBE = """<script>
window.addEventListener('load', () => {
  const imgs = Array.from(document.images);
  document.body.setAttribute('data-probe', JSON.stringify({
    images: imgs.length,
    loaded: imgs.filter(i => i.complete && i.naturalWidth > 0 && i.naturalHeight > 0).length,
    requirements_rows: document.querySelectorAll('#requirements-table tbody tr').length,
    sections: document.querySelectorAll('section').length,
    tables: Object.fromEntries(Array.from(document.querySelectorAll('table[id]')).map(
      t => [t.id, t.querySelectorAll('tbody tr').length]))}));
});
</script>"""


def _probe(browser, page, tmp_path, name):
    """Load ``page`` in headless Chromium, return what the probe script measured."""
    probe = tmp_path / f"{name}-probe.html"
    probe.write_text(page.replace("</body>", PROBE + "</body>"), encoding="utf-8")
    cmd = [browser, *CHROME_FLAGS, f"--user-data-dir={tmp_path / (name + '-profile')}",
           "--virtual-time-budget=5000", "--dump-dom", probe.as_uri()]
    dom = subprocess.run(cmd, capture_output=True, text=True, timeout=60).stdout
    found = re.search(r"data-probe=\"([^\"]+)\"", dom)
    assert found, "the browser did not run the page's load handler"
    return json.loads(found.group(1).replace("&quot;", '"'))


@pytest.fixture(scope="module")
def browser():
    path = _browser()
    if path is None:
        pytest.skip("no Chromium found (install the Debian packages chromium and chromium-driver; "
                    ".ci/run does so in CI)")
    return path


def test_probe_detects_a_broken_figure(browser, tmp_path):
    """The browser check can fail: a corrupt PNG is reported as not loaded."""
    page = '<html><body><img src="data:image/png;base64,iVBORw0KGgoAAAA="></body></html>'
    result = _probe(browser, page, tmp_path, "broken")
    assert result["images"] == 1 and result["loaded"] == 0


def test_report_renders_in_chromium(browser, html, tmp_path):
    result = _probe(browser, html, tmp_path, "report")
    assert result["images"] == html.count('<img class="report-figure"') > 0
    assert result["loaded"] == result["images"], "some figures did not load"
    assert result["requirements_rows"] >= 1
    assert result["sections"] == 1 + len(SECTIONS) + 1  # requirements, the sections, the reference list
    for table_id, rows in (("stroke-table", 4), ("closed-loop-table", 9), ("controller-table", 10),
                           ("electrics-table", 2)):
        assert result["tables"].get(table_id, 0) >= rows, table_id
    shot = tmp_path / "report.png"
    subprocess.run([browser, *CHROME_FLAGS, f"--user-data-dir={tmp_path / 'shot-profile'}",
                    "--window-size=1200,3000", f"--screenshot={shot}", (tmp_path / "report-probe.html").as_uri()], capture_output=True, timeout=60)
    assert shot.read_bytes().startswith(b"\x89PNG"), "no screenshot"


def _section_tables(html, key):
    """The tables of a report section: lists of {header: cell} rows."""
    body = re.search(rf'<section id="{key}" data-status="[^"]+">(.*?)</section>', html, re.S).group(1)
    tables = []
    for block in re.findall(r"<table[^>]*>(.*?)</table>", body, re.S):
        heads = [h.strip() for h in re.findall(r"<th>(.*?)</th>", block, re.S)]
        rows = [re.findall(r"<td>(.*?)</td>", r, re.S) for r in re.findall(r"<tr>(.*?)</tr>", block, re.S)]
        tables.append([dict(zip(heads, r)) for r in rows if r])
    return tables


def test_the_linear_8hz_figures_of_the_report_agree(html):
    """One linear loop everywhere: the time section's linear closed loop (forced response of
    the design) and the sweep's linear loop give the same 8 Hz gain, as printed."""
    time_rows = [r for t in _section_tables(html, "time") for r in t]
    linear = next(r for r in time_rows if r.get("model") == "linear closed loop")
    g_time = float(linear["gain at 8 Hz [dB]"])
    sweep_rows = [r for t in _section_tables(html, "sweep") for r in t if "linear gain [dB]" in r]
    at8 = [float(r["linear gain [dB]"]) for r in sweep_rows if float(r["frequency [Hz]"]) == 8.0]
    assert at8 and all(g == pytest.approx(g_time, abs=0.01) for g in at8), (g_time, at8)
