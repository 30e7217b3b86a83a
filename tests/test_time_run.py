"""Time simulations as studies: the reduced model by default, and what leaving out costs."""

from __future__ import annotations

import json

import numpy as np
import pytest

import servo_toolkit as st
from servo_toolkit.cli import main
from servo_toolkit.studies.time.run import simulate_study

from .conftest import SCENES


def _settled_output(res, cycles=2, freq=8.0):
    t = res.times
    k = res.state_names.index("output_angle_rad")
    keep = t >= t[-1] - cycles / freq
    return t[keep], res.states[keep, k]


def test_reduced_run_stays_within_its_a_priori_bound():
    """The default 8 Hz, 2 deg run: the reduced model leaves effects out and says so; the
    settled output of the full model differs from it by less than the stated bound
    (relative to the motion amplitude)."""
    scene = st.load_scene()
    reduced = simulate_study(scene)
    full = simulate_study(scene, full=True)
    assert any(n.startswith("reduced model for 8 Hz, 2 deg: left out") for n in reduced.notes)
    assert any(n.startswith("full model") for n in full.notes)
    # the model itself changed: the reduced one runs a constant inertia, the full one does not
    # (the armature inductance, estimated at 0.0101 since the loss no longer acts on the
    # rotor's own torque, now exceeds what the budget leaves and is kept)
    assert any(n.startswith("constant inertia") for n in reduced.notes)
    assert not any(n.startswith("constant inertia") for n in full.notes)
    t_r, y_r = _settled_output(reduced)
    t_f, y_f = _settled_output(full)
    y_f_on_r = np.interp(t_r, t_f, y_f)
    amplitude = np.radians(2.0)
    difference = np.max(np.abs(y_r - y_f_on_r)) / amplitude
    assert 0 < difference <= 0.02, difference   # the plan's default tolerance


def test_cli_simulate_says_which_model_ran(capsys):
    assert main(["simulate", str(SCENES / "ema_reference.toml"), "--json", "--method", "rk4", "--dt", "1e-4"]) == 0
    reduced = json.loads(capsys.readouterr().out)
    assert any("reduced model" in n and "left out" in n for n in reduced["notes"])
    assert main(["simulate", str(SCENES / "ema_reference.toml"), "--json", "--full", "--method", "rk4", "--dt", "1e-5"]) == 0
    full = json.loads(capsys.readouterr().out)
    assert any(n.startswith("full model") for n in full["notes"])
    assert not any("inductance left out" in n for n in full["notes"])


def test_default_run_of_an_output_travel_is_a_millimetre_sine():
    """A linear actuator's default run commands 1 mm at 8 Hz (not 2 deg read as 35 mm)."""
    scene = st.load_scene(SCENES / "linear_roller_screw_actuator.toml")
    res = simulate_study(scene)
    assert any("8 Hz, 1 mm" in n for n in res.notes)
    assert np.max(np.abs(res.reference_angle - np.mean(res.reference_angle))) == pytest.approx(1e-3, rel=1e-2)
    assert np.max(np.abs(res.motor_current)) < scene.motor.current_limit
