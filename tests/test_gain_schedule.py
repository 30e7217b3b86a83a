"""Gains scheduled along the stroke: the factors' closed form, the crossover kept within 5 %
over the reference EMA's stroke (24 % without), the margins' spread smaller, the linear
figures against python-control, and the compiled sample applying the table."""

from __future__ import annotations

from dataclasses import replace

import control as ct
import numpy as np
import pytest

from servo_toolkit.errors import SceneError
from servo_toolkit.loop import design
from servo_toolkit.loop.closed_loop import open_loop
from servo_toolkit.loop.schedule import GainSchedule, crossover_hz, gain_schedule
from servo_toolkit.loop.stroke import stroke_check
from servo_toolkit.scene.loader import load_scene

from .conftest import SCENES


@pytest.fixture(scope="module")
def ema():
    scene = load_scene(SCENES / "ema_reference.toml")
    result = design(scene, progress=False)
    schedule = gain_schedule(scene, result.q0)
    scheduled = stroke_check(scene, replace(result.controller, schedule=schedule), result.q0)
    return scene, result, schedule, scheduled


def test_factors_are_the_closed_form(ema):
    scene, result, schedule, _ = ema
    drive = scene.drivetrain
    q = np.array(schedule.q)
    n, j = np.abs(drive.ratio(q)[0]), drive.inertia(q)[0]
    n0, j0 = abs(drive.ratio([result.q0])[0][0]), drive.inertia([result.q0])[0][0]
    np.testing.assert_allclose(schedule.speed_factor, (j / n**2) / (j0 / n0**2), rtol=1e-12)
    np.testing.assert_allclose(schedule.error_factor, (j / n) / (j0 / n0), rtol=1e-12)
    ge, gw = schedule.factors([result.q0])
    assert ge[0] == pytest.approx(1.0, abs=2e-3) and gw[0] == pytest.approx(1.0, abs=2e-3)
    # held beyond the ends
    lo, hi = drive.stroke
    assert schedule.factors([lo - 1.0])[0][0] == schedule.error_factor[0]
    assert schedule.factors([hi + 1.0])[1][0] == schedule.speed_factor[-1]
    assert GainSchedule.from_dict(schedule.to_dict()) == schedule


def test_scheduled_crossover_within_5_percent_over_the_stroke(ema):
    _, result, _, scheduled = ema
    fixed = result.stroke
    assert scheduled.all_stable and scheduled.scheduled and not fixed.scheduled
    k0 = int(np.argmin(np.abs(scheduled.q - result.q0)))
    dev = np.abs(scheduled.crossover_hz / scheduled.crossover_hz[k0] - 1)
    assert np.max(dev) <= 0.05
    # the fixed gains are far from it (the rocker's ratio and inertia move by ~10 %)
    assert np.max(np.abs(fixed.crossover_hz / fixed.crossover_hz[k0] - 1)) > 0.15
    a, b = fixed.spread(), scheduled.spread()
    assert b["phase_margin_deg"] < 0.25 * a["phase_margin_deg"]
    assert b["gain_margin_db"] < a["gain_margin_db"]
    assert b["crossover_deviation_from_q0"] == pytest.approx(np.max(dev))


def test_stroke_figures_of_the_scaled_loop_match_python_control(ema):
    """At the stroke's end the scheduled check's crossover is python-control's on the loop of
    the controller scaled there (an independent assembly of the same loop)."""
    scene, result, schedule, scheduled = ema
    q_end = float(scheduled.q[-1])
    loop = open_loop(scene, schedule.scaled(result.controller, q_end), q_end)
    w = 2 * np.pi * np.logspace(-1, 2.5, 4000)
    fc = crossover_hz(w, ct.frequency_response(loop, w).complex.ravel())
    assert scheduled.crossover_hz[-1] == pytest.approx(float(fc), rel=0.02)
    gm, pm, *_ = ct.stability_margins(loop)
    assert scheduled.phase_margin_deg[-1] == pytest.approx(pm, abs=0.5)


def test_compiled_sample_applies_the_table(ema):
    """The kernel's sample with the schedule equals the sample of the controller scaled by
    the table's factors at the measured angle (linear between the points)."""
    from servo_toolkit.sim import ModelOptions, build_model
    from servo_toolkit.sim import layout as lo
    from servo_toolkit.sim.kernel import schedule_factors
    from servo_toolkit.sim.kernel import controller_sample
    from servo_toolkit.sim.reference import Reference, fill, initial_state
    scene, result, schedule, _ = ema
    exact = ModelOptions(quantization=False)  # the factors at the true angle in both
    on = build_model(scene, replace(result.controller, schedule=schedule), exact)
    q = 0.5 * (schedule.q[3] + schedule.q[4]) + 0.1 * (schedule.q[4] - schedule.q[3])
    got = schedule_factors(fill(on, Reference()), q)
    np.testing.assert_allclose(got, [f[0] for f in schedule.factors([q])], rtol=1e-14)
    scaled = build_model(scene, schedule.scaled(result.controller, q), exact)
    ref = Reference.step(0.01, offset=q)
    outs = []
    for model in (on, scaled):
        P = fill(model, ref)
        x = initial_state(model, P)
        x[1] = 0.3  # moving: the speed input counts too
        work = np.empty(model.nx)
        outs.append([controller_sample(t, x, P, model.T, work) for t in (0.0, 1e-4, 2e-4)])
    assert on.P[lo.FF_ON] == 1.0 and on.P[lo.SCHED] > 0
    np.testing.assert_allclose(outs[0], outs[1], rtol=1e-9)


def test_bad_schedule_and_continuous_controller(ema):
    scene, result, schedule, _ = ema
    from servo_toolkit.sim import ModelOptions, build_model
    with pytest.raises(SceneError) as err:
        build_model(scene, replace(result.controller, schedule=schedule), ModelOptions(controller_mode="continuous"))
    assert err.value.key == "schedule"
    with pytest.raises(SceneError):
        GainSchedule((0.0, 1.0, 3.0), (1.0, 1.0, 1.0), (1.0, 1.0, 1.0), 0.0)  # uneven points
    with pytest.raises(SceneError):
        gain_schedule(scene, points=1)
