"""``check`` judges the nonlinear actuator: the step and the requirement sine through the full
model with friction that holds, rows a margin-only check cannot see."""

import json
import math
import tomllib
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from servo_toolkit import load_scene
from servo_toolkit.cli import main
from servo_toolkit.errors import SceneError
from servo_toolkit.loop import design
from servo_toolkit.loop.tuning import LoopTuning, tuned_design
from servo_toolkit.scene.loader import scene_from_dict
from servo_toolkit.studies.actuator import actuator_check
from servo_toolkit.studies.actuator.result import IDS
from servo_toolkit.studies.actuator.runs import full_options
from servo_toolkit.studies.gate import gate

from .conftest import SCENES

GEARMOTOR = Path(__file__).parent / "scenes" / "gearmotor_carriage.toml"
#: the gains a margin-only design gave the gearmotor (GM 24 dB, PM 87 deg, Ms 1.4 dB)
MARGIN_ONLY = LoopTuning(kp=78.91, kv=7775.0, wvi=125.7)


def _gearmotor(**gear):
    data = tomllib.loads(GEARMOTOR.read_text())
    data["drivetrain"][0].update(gear)
    return scene_from_dict(data, "gearmotor_carriage.toml")


def test_a_motor_rattling_in_the_gearhead_backlash_fails_check_while_every_margin_passes():
    """The newcomer's gearmotor with the gains a margin-only design gives: every linear row
    and the large-signal fundamental pass, the motor current chatters in the sine (the motor
    side rattling through the 0.5 deg gearhead backlash) and the check fails on it. The same
    gains without the backlash chatter a small fraction of it."""
    scene = _gearmotor()
    g = gate(scene, tuned_design(scene, MARGIN_ONLY))
    rows = {r.id: r for r in g.rows}
    linear = [r for r in g.rows if r.id not in IDS]
    assert all(r.passed for r in linear), [r.message() for r in linear if not r.passed]
    assert not g.passed and not rows["current_ripple"].passed
    assert g.actuator.ripples["sine"] > rows_bound(g)
    no_lash = _gearmotor(backlash="0 deg")
    tight = actuator_check(no_lash, tuned_design(no_lash, MARGIN_ONLY))
    assert g.actuator.ripples["sine"] > 3.0 * tight.ripples["sine"], (g.actuator.ripples, tight.ripples)


def rows_bound(g):
    return g.actuator.plan.bound("current_ripple").value


def test_the_rows_read_the_full_models_own_run():
    """The step's overshoot and the sine's tracking error of the rows are those of a
    ``simulate`` run of the same controller with the full model and friction that holds,
    read here independently of the rows' code."""
    from servo_toolkit.sim import Reference, simulate
    scene = load_scene()
    d = design(scene)
    act = actuator_check(scene, d)
    p = act.plan
    run = simulate(scene, d.controller, reference=Reference.sine(p.sine_amplitude, p.frequency),
                   duration=8 / p.frequency, options=full_options())
    last = run.times >= 5 / p.frequency
    assert act.figures["tracking_error"] == pytest.approx(
        np.max(np.abs(run.reference_angle - run.output_angle)[last]), rel=1e-9)
    step = simulate(scene, d.controller, reference=Reference.step(p.step, at=0.01), duration=0.01 + 2 * p.settling_time,
                    options=full_options())
    y = step.output_angle - step.output_angle[0]
    # from the run's first record (the rows take the last one before the step: the same rest to 1e-9)
    assert act.figures["step_overshoot"] == pytest.approx(max(0.0, y.max() / p.step - 1.0), rel=1e-6)
    assert act.passed, [r.message() for r in act.rows() if not r.passed]
    assert repr(act).endswith("every row met>") and "<svg" in act._repr_html_()
    assert json.loads(json.dumps(act.to_dict()))["figures"]["tracking_error_rad"] == pytest.approx(
        act.figures["tracking_error"])


def test_load_friction_beyond_what_the_motor_can_move_fails_check(tmp_path, capsys):
    """1e5 N*m of Coulomb friction at the reference EMA's output (about 70 x what the motor
    delivers there): the output never moves, and check fails on the nonlinear rows while
    the linear rows, which cannot see a friction, pass."""
    text = (SCENES / "ema_reference.toml").read_text()
    data = tomllib.loads(text)
    data["load"]["coulomb_friction"] = "1e5 N*m"
    scene = scene_from_dict(data, "stuck.toml")
    g = gate(scene, design(scene))
    failed = {r.id for r in g.rows if not r.passed}
    assert {"step_settling_time", "position_error_at_rest", "time_at_current_limit"} <= failed
    assert failed <= set(IDS) | {"large_signal_gain", "large_signal_phase"}


def _unloaded_ema(lash):
    data = tomllib.loads((SCENES / "ema_reference.toml").read_text())
    del data["load"]["hinge_moment"]  # nothing holds the nut against one flank
    next(s for s in data["drivetrain"] if s["kind"] == "ball_screw")["backlash"] = lash
    return scene_from_dict(data, "lash.toml")


def test_a_2mm_nut_backlash_fails_check_on_the_limit_cycle_it_makes():
    """The reference EMA without its hinge moment: a 2 mm nut backlash makes the output cycle
    through the lash after the step (the margins cannot see it); without the lash every row
    is met. (With the hinge moment the load holds the nut on one flank: no cycle, and the
    rows are met.)"""
    loose = _unloaded_ema("2 mm")
    g = gate(loose, design(loose))
    failed = {r.id for r in g.rows if not r.passed}
    assert {"limit_cycle", "step_settling_time"} <= failed, [r.message() for r in g.rows if not r.passed]
    assert g.actuator.limit_cycle.amplitude > math.radians(1.0)
    tight = _unloaded_ema("0 mm")
    assert actuator_check(tight, design(tight)).passed


def test_check_json_and_junit_carry_the_nonlinear_rows(tmp_path, capsys):
    junit = tmp_path / "check.xml"
    assert main(["check", str(GEARMOTOR), "--json", "--junit", str(junit)]) in (0, 1)
    out = json.loads(capsys.readouterr().out)
    scene = out["scenes"][0]
    ids = [r["id"] for r in scene["rows"]]
    assert {"step_overshoot", "step_settling_time", "position_error_at_rest", "limit_cycle", "tracking_error",
            "current_ripple", "time_at_current_limit", "time_at_voltage_limit"} <= set(ids)
    act = scene["actuator"]
    assert act["model"] == "full chain, friction that holds" and act["sine_frequency_Hz"] == 5.0
    assert act["step_m"] == pytest.approx(5e-4) and act["sine_amplitude_m"] == pytest.approx(2e-4)
    assert scene["passed"] == all(r["status"] == "pass" for r in scene["rows"])
    cases = {c.get("name") for c in ET.parse(junit).getroot().iter("testcase")}
    assert set(ids) <= cases


def test_the_scene_sets_the_time_requirements_in_its_own_units():
    """[requirements] time keys replace the defaults (source scene); the continuous current
    row appears when the motor has a continuous rating."""
    data = tomllib.loads((SCENES / "ema_reference.toml").read_text())
    data["requirements"].update({"max_overshoot": "1 %", "max_settling_time": "0.4 s", "step_amplitude": "0.5 deg",
                                 "max_tracking_error": "3 deg", "max_current_ripple": "0.1 A"})
    data["motor"]["continuous_torque"] = "0.5 N*m"
    scene = scene_from_dict(data, "own.toml")
    d = design(scene)
    act = actuator_check(scene, d)
    bounds = {b.name: b for b in act.plan.bounds}
    assert act.plan.step == pytest.approx(math.radians(0.5))
    assert bounds["step_overshoot"].value == pytest.approx(0.01) and bounds["step_overshoot"].source == "scene"
    assert bounds["tracking_error"].value == pytest.approx(math.radians(3.0))
    assert bounds["rms_current"].value == pytest.approx(0.5 / scene.motor.torque_constant)
    rows = {r.id: r for r in act.rows()}
    # the design keeps the encoder's ripple within the scene's allowance too (it lowers the
    # speed gain for it); the row judges the run's own figure against the same 0.1 A
    assert d.actuator.allowance == pytest.approx(0.1) and d.actuator.allowance_source == "the scene's max_current_ripple"
    assert rows["current_ripple"].required == "<= 0.1 A"
    assert (rows["current_ripple"].status == "pass") == (act.figures["current_ripple"] <= 0.1)
    assert "default" not in rows["step_overshoot"].detail


def test_a_length_for_an_angle_output_names_the_key():
    data = tomllib.loads((SCENES / "ema_reference.toml").read_text())
    data["requirements"]["max_tracking_error"] = "0.2 mm"
    with pytest.raises(SceneError, match=r"requirements\.max_tracking_error.*give an angle"):
        scene_from_dict(data, "wrong.toml")   # refused as the scene loads, before any design
    data["requirements"]["max_overshoot"] = 20
    with pytest.raises(SceneError, match=r"requirements\.max_overshoot.*fraction"):
        scene_from_dict(data, "wrong.toml")


def test_the_default_sine_is_what_the_emps_axis_can_follow_by_its_published_mass():
    """The EMPS axis (published moving mass M = 95.1089 kg at the cart, 10 mm lead, Kt =
    0.013984 N*m/A, 0.25 ohm, 40 A, 10 V): at 5 Hz the rigid-body reach with half the current
    and half the voltage is the smaller of s I n Kt / (M w^2) and s V / (w (R M w / (n Kt) +
    Ke n)), n = 2 pi / 10 mm; the default 1 mm sine lies within it, at 8 Hz it is cut to it."""
    from servo_toolkit.studies.actuator.spec import followable_amplitude
    scene = load_scene(SCENES / "emps.toml")
    n, kt, m = 2 * math.pi / 0.01, 0.013984, 95.1089

    def reach(f):
        w = 2 * math.pi * f
        return min(0.5 * 40 * n * kt / (m * w * w), 0.5 * 10 / (w * (0.25 * m * w / (n * kt) + kt * n)))
    for f in (5.0, 8.0):
        assert followable_amplitude(scene, scene.drivetrain.mid_stroke, f) == pytest.approx(reach(f), rel=1e-4)
    assert reach(5.0) > 1e-3 > reach(8.0)


def test_the_error_at_rest_is_the_largest_after_the_motion_not_a_mean_that_cancels():
    """A step still settling through the judged window (its error crosses zero there, as a
    flap against a hinge moment did) has a mean error near zero; the row takes the largest
    |error| over the window, so a response that has not come to rest cannot pass on a cancelled
    mean."""
    from types import SimpleNamespace

    from servo_toolkit.core.output_units import OutputUnit
    from servo_toolkit.studies.actuator.result import _step_figures
    from servo_toolkit.studies.actuator.runs import STEP_AT
    step, settle = math.radians(1.0), 0.4
    t = np.linspace(0.0, STEP_AT + 2 * settle, 16001)
    after = np.clip(t - STEP_AT, 0.0, None)
    # a slow decaying swing about the command, one full period over the judged last quarter
    y = np.where(t < STEP_AT, 0.0, step * (1.0 - np.exp(-after / 0.3) * np.cos(2 * np.pi * after / (0.5 * settle))))
    run = SimpleNamespace(times=t, output_angle=y, motor_current=np.zeros_like(t),
                          trace=lambda name: y)
    plan = SimpleNamespace(step=step, rest_band=0.02 * step, settling_time=settle, frequency=8.0)
    figures, details = {}, {}
    _step_figures(plan, run, OutputUnit("rad"), figures, details)
    tail = (t - STEP_AT) >= 0.5 * (settle + (t[-1] - STEP_AT))
    err = step - y[tail]
    assert abs(np.mean(err)) < 0.1 * np.max(np.abs(err))  # the mean cancels
    assert figures["position_error_at_rest"] == pytest.approx(np.max(np.abs(err)), rel=1e-12)
    assert details["position_error_at_rest"].startswith("largest over ")
