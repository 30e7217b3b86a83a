"""Leaving out what a study does not need: a-priori estimates against measured differences."""

from __future__ import annotations

import json
import math
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
    res = reduce(slow_sweep, "sweep", frequencies=LOW, progress=False, per_effect=False)
    left = {e.effect for e in res.plan.omitted}
    assert {"drivetrain compliance", "armature inductance"} <= left
    assert res.reduced_options["compliance"] is False and res.reduced_options["inductance"] is False
    assert res.within_bound
    assert res.measured <= res.bound
    assert 0.5 * res.plan.predicted <= res.measured <= 2.0 * res.plan.predicted
    assert res.to_dict()["within_bound"] is True
    assert math.isnan(res.measured_saturated)  # no saturated point: no figure, written as null
    strict = json.loads(json.dumps(res.to_dict(), allow_nan=False, default=str))
    assert strict["measured_saturated_relative"] is None
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


def test_a_plan_judged_once_is_handed_to_reduce(slow_sweep):
    """``reduce`` given the plan of :func:`reduced_options` for the same points reduces as it
    would have judged itself, and refuses a plan judged for other frequencies or another
    tolerance (before any run)."""
    _, plan = reduced_options(slow_sweep, "sweep", frequencies=LOW)
    given = reduce(slow_sweep, "sweep", frequencies=LOW, reduction=plan, progress=False, per_effect=False)
    own = reduce(slow_sweep, "sweep", frequencies=LOW, progress=False, per_effect=False)
    assert given.reduced_options == own.reduced_options
    assert given.to_dict() == own.to_dict()
    with pytest.raises(ValueError, match="other frequencies"):
        reduce(slow_sweep, "sweep", frequencies=[1.0, 4.0], reduction=plan, progress=False)
    with pytest.raises(ValueError, match="tolerance"):
        reduce(slow_sweep, "sweep", frequencies=LOW, tolerance=0.01, reduction=plan, progress=False)


def test_the_plan_shows_itself(slow_sweep):
    """The a-priori plan (what ``reduce --estimate-only`` gives) in one line, a card and a
    figure: one bar per effect at its estimate, against the budget of the effects left out
    (half the tolerance) and the tolerance."""
    import matplotlib
    matplotlib.use("Agg")
    from .conftest import closed_tags
    _, plan = reduced_options(slow_sweep, "sweep", frequencies=LOW)
    text = repr(plan)
    assert text.startswith(f"<ReductionPlan: {len(plan.effects)} effects at 1-3 Hz; left out ") and "\n" not in text
    assert "armature inductance" in text and "of the budget 0.01>" in text
    html = plan._repr_html_()
    assert closed_tags(html) and "<svg" in html and all(e.effect in html for e in plan.effects)
    ax = plan.plot()
    bars = ax.patches
    assert len(bars) == len(plan.effects)
    drawn = [(b.get_x() + b.get_width(), e.estimate) for b, e in zip(bars, plan.effects) if 0 < e.estimate < math.inf]
    assert drawn and all(end == pytest.approx(est) for end, est in drawn)
    assert sorted(line.get_xdata()[0] for line in ax.get_lines()) == [plan.tolerance / 2, plan.tolerance]


def test_tighter_tolerance_keeps_more(slow_sweep):
    """A bound below the compliance's estimate keeps the compliance. The measurement meets the
    tighter bound but for one effect the linear estimates do not see, which reduce measures on
    its own: lumping the chain's upper modes (estimate 3e-6) also lumps where the losses'
    direction is judged (past the rotor's node in the full chain, past the whole motor side in
    the two-mass reduction), about 1e-4 at 1 Hz under the 700 N*m hinge moment."""
    loose = reduced_options(slow_sweep, "sweep", frequencies=LOW)[1]
    modes = "drivetrain modes above the first"
    tight = reduce(slow_sweep, "sweep", tolerance=1e-4, frequencies=LOW, progress=False, per_effect=[modes])
    assert len(tight.plan.omitted) < len(loose.omitted)
    assert "drivetrain compliance" not in {e.effect for e in tight.plan.omitted}
    (modes,) = tight.per_effect
    assert modes.measured > 10 * modes.estimate  # what the per-effect measurement is for
    assert tight.measured <= tight.bound + modes.measured


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
    res = reduce(load_scene(), "kv_8hz", progress=False, per_effect=False)
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


def test_estimate_only_refuses_what_the_runs_refuse(capsys, scenes_dir, ema_dict):
    """A frequency the sampled loop cannot track (above a quarter of the 10 kHz sample rate)
    and frequencies given for a time study exit 2 with or without the runs; a motor-gear kv
    study is judged at its output amplitude A / N."""
    path = str(scenes_dir / "ema_reference.toml")
    for extra in ([], ["--estimate-only"]):
        assert main(["reduce", path, "--frequency", "4000", *extra]) == 2
        assert "--frequency: must be at most 2500 Hz" in capsys.readouterr().err
    with pytest.raises(SceneError, match=r"studies\.kv_8hz\.kind.*frequencies"):
        reduced_options(load_scene(path), "kv_8hz", frequencies=[10.0])
    fast = build(variant(ema_dict, studies__kv_8hz__frequency="3000 Hz"))
    with pytest.raises(SceneError, match=r"studies\.kv_8hz\.frequency: must be at most 2500 Hz"):
        reduced_options(fast, "kv_8hz")
    scene = build(variant(ema_dict, studies__kv_8hz__amplitude_at="motor"))
    n0 = float(scene.drivetrain.ratio([scene.drivetrain.mid_stroke])[0][0])
    _, plan = reduced_options(scene, "kv_8hz")
    assert plan.to_dict()["amplitudes_deg"] == pytest.approx([a / n0 for a in (2.0, 3.0, 4.0)], rel=1e-9)


def test_kv_stroke_start_up_saturation_is_outside_the_compared_window():
    """The 30 deg, 0.6 s stroke motion needs at most 8.1 N*m from the motor in steady state
    (rigid inverse dynamics, lossless: 40 A < the 60 A limit), but the sine command starts
    with its full slope, so the start-up transient reaches the current limit. Saturation is
    judged over the compared window, as the sweep does: the point is in the linear range and
    its measured difference is within the bound (not NaN)."""
    from servo_toolkit.studies.mechanisms.inverse_dynamics import inverse_dynamics
    from servo_toolkit.loop import design as st_design
    from servo_toolkit.studies.trajectories import SineMotion
    scene = load_scene()
    motion = SineMotion(np.radians(30.0), 1 / 0.6, scene.drivetrain.mid_stroke)
    need = inverse_dynamics(scene.drivetrain, motion, motion.times(400), losses="none").peak_motor_torque
    assert need / scene.motor.torque_constant < scene.motor.current_limit
    # the stiff loop designed at q0 alone (18.7 Hz): its start-up transient hits the limit
    stiff = st_design(scene, over_stroke=False).controller
    res = reduce(scene, "kv_stroke", controller=stiff, progress=False, per_effect=False)
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
    res = reduce(scene, "kv_stroke", progress=False, per_effect=False)
    assert res.saturated.all() and not res.bound_applies
    assert res.within_bound is None and res.verdict == "not applicable"
    d = res.to_dict()
    assert d["within_bound"] is None and d["bound_applies"] is False
    assert np.isfinite(d["measured_saturated_relative"])
    text = res.table()
    assert "no point stayed within the current and voltage limits" in text
    assert "does not apply" in text and "NOT within" not in text and not re.search(r"\bnan\b", text)
    assert f"{res.measured_saturated:.2e}" in text
    # an effect measured on its own has no figure within the limits either: its line says so
    # rather than printing NaN as "inf dB / inf deg"
    from dataclasses import replace
    from servo_toolkit.studies.reduce import EffectCost
    alone = replace(res, per_effect=(EffectCost("backlash", 0.0, math.nan, 2.12e-4),)).table()
    line = next(s for s in alone.splitlines() if s.lstrip().startswith("backlash") and "measured" in s)
    assert "inf" not in line and not re.search(r"\bnan\b", line), line
    assert "no point within the limits" in line and "2.12e-04 where a limit was reached" in line


def test_each_effect_left_out_is_measured_on_its_own_with_the_chain_s_modes():
    """A three-mass chain (modes 232 and 323 Hz) at 20 Hz: simulate's rule lumps the second
    mode, and reduce names it with its frequency, runs the full model with only that switch
    changed (chain "full" against "two_mass") and measures its cost, here the whole
    reduction's: close to its estimate and within the bound."""
    from .test_sim_full_chain import three_mass
    res = reduce(three_mass(), frequencies=[20.0], amplitudes=[np.radians(1.0)], progress=False)
    modes = next(e for e in res.plan.effects if e.effect == "drivetrain modes above the first")
    assert modes.omitted and "323.5 Hz" in modes.quantity and "RK4 step" in modes.quantity
    cost = {c.effect: c for c in res.per_effect}
    assert set(cost) == {e.effect for e in res.plan.omitted}
    alone = cost["drivetrain modes above the first"]
    assert 0.5 * alone.estimate < alone.measured < 2 * alone.estimate and alone.measured < res.bound
    assert alone.measured == pytest.approx(res.measured, rel=1e-6)  # the only effect left out
    assert "each effect on its own" in res.table() and res.to_dict()["per_effect"][0]["effect"] == alone.effect


def test_the_backlash_estimate_takes_the_two_mass_reduction_s_load_side():
    """A rigid gear followed by a compliant shaft: the gear wheel turns with the output but sits
    on the motor side of the shaft, so the inertia the backlash's dynamic force accelerates
    is the load's alone (the chain's two-mass reduction), not the load and the wheel."""
    import math

    from servo_toolkit.components.compliance import Compliance, Load
    from servo_toolkit.components.gear import GearTrain
    from servo_toolkit.components.motor import DCMotor
    from servo_toolkit.scene.loader import Scene
    from servo_toolkit.sim import controller_for
    from servo_toolkit.studies.reduce.estimates import load_side_inertia, loop_response, plan_reduction
    from servo_toolkit.plant.linear import plant_parameters
    motor = DCMotor(resistance=0.5, inductance=1e-3, torque_constant=0.2, back_emf_constant=0.2,
                    rotor_inertia=2e-4, viscous_friction=1e-4, coulomb_friction=0.0, current_limit=20.0)
    j_wheel, j_load = 0.05, 0.6
    gear = GearTrain("gear", ratio=20.0, inertias=(1.5e-4, j_wheel), backlash=math.radians(0.2))
    sc = Scene("lash", motor=motor, stages=(gear, Compliance("shaft", 2e4)), load=Load(inertia=j_load, hinge_moment=5.0))
    assert load_side_inertia(sc.drivetrain, 0.0) == pytest.approx(j_load, rel=1e-9)
    ctrl = controller_for(sc)[0]
    plan = plan_reduction(sc, ctrl, [5.0, 20.0], [math.radians(1.0)])
    lash = next(e for e in plan.effects if e.effect == "backlash")
    w = 2 * np.pi * np.array([5.0, 20.0])
    t = loop_response(plant_parameters(sc, 0.0, structural_damping=0.02), ctrl, motor, w)["theta"]
    dynamic = float(np.max(np.abs(-j_load * w**2 * t))) * math.radians(1.0)
    assert f"{dynamic:.4g} N*m dynamic" in lash.quantity
    assert f"{float(np.max(np.abs(-(j_load + j_wheel) * w**2 * t))) * math.radians(1.0):.4g}" not in lash.quantity


def test_a_failed_run_is_reported_as_failed_not_saturated(monkeypatch):
    """A point whose run fails on the reduced model (here the 3 deg run, its result replaced
    by a failure as a non-finite state gives one) has no difference: it is reported as
    failed with its reason in the table, the JSON and the plot, is not counted as saturated,
    and the measured difference and the verdict are over the one point that ran on both."""
    import servo_toolkit.studies.reduce.run as reduce_module
    true_case, seen = reduce_module._trace_case, []

    def failing_case(case):
        model, amp = case[0], case[1]
        seen.append(model.options)
        if model.options != seen[0] and amp > np.radians(2.5):  # the reduced model, 3 deg
            return {"error": "the state became non-finite at t = 0.3 s"}
        return true_case(case)
    monkeypatch.setattr(reduce_module, "_trace_case", failing_case)
    res = reduce(load_scene(), "kv_8hz", amplitudes=np.radians([2.0, 3.0]), progress=False, per_effect=False)
    assert res.failed.tolist() == [[False], [True]] and not res.saturated.any()
    assert np.isnan(res.difference[1, 0]) and np.isfinite(res.difference[0, 0])
    assert res.measured == res.difference[0, 0] and res.within_bound is True
    text = res.table()
    assert "over 1 of 2 point(s) (1 failed)" in text
    assert "FAILED at 8 Hz, 3 deg (not compared): reduced model: the state became non-finite" in text
    assert "inf" not in text and "reached a limit" not in text
    d = res.to_dict()
    assert (d["points_failed"], d["points_compared"], d["points_saturated"]) == (1, 1, 0)
    assert d["points"][1]["failed"] and not d["points"][1]["saturated"]
    assert d["points"][1]["error"].startswith("reduced model: the state became non-finite")
    assert d["points"][0]["error"] is None and not math.isinf(d["measured_relative"])
    labels = [line.get_label() for line in res.plot().get_lines()]
    assert "run failed (not compared)" in labels
    assert "1 point(s) failed" in repr(res)
    assert res.failed_text().startswith("8 Hz, 3 deg: reduced model: the state became non-finite")
    # an effect measured on its own counts its failed points too
    from dataclasses import replace
    from servo_toolkit.studies.reduce import EffectCost
    alone = replace(res, per_effect=(EffectCost("backlash", 1e-3, 2e-4, math.nan, failed=1),))
    assert "1 point(s) failed, not compared" in alone.table()
    assert alone.to_dict()["per_effect"][0]["failed_points"] == 1


def test_a_failed_dwell_is_not_a_saturated_point():
    """The sweep measure: a dwell that failed on one model (saturated before failing) or on
    both is failed, with the models' reasons, and neither saturated nor infinite."""
    from types import SimpleNamespace

    from servo_toolkit.studies.reduce.run import _difference
    nan = complex(math.nan, math.nan)
    full = SimpleNamespace(response=np.array([[1.0 + 0j, 0.5j, nan]]), saturated=np.array([[False, False, True]]),
                           errors=(None, None, "left its domain at t = 1 s"))
    red = SimpleNamespace(response=np.array([[1.01 + 0j, nan, nan]]), saturated=np.array([[False, True, True]]),
                          errors=(None, "non-finite at t = 2 s", "non-finite at t = 1 s"))
    diff, sat, why = _difference(full, red, ("full", "reduced"))
    assert diff[0, 0] == pytest.approx(0.01) and np.isnan(diff[0, 1:]).all()
    assert not sat.any()
    assert why == (None, "reduced model: non-finite at t = 2 s",
                   "full model: left its domain at t = 1 s; reduced model: non-finite at t = 1 s")
