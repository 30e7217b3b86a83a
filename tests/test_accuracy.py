"""Accuracy study and the simulate/accuracy commands."""

from __future__ import annotations

import json
import math
import re

from servo_toolkit import load_scene
from servo_toolkit.cli import main
from servo_toolkit.sim import ModelOptions, Reference, build_model, default_controller
from servo_toolkit.studies.accuracy import accuracy_study

from .conftest import SCENES


def test_accuracy_study_orders():
    scene = load_scene(SCENES / "ema_reference.toml")
    model = build_model(scene, default_controller(scene))
    res = accuracy_study(model, Reference.sine(math.radians(2), 8.0), 0.03,
                         dts=[1e-4, 5e-5, 2.5e-5], progress=False)
    assert 3.5 < res.order < 4.6
    assert 0.7 < res.paper_order < 1.4
    d = res.to_dict()
    assert {"method", "dt_s", "wall_s", "error"} <= set(d["runs"][0])


def test_the_paper_scheme_converges_to_the_reference_at_first_order():
    """The frozen-configuration scheme is first order towards the same solution as RK4 and
    the stiff reference, not towards one of its own: on a rigid chain with a continuous
    controller (whose position feedback reads the load-side coordinate) and on the compliant
    EMA, halving the step halves the error against the reference, which goes to zero."""
    for name in ("linear_roller_screw_actuator", "ema_reference"):
        scene = load_scene(SCENES / f"{name}.toml")
        model = build_model(scene, default_controller(scene))
        amp = 1e-3 if name.startswith("linear") else math.radians(2)
        res = accuracy_study(model, Reference.sine(amp, 8.0), 0.05, dts=[1e-4, 5e-5, 2.5e-5], progress=False)
        errors = [r["error"] for r in res.runs if r["method"] == "paper"]
        assert all(1.7 < a / b < 2.3 for a, b in zip(errors, errors[1:])), (name, errors)
        assert errors[-1] < 2e-3, (name, errors)


def test_cli_simulate_and_accuracy_json(capsys, tmp_path):
    out = tmp_path / "traces.csv"
    assert main(["simulate", str(SCENES / "ema_reference.toml"), "--method", "rk4", "--json",
                 "-o", str(out)]) == 0
    d = json.loads(capsys.readouterr().out)
    for key in ("t_final_s", "final_state", "max_abs_motor_torque_Nm", "wall_s", "method", "dt_s"):
        assert key in d
    assert d["t_final_s"] == 1.0 and d["method"] == "rk4"
    assert out.read_text().startswith("t_s,")
    assert main(["simulate", str(SCENES / "ema_reference.toml"), "--study", "nope"]) == 2


def test_the_observed_order_leaves_out_the_reference_plateau():
    """Errors that stop falling have reached the reference's own accuracy: the fit of the
    order stops there instead of averaging the plateau into a lower order."""
    from servo_toolkit.studies.accuracy import _order
    dts = [1e-4, 5e-5, 2.5e-5, 1.25e-5, 6.25e-6]
    fourth = [1e-3 * (d / 1e-4) ** 4 for d in dts[:3]]
    assert abs(_order(dts, fourth + [3.5e-6, 3.5e-6]) - 4.0) < 1e-9
    assert abs(_order(dts[::-1], (fourth + [3.5e-6, 3.5e-6])[::-1]) - 4.0) < 1e-9   # any order of the ladder
    assert abs(_order(dts, [1e-3 * d / 1e-4 for d in dts]) - 1.0) < 1e-9         # no plateau: every point


def test_the_reference_s_own_error_is_not_fitted_as_rk4_s():
    """On the reference EMA (8 Hz, 2 deg, 0.1 s) RK4's errors against an RK4 run at 1/128
    of the sample time fall at fourth order (2.0e-7, 1.15e-8, 6.9e-10, 4.2e-11, 2.6e-12 as
    dt halves from 1e-4 s) while the LSODA reference (rtol 1e-12) itself is 8.6e-12 off:
    against it the last two read 4.0e-11 and 1.0e-11. Those are the reference's accuracy,
    not the step's: left out, the fitted order is the true 4.1, not 3.7."""
    from servo_toolkit.studies.accuracy import AccuracyResult, _order
    dts = [1e-4 / k for k in (1, 2, 4, 8, 16)]
    against_reference = [2.004e-7, 1.148e-8, 6.843e-10, 4.024e-11, 1.007e-11]
    assert abs(_order(dts, against_reference) - 4.1) < 0.05
    runs = tuple({"method": "rk4", "dt_s": d, "wall_s": 1e-3, "error": e} for d, e in zip(dts, against_reference))
    table = AccuracyResult(runs, 4.1, 1.0, 1.0, 0.0349, 0.1).table()
    assert table.count("(at the reference's own accuracy)") == 2
    assert "relative to the motion amplitude (0.0349 rad)" in table


def test_self_convergence_measures_the_order_where_the_reference_cannot():
    """On the cam drive every RK4 error against the stiff reference sits at the reference's
    own accuracy (no order can be fitted), yet successive halvings of the step still shrink
    the difference at fourth order."""
    from servo_toolkit.sim import controller_for
    scene = load_scene(SCENES / "cam_follower.toml")
    model = build_model(scene, controller_for(scene)[0])  # as `servo-toolkit accuracy` runs it
    res = accuracy_study(model, Reference.sine(math.radians(2), 8.0), 0.1, progress=False)
    errors = [r["error"] for r in res.runs if r["method"] == "rk4"]
    assert max(errors) < 1.2 * min(errors) and min(errors) > 1e-11  # a plateau above the tolerance floor
    assert math.isnan(res.order)
    assert 3.5 < res.self_order < 4.6
    assert "not measurable against the reference" in res.order_text() and res.to_dict()["self_order"] == res.self_order


def test_the_order_floor_leaves_out_rounding():
    from servo_toolkit.studies.accuracy import ROUNDING_FLOOR, _order
    dts = [1e-4, 5e-5, 2.5e-5, 1.25e-5]
    fourth = [1e-10 * (d / 1e-4) ** 4 for d in dts]  # from the third on below the rounding floor
    assert abs(_order(dts, fourth, ROUNDING_FLOOR) - 4.0) < 1e-9
    assert math.isnan(_order(dts, fourth))  # the reference floor (1e-10) leaves a single point


def test_with_friction_that_holds_the_order_stays_four_away_from_the_switching_instants():
    """A geared motor with static friction, set turning and then driven by a sine voltage
    that stops it, reverses it and breaks it away again: before the first switching instant
    RK4's order against the reference (which stops on the same events) is 4; over the whole
    run the steps meeting a switching instant bring it down, and the note says so."""
    import numpy as np

    from servo_toolkit.components.compliance import Load
    from servo_toolkit.components.gear import GearTrain
    from servo_toolkit.components.motor import DCMotor
    from servo_toolkit.scene.loader import Scene

    motor = DCMotor(resistance=0.5, inductance=0.0, torque_constant=0.2, back_emf_constant=0.2, rotor_inertia=2e-4,
                    viscous_friction=1e-4, coulomb_friction=0.02, static_friction=0.05, voltage_limit=100.0,
                    current_limit=50.0)
    scene = Scene("stick", motor=motor, stages=(GearTrain("gear", ratio=10.0, inertias=(1e-5, 1e-3)),),
                  load=Load(inertia=0.05))
    model = build_model(scene, None, ModelOptions(friction="stick", efficiency=False))
    x0 = np.zeros(model.nx)
    x0[0] = x0[2] = model.q0
    x0[1] = x0[3] = 1.0  # output rad/s: 10 rad/s at the motor
    volts = 3.0 * 0.5 * 0.05 / 0.2  # three times the breakaway voltage
    res = accuracy_study(model, Reference.voltage(0.0, swing=volts, frequency=5.0), 0.5,
                         dts=[4e-4, 2e-4, 1e-4, 5e-5], progress=False, repeats=1, x0=x0)
    sw = res.switching
    assert sw["instants"] >= 4 and 0.05 < sw["first_s"] < 0.2
    assert 3.7 < sw["order_smooth"] < 4.3
    # the switches located within their steps: fourth order after them and over the whole run
    # (1.5 with a breakaway at a step boundary and a linear estimate of a reversal)
    assert sw["after_window_s"] > 0.02 and 3.5 < sw["order_after"] < 4.5
    assert 3.5 < res.order < 4.5
    (note,) = res.notes
    assert f"RK4's order is {sw['order_smooth']:.2f}" in note and "switching instants" in note
    assert f"{sw['order_after']:.2f} over the" in note
    assert res.to_dict()["switching"]["instants"] == sw["instants"] and note in res.table()
    smooth = accuracy_study(build_model(scene, None, ModelOptions(efficiency=False)), Reference.voltage(1.0), 0.05,
                            dts=[4e-4, 2e-4], progress=False, repeats=1)
    assert smooth.switching == {} and smooth.notes == ()


def test_failed_rungs_are_named_in_the_table_not_printed_as_nan():
    """A step that left RK4's stability region is a failed rung: the table says so with its
    reason, and an order that could not be measured reads as such, never 'nan'."""
    from servo_toolkit.studies.accuracy import AccuracyResult
    why = "RK4 step 0.0001 s left the stability region along the run: |lambda| = 1.6e+08 1/s"
    runs = tuple({"method": m, "dt_s": dt, "wall_s": math.nan, "error": math.nan, "failed": why}
                 for m in ("rk4", "paper") for dt in (1e-4, 5e-5)) + (
        {"method": "reference:LSODA", "dt_s": None, "wall_s": 2.0, "error": 0.0},)
    res = AccuracyResult(runs, math.nan, math.nan, 2.0, 0.035, 0.2, "study", self_order=math.nan)
    text = res.table()
    assert not re.search(r"\bnan\b", text), text
    assert text.count("failed: " + why) == 4
    assert "RK4 not measured (no step ran), self-convergence not measured; paper scheme not measured" in text
