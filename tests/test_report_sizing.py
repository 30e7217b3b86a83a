"""Report section on the sizing along the duty cycle, and its rows in the requirement table."""

from __future__ import annotations

from servo_toolkit import load_scene
from servo_toolkit.errors import SimulationError
from servo_toolkit.report.builder import SECTIONS, run_section
from servo_toolkit.report.context import Context
from servo_toolkit.report.sections_requirements import requirement_rows

from .conftest import SCENES


def _section(ctx):
    key, title, builder = next(s for s in SECTIONS if s[0] == "sizing")
    return run_section(key, title, builder, ctx)


def test_section_shows_the_three_plots_and_the_margins_of_the_duty_cycle():
    ctx = Context(load_scene(SCENES / "ema_sizing.toml"))
    section = _section(ctx)
    assert section.status == "pass" and section.key == "sizing", section.reason
    assert len(section.figures) == 3
    captions = " ".join(f.caption for f in section.figures)
    assert "torque against speed" in captions and "Winding temperature" in captions and "ratio" in captions
    assert 'id="sizing-table"' in section.html
    for rid in ("envelope_peak_torque", "thermal_margin", "life_ball_screw_screw"):
        assert rid in section.html
    assert ctx.result("sizing", lambda: None).sweep is not None    # computed once, with the sweep


def test_section_does_not_apply_without_a_duty_cycle():
    section = _section(Context(load_scene(SCENES / "ema_reference.toml")))
    assert section.status == "n/a" and "[duty_cycle]" in section.reason


def test_requirement_table_carries_the_sizing_rows_or_says_why_not():
    scene = load_scene(SCENES / "ema_sizing.toml")
    ctx = Context(scene)
    rows = {r.id: r for r in requirement_rows(ctx)}
    assert rows["thermal_margin"].passed and rows["envelope_rms_torque"].passed
    assert rows["life_ball_screw_bearing"].passed
    failed = Context(scene)
    failed.use_design(ctx.design())
    failed._cache["sizing"] = (False, SimulationError("the ratio vanishes along the cycle"))
    rows = {r.id: r for r in requirement_rows(failed)}
    assert rows["sizing"].status == "unavailable" and "ratio vanishes" in rows["sizing"].detail
    assert "thermal_margin" not in rows and rows["bandwidth"].passed
