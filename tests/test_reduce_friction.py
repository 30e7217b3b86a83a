"""`reduce` and friction that holds: the full model sticks, the estimate of leaving stick out is
an upper one, and the study measures the cost with and without stick."""

from __future__ import annotations

import math

import numpy as np
import pytest

from servo_toolkit.sim import ModelOptions, Reference, build_model, controller_for, run
from servo_toolkit.studies.reduce import plan_reduction, reduce, reduced_options
from servo_toolkit.studies.time.run import sine_run_options

from .conftest import build, variant

STICK = "friction that holds (stick)"


def sticky(ema_dict, amplitude="0.2 deg", breakaway="0.2 N*m"):
    return build(variant(ema_dict, motor__static_friction=breakaway, studies__kv_8hz__amplitudes=[amplitude]))


def test_stick_is_kept_where_friction_dominates_the_motion(ema_dict):
    """A 0.2 N*m breakaway (ten times the Coulomb level) against a 0.2 deg, 8 Hz motion:
    the estimate exceeds the budget, the reduced model keeps the stick and says why."""
    options, plan = reduced_options(sticky(ema_dict), "kv_8hz")
    effect = next(e for e in plan.effects if e.effect == STICK)
    assert effect.switch == "friction" and not effect.omitted and effect.estimate > plan.tolerance
    assert "motor breakaway 0.2 N*m" in effect.quantity and effect.reason.startswith("kept")
    assert options.friction == "stick"


def test_a_time_run_keeps_stick_where_friction_dominates_and_says_so(ema_dict):
    """``simulate``'s sine runs start from friction that holds: a 0.2 N*m breakaway against a
    0.2 deg, 8 Hz motion keeps it, and the notes name the motor's friction with its estimate."""
    scene = sticky(ema_dict)
    controller, _ = controller_for(scene)
    options, notes = sine_run_options(scene, controller, Reference.sine(math.radians(0.2), 8.0))
    assert options.friction == "stick" and STICK not in notes[0]
    line = next(n for n in notes if n.startswith("friction that holds (stick) kept"))
    assert "motor holds (estimate" in line


def test_a_time_run_smooths_the_motor_s_friction_where_it_costs_little(ema_dict):
    """The reference EMA's 0.02 N*m Coulomb friction against its 2 deg, 8 Hz sine: within the
    budget, the run smooths it and its notes say so, with the estimate."""
    scene = build(ema_dict)
    controller, _ = controller_for(scene)
    options, notes = sine_run_options(scene, controller, Reference.sine(math.radians(2.0), 8.0))
    line = next(n for n in notes if n.startswith("friction without stick"))
    est = float(line.split("motor smoothed, no stick (estimate ")[1].split(")")[0])
    assert options.friction == "smooth" and 0 < est <= 0.01
    assert f"{STICK} (estimate" in notes[0]


def _friction_only_cost(scene, controller, amplitude):
    """RMS output difference, stick against smooth (the two-mass model, every other effect
    kept), over the second half of a 1 s sine at 8 Hz, relative to the output's RMS about q0
    without stick (with stick a lossy chain at rest may hold the output still)."""
    runs = []
    for friction in ("stick", "smooth"):
        model = build_model(scene, controller, ModelOptions(damping_ratio=0.05, chain="two_mass", friction=friction,
                                                            stroke_end="stop"))
        r = run(model, Reference.sine(amplitude, 8.0), 1.0, "auto")
        runs.append((r.times, r.output_angle - model.q0))
    (t, q_full), (t_red, q_red) = runs
    keep = t >= 0.5
    diff = np.interp(t[keep], t_red, q_red) - q_full[keep]
    return float(np.sqrt(np.mean(diff**2) / np.mean(q_red[t_red >= 0.5]**2)))


@pytest.mark.parametrize("breakaway", ["0.02 N*m", "0.2 N*m"])
def test_the_estimate_is_an_upper_one(ema_dict, breakaway):
    """Measured with and without stick, the cost stays below the estimate at 0.05 deg (a few
    encoder counts, friction dominates) and at 2 deg; where friction dominates the estimate
    is within a factor 10 of the cost (it is not vacuous)."""
    scene = sticky(ema_dict, breakaway=breakaway)
    controller, _ = controller_for(scene)
    base = ModelOptions(damping_ratio=0.05, chain="two_mass", friction="stick")
    for amp_deg in (0.05, 2.0):
        amp = math.radians(amp_deg)
        plan = plan_reduction(scene, controller, [8.0], [amp], base=base)
        estimate = next(e for e in plan.effects if e.effect == STICK).estimate
        cost = _friction_only_cost(scene, controller, amp)
        assert cost <= estimate, (amp_deg, cost, estimate)
        if amp_deg == 0.05:
            assert cost >= estimate / 10, (cost, estimate)


def test_reduce_measures_leaving_stick_out(ema_dict):
    """The full model of ``reduce`` sticks; at 2 deg and a loose tolerance the reduced model
    leaves the stick out (the smooth friction), and the measured difference of the two runs
    is within the bound."""
    scene = sticky(ema_dict, amplitude="2 deg", breakaway="0.02 N*m")
    res = reduce(scene, "kv_8hz", tolerance=0.2, progress=False, per_effect=False)
    effect = next(e for e in res.plan.effects if e.effect == STICK)
    assert effect.omitted
    assert res.full_options["friction"] == "stick" and res.reduced_options["friction"] == "smooth"
    assert res.within_bound and np.isfinite(res.measured)
    assert STICK in res.table() and STICK in res.to_dict()["left_out"]
