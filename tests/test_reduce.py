"""Leaving out what a study does not need: a-priori estimates against measured differences."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from servo_toolkit import SceneError, load_scene
from servo_toolkit.cli import main
from servo_toolkit.studies.reduce import reduce, reduced_options

from .conftest import build, variant


#: explicit frequencies replace the study's (and the 8 Hz that a sweep study always gets)
LOW = [1.0, 3.0]


@pytest.fixture
def slow_sweep(ema_dict):
    """The reference EMA with its sweep limited to 1 and 3 Hz, well below the 32 Hz mode."""
    return build(variant(ema_dict, studies__sweep__frequencies=["1 Hz", "3 Hz"]))


def test_low_frequency_study_leaves_out_the_compliance_within_its_bound(slow_sweep):
    """At 1-3 Hz the drivetrain mode (32 Hz) and the inductance do not matter: the reduced
    model is rigid with an ideal current loop, and the measured sine-dwell difference is
    within the bound and close to the first-order estimate (the estimate is not a loose
    upper bound but predicts the difference)."""
    res = reduce(slow_sweep, "sweep", frequencies=LOW, progress=False)
    left = {e.effect for e in res.plan.omitted}
    assert {"drivetrain compliance", "armature inductance"} <= left
    assert res.reduced_options["compliance"] is False and res.reduced_options["inductance"] is False
    assert res.within_bound
    assert res.measured <= res.bound
    assert 0.5 * res.plan.predicted <= res.measured <= 2.0 * res.plan.predicted
    assert res.to_dict()["within_bound"] is True
    # no timing of one noisy run in any view (a reduced model once "ran slower" than the full one)
    for view in (res.table(), json.dumps(res.to_dict(), default=str), res._repr_html_(), repr(res)):
        assert not re.search(r"wall|\d s / \d", view), view[:200]


def test_a_named_sweep_study_gets_8hz_unless_frequencies_are_given(slow_sweep):
    """Without explicit frequencies the study's 1 and 3 Hz gain the seed's 8 Hz, where the
    compliance (32 Hz mode) matters more: its estimate grows roughly as f^2."""
    with_8 = reduced_options(slow_sweep, "sweep")[1]
    low = reduced_options(slow_sweep, "sweep", frequencies=LOW)[1]
    comp = {p: next(e for e in plan.effects if e.effect == "drivetrain compliance") for p, plan in
            (("8", with_8), ("low", low))}
    assert comp["8"].estimate > 3 * comp["low"].estimate
    assert "8 Hz" in comp["8"].quantity


def test_tighter_tolerance_keeps_more(slow_sweep):
    """A bound below the compliance's estimate keeps the compliance; the measurement then
    still meets the tighter bound."""
    loose = reduced_options(slow_sweep, "sweep", frequencies=LOW)[1]
    tight = reduce(slow_sweep, "sweep", tolerance=1e-4, frequencies=LOW, progress=False)
    assert len(tight.plan.omitted) < len(loose.omitted)
    assert "drivetrain compliance" not in {e.effect for e in tight.plan.omitted}
    assert tight.within_bound


def test_resonance_in_band_keeps_the_compliance():
    """The default sweep reaches 40 Hz, past the drivetrain mode: the compliance stays, and
    its estimate says why (order one)."""
    _, plan = reduced_options(load_scene())
    comp = next(e for e in plan.effects if e.effect == "drivetrain compliance")
    assert not comp.omitted and comp.estimate > 0.1
    assert "resonance" in comp.quantity


def test_time_study_reduction_within_bound():
    """The 8 Hz kv motion run as closed-loop simulations: output-angle RMS difference of
    the reduced model within the bound."""
    res = reduce(load_scene(), "kv_8hz", progress=False)
    assert res.measure == "trace"
    assert res.plan.omitted and res.within_bound
    assert np.all(np.isfinite(res.difference))


def test_unsupported_study_names_the_key(ema_dict):
    """A ramp trajectory cannot be reduced by sine measures (nor run as a Kv study): the
    scene loader refuses it, naming the key."""
    with pytest.raises(SceneError, match=r"studies\.kv_8hz\.trajectory"):
        build(variant(ema_dict, studies__kv_8hz__trajectory="ramp"))


def test_cli_reduce(capsys, scenes_dir):
    """``reduce --estimate-only --json`` lists every effect with its estimate; a bad
    tolerance exits 2."""
    path = str(scenes_dir / "ema_reference.toml")
    assert main(["reduce", path, "--estimate-only", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert {e["effect"] for e in out["effects"]} >= {"armature inductance", "backlash", "drivetrain compliance"}
    assert all("reason" in e and "estimate_relative" in e for e in out["effects"])
    assert main(["reduce", path, "--tolerance", "2"]) == 2
    capsys.readouterr()


def test_kv_stroke_start_up_saturation_is_outside_the_compared_window():
    """The 30 deg, 0.6 s stroke motion needs at most 8.1 N*m from the motor in steady state
    (rigid inverse dynamics, lossless: 40 A < the 60 A limit), but the sine command starts
    with its full slope, so the start-up transient reaches the current limit. Saturation is
    judged over the compared window, as the sweep does: the point is in the linear range and
    its measured difference is within the bound (not NaN)."""
    from servo_toolkit.studies.inverse_dynamics import inverse_dynamics
    from servo_toolkit.loop import design as st_design
    from servo_toolkit.studies.trajectories import SineMotion
    scene = load_scene()
    motion = SineMotion(np.radians(30.0), 1 / 0.6, scene.drivetrain.mid_stroke)
    need = inverse_dynamics(scene.drivetrain, motion, motion.times(400), losses="none").peak_motor_torque
    assert need / scene.motor.torque_constant < scene.motor.current_limit
    # the stiff loop designed at q0 alone (18.7 Hz): its start-up transient hits the limit
    stiff = st_design(scene, over_stroke=False).controller
    res = reduce(scene, "kv_stroke", controller=stiff, progress=False)
    assert not res.saturated.any() and res.bound_applies
    assert np.isfinite(res.measured) and res.within_bound is True
    assert any("start-up transient" in n for n in res.notes)
    assert not re.search(r"\bnan\b", res.table())


def test_no_point_within_the_limits_makes_the_bound_not_applicable(ema_dict):
    """With the current limit at 30 A the stroke motion's steady state needs more (~40 A,
    rigid inverse dynamics): every point saturates in the window, so the linear bound does
    not apply. within_bound is None (not False), and the text says why and gives the
    difference at the saturated points instead of 'nan ... NOT within'."""
    scene = build(variant(ema_dict, motor__current_limit="30 A"))
    res = reduce(scene, "kv_stroke", progress=False)
    assert res.saturated.all() and not res.bound_applies
    assert res.within_bound is None and res.verdict == "not applicable"
    d = res.to_dict()
    assert d["within_bound"] is None and d["bound_applies"] is False
    assert np.isfinite(d["measured_saturated_relative"])
    text = res.table()
    assert "no point stayed within the current and voltage limits" in text
    assert "does not apply" in text and "NOT within" not in text and not re.search(r"\bnan\b", text)
    assert f"{res.measured_saturated:.2e}" in text
