"""The sizing's rows in the shared requirement table (check, JUnit, report)."""

from __future__ import annotations

import json
import subprocess
import sys
import xml.etree.ElementTree as ET
from types import SimpleNamespace

from servo_toolkit.errors import SimulationError
from servo_toolkit.studies.gate import gate, sizing_rows
from servo_toolkit.studies.sizing import size

from .conftest import ROOT, SCENES

ROWS = ["envelope_peak_torque", "envelope_rms_torque", "envelope_peak_current", "envelope_peak_voltage",
        "thermal_margin", "life_ball_screw_screw", "life_ball_screw_bearing"]


def _design():
    """A stand-in DesignResult with no requirement rows and a stable loop."""
    return SimpleNamespace(requirements=[], robustness=None, controller=None, scene_name="s",
                           margins=SimpleNamespace(closed_loop_stable=True, max_closed_loop_pole_real=-1.0))


def test_sizing_rows_are_the_margins_with_stable_ids():
    res = size(SCENES / "ema_sizing.toml", sweep=False)
    rows = sizing_rows(res)
    assert [r.id for r in rows] == ROWS
    assert all(r.passed for r in rows)
    thermal = rows[4]
    assert thermal.required == "<= 155 degC" and thermal.achieved.endswith("degC")
    assert rows[5].required == ">= 1000 h" and "inverse dynamics" in rows[5].detail


def test_gate_adds_sizing_rows_only_with_a_duty_cycle():
    design = _design()
    plain = SimpleNamespace(robustness=None, duty_cycle=None)
    g = gate(plain, design, linear_only=True, montecarlo=((), None))
    assert [r.id for r in g.rows] == ["closed_loop_stable"] and g.sizing is None
    res = size(SCENES / "ema_sizing.toml", sweep=False)
    sized = SimpleNamespace(robustness=None, duty_cycle=object())
    g = gate(sized, design, linear_only=True, montecarlo=((), None), sizing=res)
    assert [r.id for r in g.rows][1:] == ROWS and g.sizing is res and g.passed
    g = gate(sized, design, linear_only=True, montecarlo=((), None), sizing=SimulationError("ratio vanishes"))
    assert g.rows[-1].id == "sizing" and g.rows[-1].status == "unavailable" and not g.passed
    assert "ratio vanishes" in g.rows[-1].message()


def test_check_fails_a_life_short_of_the_required_and_names_it_in_junit(tmp_path):
    text = (SCENES / "ema_sizing.toml").read_text()
    short = tmp_path / "short.toml"
    short.write_text(text.replace('required_life = "1000 h"', 'required_life = "2000 h"'))
    junit = tmp_path / "check.xml"
    run = subprocess.run([sys.executable, "-m", "servo_toolkit", "check", str(short), "--linear-only", "--json",
                          "--junit", str(junit)], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert run.returncode == 1, run.stderr
    scene = json.loads(run.stdout)["scenes"][0]
    status = {r["id"]: r["status"] for r in scene["rows"]}
    assert status["life_ball_screw_screw"] == "fail" and status["life_ball_screw_bearing"] == "pass"
    assert status["thermal_margin"] == "pass" and status["envelope_peak_torque"] == "pass"
    assert scene["sizing"]["method"] == "inverse_dynamics"
    # one verdict per scene: the loop alone meets its requirements, the scene does not
    assert scene["passed"] is False and scene["requirements_met"] is False
    assert scene["loop_requirements_met"] is True
    cases = {c.get("name"): c for c in ET.parse(junit).getroot().iter("testcase")}
    assert cases["life_ball_screw_screw"].find("failure") is not None
    assert cases["thermal_margin"].find("failure") is None


def test_a_motor_without_torque_limits_has_no_envelope_row_and_passes():
    from servo_toolkit.scene.loader import scene_from_dict

    from .test_sizing import inertia_scene, trapezoid_cycle
    res = size(scene_from_dict(inertia_scene(trapezoid_cycle(), start="0 deg")), sweep=False)
    assert res.margins == () and res.passed
    assert sizing_rows(res) == []
