"""The report's section on a measured plant response (report --plant-frf)."""

from __future__ import annotations

import re

import numpy as np
import pytest

from servo_toolkit.cli import main
from servo_toolkit.core.spectra import response_csv
from servo_toolkit.identify.data import FrequencyData
from servo_toolkit.report.builder import MEASURED, SECTIONS, sections_of
from servo_toolkit.report.context import Context
from servo_toolkit.report.section import fmt

from .test_design_plant_frf import GEARED, F, _rig


@pytest.fixture(scope="module")
def rig(memo):
    """The geared scene and a noise-free response of its plant 15 % stiffer in frequency, the
    points above 100 Hz of poor coherence."""
    from servo_toolkit.loop import design
    from servo_toolkit.scene.loader import load_scene
    scene = load_scene(GEARED)
    r = design(scene, progress=False)
    h, _ = _rig(r)
    coherence = np.where(F > 100, 0.5, 0.99)
    return scene, FrequencyData.from_complex(F, h, coherence, source="rig.csv", averages=8)


def test_the_section_shows_both_margins_the_mismatch_and_the_bode_of_both(rig):
    from servo_toolkit.report.sections_measured import measured_plant, measured_result
    scene, data = rig
    ctx = Context(scene, plant_frf=data)
    section = measured_plant(ctx)
    m = measured_result(ctx)
    html = section.html
    table = html[html.index('id="measured-margins-table"'):]
    for name, unit, model, measured in m.side_by_side()[:2]:
        assert f"{name} [{unit}]" in table
        assert f"{model:.4g} {unit}" in table and f"{measured:.4g} {unit}" in table
    assert 'id="measured-mismatch-table"' in html and "[dB]" in html and "[deg]" in html
    assert "95 % interval" in table  # from the coherence of 8 averaged spectra
    for name in ("gain margin", "phase margin"):
        lo, hi = m.intervals()[name]
        assert lo < hi and f"{fmt(lo, 4)} .. {fmt(hi, 4)}" in table
    assert "Verdict: the requirements table judges both" in html
    assert "measured anti-resonance" in html and "Hz" in html  # the design's notch note
    (spec,) = section.figures
    labels = [line.get_label() for ax in spec.figure.axes for line in ax.get_lines()]
    assert labels.count("model") == 4 and labels.count("measured") == 4
    poor = [line for ax in spec.figure.axes for line in ax.get_lines() if line.get_label().startswith("coherence")]
    assert poor and all(len(line.get_xdata()) == int((F > 100).sum()) for line in poor)


def test_the_measured_rows_join_the_requirements(rig):
    from servo_toolkit.report.sections_requirements import _measured_rows
    scene, data = rig
    ctx = Context(scene, plant_frf=data)
    rows = _measured_rows(ctx, ctx.design())
    ids = {r.id for r in rows}
    assert {"measured_closed_loop_stable", "measured_gain_margin", "measured_phase_margin"} <= ids
    assert _measured_rows(Context(scene), ctx.design()) == []


def test_the_section_comes_after_the_loop_only_with_a_measured_response():
    assert sections_of(None) == list(SECTIONS)
    keys = [k for k, _, _ in sections_of(object())]
    assert keys[keys.index("loop") + 1] == MEASURED[0] and len(keys) == len(SECTIONS) + 1


def test_report_refuses_a_bad_file_before_any_work(tmp_path, capsys):
    path = tmp_path / "frf.csv"
    path.write_text("frequency_hz,gain,phase_deg\n1,0,0\n2,0,0\n")
    assert main(["report", GEARED, "--plant-frf", str(path), "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--plant-frf" in err[0]
    assert not (tmp_path / "out").exists()


def test_the_report_command_writes_the_section(rig, tmp_path, capsys):
    _, data = rig
    path = tmp_path / "rig.csv"
    path.write_text(response_csv(F, data.gain_db, data.phase_deg, data.coherence, 8))
    code = main(["report", GEARED, "--plant-frf", str(path), "-o", str(tmp_path / "out")])
    assert code == 0, capsys.readouterr().err[-2000:]
    html = (tmp_path / "out" / "index.html").read_text(encoding="utf-8")
    keys = re.findall(r'<section id="([^"]+)"', html)
    assert keys[keys.index("loop") + 1] == "measured"
    req = html[html.index('id="requirements-table"'):html.index('id="scene"')]
    assert "measured_phase_margin" in req and "measured_closed_loop_stable" in req
