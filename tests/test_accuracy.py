"""Accuracy study and the simulate/accuracy commands."""

from __future__ import annotations

import json
import math

from servo_toolkit import load_scene
from servo_toolkit.cli import main
from servo_toolkit.sim import ModelOptions, Reference, build_model, default_controller
from servo_toolkit.sim.accuracy import accuracy_study

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
    from servo_toolkit.sim.accuracy import _order
    dts = [1e-4, 5e-5, 2.5e-5, 1.25e-5, 6.25e-6]
    fourth = [1e-3 * (d / 1e-4) ** 4 for d in dts[:3]]
    assert abs(_order(dts, fourth + [3.5e-6, 3.5e-6]) - 4.0) < 1e-9
    assert abs(_order(dts[::-1], (fourth + [3.5e-6, 3.5e-6])[::-1]) - 4.0) < 1e-9   # any order of the ladder
    assert abs(_order(dts, [1e-3 * d / 1e-4 for d in dts]) - 1.0) < 1e-9         # no plateau: every point
