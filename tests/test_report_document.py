"""The report as a document to sign: one requirement table with ``check``, numbers checked
against independent computations, plain words, and a typeset A4 PDF."""

from __future__ import annotations

import html as html_lib
import json
import math
import re

import numpy as np
import pytest

from servo_toolkit import load_scene
from servo_toolkit.cli import main

from .conftest import SCENES

EMA = SCENES / "ema_reference.toml"


@pytest.fixture(scope="module")
def report_dir(scene_report):
    """The reference EMA's report, written once by the command line (light settings)."""
    run = scene_report("ema_reference")
    assert run.code == 0, run.err[-2000:]  # complete, and --strict: every requirement met
    return run.folder


@pytest.fixture(scope="module")
def html(report_dir):
    return (report_dir / "index.html").read_text(encoding="utf-8")


@pytest.fixture(scope="module")
def design():
    from servo_toolkit.loop import design as run
    return run(load_scene(EMA), progress=False)


def _text(html):
    body = re.sub(r"<style>.*?</style>", " ", html, flags=re.S)
    body = re.sub(r"<img[^>]*>", " ", body)
    return " ".join(html_lib.unescape(re.sub(r"<[^>]+>", " ", body)).split())


def _table(html, table_id):
    block = re.search(rf'<table id="{table_id}">(.*?)</table>', html, re.S).group(1)
    heads = [html_lib.unescape(re.sub(r"<[^>]+>", "", h)).strip() for h in re.findall(r"<th>(.*?)</th>", block, re.S)]
    rows = []
    for r in re.findall(r"<tr>(.*?)</tr>", block, re.S):
        cells = [html_lib.unescape(re.sub(r"<[^>]+>", "", c)).strip() for c in re.findall(r"<td>(.*?)</td>", r, re.S)]
        if cells:
            rows.append(dict(zip(heads, cells)))
    return rows


def _response(sys, f_hz):
    """C (jw I - A)^-1 B + D of a SISO state space, by numpy alone."""
    a, b, c, d = (np.asarray(x, float) for x in (sys.A, sys.B, sys.C, sys.D))
    s = 2j * math.pi * f_hz
    return complex((c @ np.linalg.solve(s * np.eye(a.shape[0]) - a, b) + d)[0, 0])


# --- one requirement table -----------------------------------------------------------------


@pytest.mark.parametrize("name, code", [("ema_reference", 0), ("ema_robust", 1)])
def test_report_and_check_have_the_same_rows(name, code, scene_report, capsys):
    """The same rows, IDs, requirements, achieved figures and verdicts: on the reference EMA
    (every row met) and on the robust scene (failing rows, large-signal and robustness rows)."""
    run = scene_report(name)
    page = (run.folder / "index.html").read_text(encoding="utf-8")
    rows = _table(page, "requirements-table")
    section = re.search(r'<section id="requirements".*?</section>', page, re.S).group(0)
    details = {k: html_lib.unescape(v) for k, v in re.findall(r"<li>([a-z0-9_]+): (.*?)</li>", section)}
    capsys.readouterr()
    assert main(["check", str(SCENES / f"{name}.toml"), "--json"]) == code
    checked = json.loads(capsys.readouterr().out)["scenes"][0]["rows"]
    assert [r["ID"] for r in rows] == [r["id"] for r in checked]
    for shown, row in zip(rows, checked):
        assert (shown["required"], shown["achieved"], shown["status"]) == (
            row["required"], row["achieved"], row["status"]), row["id"]
        assert details.get(row["id"], "") == row["detail"], row["id"]  # the worst variant named alike
    ids = {r["ID"] for r in rows}
    # the large-signal rows the report used to leave out are there
    assert {"large_signal_gain", "large_signal_phase", "closed_loop_stable", "bandwidth"} <= ids
    assert (run.code == 1) == any(r["status"] == "fail" for r in checked)  # --strict: exit 1 on a failed row
    if name == "ema_robust":
        assert {"robust_gain_margin", "robust_stable_fraction"} <= ids
        assert [r["id"] for r in checked if r["status"] == "fail"], "the robust scene fails some rows"


def test_junit_testcases_are_the_row_ids(tmp_path, design):
    from servo_toolkit.cli.cmd_check import _cases
    from servo_toolkit.studies.gate import design_rows
    rows = design_rows(design)
    assert [c[0] for c in _cases(rows)] == [r.id for r in rows]
    assert all(c[1] == r.passed for c, r in zip(_cases(rows), rows))


def test_strict_exits_1_when_a_requirement_fails(monkeypatch, tmp_path, capsys):
    import servo_toolkit.report as report_pkg
    from servo_toolkit.report.builder import Report
    from servo_toolkit.report.section import Section
    from servo_toolkit.studies.gate import RequirementRow
    out = tmp_path / "r"
    failing = RequirementRow("bandwidth", "closed-loop bandwidth (-3 dB)", ">= 8 Hz", "7.9 Hz", "0.1 Hz", "fail")
    fake = Report("x", "x", (Section("Requirements", status="fail", key="requirements"),), (failing,))
    monkeypatch.setattr(report_pkg, "build_report", lambda *a, **k: fake)
    monkeypatch.setattr(report_pkg, "write_report", lambda *a, **k: {"html": out / "index.html", "pdf": out / "report.pdf",
                                                                      "pdf_engine": "weasyprint"})
    monkeypatch.setattr("servo_toolkit.cli.cmd_report._check_budget", lambda *a, **k: None)
    assert main(["report", str(EMA), "-o", str(out)]) == 0
    assert main(["report", str(EMA), "-o", str(out), "--strict"]) == 1
    assert "bandwidth" in capsys.readouterr().err


# --- every number right ----------------------------------------------------------------------


def test_rotor_share_is_taken_point_by_point(html):
    """Rotor inertia times N(q)^2 over J(q) at the same q: 66.2 % to 71.4 % along the
    reference stroke (the wrong pairing gave 50.1 % to 94.3 %)."""
    text = _text(html)
    lo, hi = (float(x) for x in re.search(r"motor rotor contributes ([\d.]+)% to ([\d.]+)%", text).groups())
    drive = load_scene(EMA).drivetrain
    shares = []
    for q in np.linspace(*drive.stroke, 401):  # one point at a time
        n, _ = drive.ratio(np.array([q]))
        j, _ = drive.inertia(np.array([q]))
        shares.append(drive.motor.rotor_inertia * n[0] ** 2 / j[0])
    assert lo == pytest.approx(100 * min(shares), abs=0.05) and hi == pytest.approx(100 * max(shares), abs=0.05)
    assert (lo, hi) == (66.2, 71.4)


def test_phase_lag_row_is_at_the_required_bandwidth_and_labelled(html, design):
    row = next(r for r in _table(html, "requirements-table") if r["ID"] == "phase_lag_at_bandwidth")
    assert "required bandwidth, 8 Hz" in row["requirement"]
    lag = -math.degrees(np.angle(_response(design.closed_loop["theta", "theta_ref"], 8.0)))
    assert float(row["achieved"].split()[0]) == pytest.approx(lag, rel=2e-3)


def test_loop_table_gives_the_phase_at_the_achieved_bandwidth(html, design):
    body = re.search(r'<section id="loop".*?</section>', html, re.S).group(0)
    bw = design.margins.bandwidth_hz
    cell = re.search(r"closed-loop phase at the achieved bandwidth, ([\d.]+) Hz</td><td>([-\d.]+)</td>", body)
    assert cell and float(cell.group(1)) == pytest.approx(bw, rel=1e-3)
    ph = math.degrees(np.angle(_response(design.closed_loop["theta", "theta_ref"], bw)))
    assert float(cell.group(2)) == pytest.approx(ph if ph <= 0 else ph - 360, abs=0.05)
    # |T| is -3 dB there: the bandwidth itself, independently
    assert 20 * math.log10(abs(_response(design.closed_loop["theta", "theta_ref"], bw))) == pytest.approx(-3.0, abs=0.01)


def test_every_listed_crossing_lies_in_the_plotted_range(html):
    body = re.search(r'<section id="loop".*?</section>', html, re.S).group(0)
    top = float(re.search(r"the plots span [\d.]+ to ([\d.e]+) Hz", _text(body)).group(1))
    crossings = [float(r["frequency [Hz]"]) for r in _table(body, "crossings-table")]
    assert crossings and max(crossings) < top


def test_plotted_range_reaches_past_the_last_crossing():
    from types import SimpleNamespace

    from servo_toolkit.report.sections_loop import F_MAX, plotted_range
    m = SimpleNamespace(gain_crossover_hz=[6.2], phase_crossover_hz=[29.3, 3762.0])
    assert plotted_range(m) > 3762.0
    assert plotted_range(SimpleNamespace(gain_crossover_hz=[6.2], phase_crossover_hz=[math.inf])) == F_MAX


def test_a_step_that_does_not_settle_is_said_in_words():
    from servo_toolkit.report.sections_time import step_cells
    t = np.linspace(0.0, 0.25, 1001)
    y = 1.0 - np.exp(-t / 0.155)  # 80 % of the step after 250 ms
    (rise, _, settle), note = step_cells(t, y, 1.0, "nonlinear")
    assert rise.startswith("not reached (80%") and settle == "not settled within 250 ms"
    assert "does not settle" in note and "80%" in note
    (rise, _, settle), note = step_cells(t, 1.0 - np.exp(-t / 0.01), 1.0, "linear")
    assert float(rise) == pytest.approx(0.01 * math.log(9) * 1e3, rel=0.02) and note == ""


def test_no_docstring_markup_where_a_user_reads(html):
    text = _text(html)
    assert "`" not in text
    assert not re.search(r":(data|mod|func|class|meth|attr):", text)
    # the constants the simulation's notes name appear as their values
    from servo_toolkit.sim.chain_split import LOSS_TORQUE_SCALE, MIN_BACKDRIVE
    assert f"eta_b = {MIN_BACKDRIVE:g}" in text and f"{LOSS_TORQUE_SCALE:g} of the peak motor torque" in text


def test_plain_text_of_markup():
    from servo_toolkit.report.plain_text import plain
    from servo_toolkit.sim import chain_split
    assert plain(":data:`~.chain_split.MIN_BACKDRIVE`", vars(chain_split)) == f"{chain_split.MIN_BACKDRIVE:g}"
    assert plain(":data:`UNKNOWN`") == "UNKNOWN"
    assert plain("(:mod:`servo_toolkit.plant.linear`)") == "(servo_toolkit.plant.linear)"
    assert plain(":func:`~.sweep.study_points`, ``x``, `y`") == "study_points, x, y"
    assert plain(":func:`the sweep <servo_toolkit.studies.sweep.compute>`") == "the sweep"


# --- the PDF as a document: tests/test_report_pdf.py, for every shipped scene ------------------


# --- timings -----------------------------------------------------------------------------------


def test_accuracy_wall_times_are_the_best_of_repeats(monkeypatch):
    """Each rung runs ``repeats`` times; its wall time is the smallest, never one noisy run."""
    from types import SimpleNamespace

    import servo_toolkit.studies.accuracy as acc
    walls = iter([5.0, 1.0, 3.0] * 20)
    calls = []

    def fake_run(model, reference, duration, method, dt=None, output_dt=None, **kw):
        calls.append(method)
        t = np.linspace(0.0, duration, 11)
        return SimpleNamespace(dt_s=dt, wall_s=next(walls), output_angle=np.sin(t) * (1 + (dt or 0.0)),
                               method=method)
    monkeypatch.setattr(acc, "run", fake_run)
    from servo_toolkit.sim import layout as lo
    model = SimpleNamespace(sample_time=1e-3, name="m", output_unit="rad", controller="c", P=np.zeros(lo.NP_HEADER))
    reference = SimpleNamespace(kind="sine", amplitude=1.0, describe=lambda unit: "sine")
    res = acc.accuracy_study(model, reference, 0.01, dts=[1e-3, 5e-4], progress=False, repeats=3)
    assert len(calls) == 3 * (1 + 2 * 2) and res.repeats == 3
    assert all(r["wall_s"] == 1.0 for r in res.runs) and res.reference_wall_s == 1.0


# --- the typeset PDF is what an installation gives ------------------------------------------


def test_weasyprint_is_a_dependency_of_the_toolkit():
    """``python -m pip install .`` (the README's set-up) brings the paged-media engine."""
    import tomllib
    project = tomllib.loads((SCENES.parent / "pyproject.toml").read_text())["project"]
    names = [re.split(r"[<>=!~ \[]", d, maxsplit=1)[0].lower() for d in project["dependencies"]]
    assert "weasyprint" in names and "jinja2" in names


def test_without_pango_the_fallback_pdf_says_why(monkeypatch, tmp_path, capsys):
    """A system without Pango (WeasyPrint cannot load it) gets the plain PDF and one stderr
    line naming what to install; the report is still complete."""
    import servo_toolkit.report as report_pkg
    import servo_toolkit.report.pdf_writer as pdf_writer
    from servo_toolkit.report.builder import Report
    from servo_toolkit.report.section import Section

    def no_pango():
        raise OSError("cannot load library 'libpango-1.0-0': libpango-1.0-0: cannot open shared object file")
    monkeypatch.setattr(pdf_writer, "_weasyprint", no_pango)
    fake = Report("x", "x", (Section("Requirements", "<p>none</p>", status="n/a", reason="nothing to check",
                                     key="requirements"),), ())
    monkeypatch.setattr(report_pkg, "build_report", lambda *a, **k: fake)
    monkeypatch.setattr("servo_toolkit.cli.cmd_report._check_budget", lambda *a, **k: None)
    out = tmp_path / "r"
    assert main(["report", str(EMA), "-o", str(out)]) == 0
    assert (out / "report.pdf").read_bytes().startswith(b"%PDF")
    note = [ln for ln in capsys.readouterr().err.splitlines() if "fallback" in ln]
    assert len(note) == 1 and "Pango" in note[0] and "apt-get install libpango-1.0-0" in note[0]
