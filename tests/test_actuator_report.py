"""A verdict is only as good as the worst run behind it: when the report's requirement rows
say met, no figure of its time section shows otherwise. The figures are read back from what
the section draws and tables, independently of the rows' own code."""

import math
import re
import tomllib

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from servo_toolkit.report import run_section
from servo_toolkit.report.context import Context
from servo_toolkit.report.sections_requirements import requirement_rows
from servo_toolkit.report.sections_time import time_responses
from servo_toolkit.scene.loader import scene_from_dict

from .conftest import SCENES

BASE = tomllib.loads((SCENES / "ema_reference.toml").read_text())


def _scene(load_friction, lash_mm, current_limit):
    data = tomllib.loads((SCENES / "ema_reference.toml").read_text())
    data["load"]["coulomb_friction"] = f"{load_friction} N*m"
    next(s for s in data["drivetrain"] if s["kind"] == "ball_screw")["backlash"] = f"{lash_mm} mm"
    data["motor"]["current_limit"] = f"{current_limit} A"
    return scene_from_dict(data, "variant.toml")


def _drawn(sec, name):
    """The (x, y) of the line labelled ``name`` on the step plot (ms, deg)."""
    ax = sec.figures[0].figure.axes[0]
    line = next(ln for ln in ax.get_lines() if ln.get_label() == name)
    return np.asarray(line.get_xdata(), float), np.asarray(line.get_ydata(), float)


def _electrics(html):
    table = re.search(r'<table id="electrics-table">(.*?)</table>', html, re.S).group(1)
    return [re.findall(r"<td>([^<]*)</td>", r) for r in re.findall(r"<tr>(.*?)</tr>", table, re.S) if "<td>" in r]


@settings(max_examples=3, deadline=None, derandomize=True)
@given(load_friction=st.sampled_from([0.0, 30.0, 3000.0]), lash_mm=st.sampled_from([0.0, 0.05, 2.0]),
       current_limit=st.sampled_from([60.0, 25.0]))
def test_when_the_report_says_met_its_time_figures_agree(load_friction, lash_mm, current_limit):
    ctx = Context(_scene(load_friction, lash_mm, current_limit), light=True)
    rows = {r.id: r for r in requirement_rows(ctx)}
    sec = run_section("time", "time", time_responses, ctx)
    assert sec.status == "info", sec.reason
    act = ctx.actuator()
    step_deg = math.degrees(act.plan.step)
    t_ms, y = _drawn(sec, "nonlinear")
    over = max(0.0, y.max() / step_deg - 1.0)
    band = math.degrees(act.plan.rest_band)
    outside = np.nonzero(np.abs(y - step_deg) > band)[0]
    settle_ms = 0.0 if not outside.size else (math.inf if outside[-1] + 1 >= y.size else t_ms[outside[-1] + 1])
    sine = _electrics(sec.html)[1]
    at_i, at_v = float(sine[5]), float(sine[6])
    figures_fail = []
    if over > act.plan.bound("step_overshoot").value + 1e-9:
        figures_fail.append(("overshoot", over))
    if settle_ms > 1e3 * act.plan.settling_time + 1e-6:
        figures_fail.append(("settling", settle_ms))
    if at_i > 1e3 * act.plan.bound("time_at_current_limit").value + 1e-9:
        figures_fail.append(("time at the current limit", at_i))
    if at_v > 1e3 * act.plan.bound("time_at_voltage_limit").value + 1e-9:
        figures_fail.append(("time at the voltage limit", at_v))
    met = all(r.passed for r in rows.values())
    if met:
        assert not figures_fail, figures_fail
    # and the other way round: a figure the section shows failing is a failed row
    names = {"overshoot": "step_overshoot", "settling": "step_settling_time",
             "time at the current limit": "time_at_current_limit", "time at the voltage limit": "time_at_voltage_limit"}
    for what, _ in figures_fail:
        assert not rows[names[what]].passed, what
