"""RK4 through the smooth signs' band: with the smooth friction, the Coulomb torque's and the
drivetrain loss's smooth signs tanh(omega_m / w_s) switch within a fraction of a millisecond at
every reversal, and a step that passes through that band is taken in substeps
(``servo_toolkit/_physics/integrate.h``, smooth_substeps). Checked against the stiff reference
solver at 1e-12, against RK4 itself at a step eight times finer, and for what it leaves alone."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from servo_toolkit import load_scene
from servo_toolkit.sim import ModelOptions, Reference, build_model, controller_for, run
from servo_toolkit.sim import layout as lo

AMP = math.radians(2.0)


@pytest.fixture(scope="module")
def ema():
    scene = load_scene()
    controller, _ = controller_for(scene)
    return scene, controller


def _model(scene, controller, **options):
    return build_model(scene, controller, ModelOptions(controller_mode="continuous", **options))


def _lossless(scene):
    return replace(scene, stages=tuple(replace(s, efficiency=1.0) if hasattr(s, "efficiency") else s
                                       for s in scene.stages))


def _error(model, dt, duration=0.5):
    ref = Reference.sine(AMP, 8.0)
    truth = run(model, ref, duration, "reference", output_dt=1e-3, rtol=1e-12, atol=1e-12).output_angle
    got = run(model, ref, duration, "rk4", dt, output_dt=1e-3)
    assert got.steps == round(duration / dt)  # substeps are no steps of the run's own
    return float(np.max(np.abs(got.output_angle - truth)) / AMP)


def test_the_reversals_cost_no_more_than_the_motion_between_them(ema):
    """The reference EMA's 8 Hz, 2 deg sine (continuous controller): at 0.2 ms a step through a
    reversal's band once made nearly all of the error, 7.5e-7 of the amplitude against 1e-9
    for the same run without the drivetrain's loss, whose smooth sign switches the loss from
    driving to back-driving there. With the band in substeps the run is within 2e-8, about
    the lossless run's error; and the error falls with the step (fourth order between the
    reversals)."""
    scene, controller = ema
    lossy = _model(scene, controller)
    assert lossy.P[lo.ETA_MEAN] > 0.0 and lossy.P[lo.STICK] == 0.0
    coarse, fine = _error(lossy, 2e-4), _error(lossy, 1e-4)
    lossless = _error(_model(_lossless(scene), controller), 2e-4)
    assert coarse < 2e-8, coarse
    assert coarse < 20 * max(lossless, 1e-10), (coarse, lossless)
    assert fine < coarse / 4, (fine, coarse)


def test_a_band_step_is_eight_rk4_steps_of_an_eighth(ema):
    """A step through the band equals RK4 at an eighth of the step over it: a run at dt and a
    run at dt / 8 differ only by what the steps outside the band make (the fine run's error
    alone there), far less than the coarse run's distance from the truth without substeps."""
    scene, controller = ema
    model = _model(scene, controller)
    ref = Reference.sine(AMP, 8.0)
    dt = 2e-4
    coarse = run(model, ref, 0.2, "rk4", dt, output_dt=1e-3).output_angle
    eighth = run(model, ref, 0.2, "rk4", dt / lo.SMOOTH_SUBSTEPS, output_dt=1e-3).output_angle
    truth = run(model, ref, 0.2, "reference", output_dt=1e-3, rtol=1e-12, atol=1e-12).output_angle
    assert np.max(np.abs(coarse - eighth)) <= 2.0 * np.max(np.abs(coarse - truth)) + 1e-12
    assert np.max(np.abs(coarse - truth)) / AMP < 2e-8


def test_a_chain_without_a_smooth_sign_takes_its_steps_as_they_are(ema):
    """The substeps are the smooth signs': a chain with neither a Coulomb torque nor a loss
    has none, and its RK4 run at 0.1 ms is within the truth's own precision of it."""
    scene, controller = ema
    plain = _model(_lossless(replace(scene, motor=replace(scene.motor, coulomb_friction=0.0))), controller)
    assert plain.P[lo.TC] == 0.0 and plain.P[lo.ETA_MEAN] == 0.0
    assert _error(plain, 1e-4) < 1e-9
