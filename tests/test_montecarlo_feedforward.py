"""Monte Carlo with a feedforward: a variant's feedforward keeps the nominal model (a drive's
does not know the variant's inertia), and at the current limit the feedforward does not make
the error worse than the feedback alone (the clamp's back-calculation)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from servo_toolkit.loop.controller import Feedforward
from servo_toolkit.sim import simulate
from servo_toolkit.sim.variants import with_load_inertia
from servo_toolkit.studies.montecarlo import montecarlo
from servo_toolkit.studies.time.run import sine_run_options


DURATION = 0.5


@pytest.fixture(scope="module")
def runs(ema):
    """Variants at the nominal load, +30 % and 4x, with the feedback alone and with the
    model-based feedforward (nominal model)."""
    scene, controller = ema
    values = {"load_inertia": scene.load.inertia * np.array([1.0, 1.3, 4.0])}
    return {ff: montecarlo(scene, values, controller=controller, duration=DURATION, progress=False, feedforward=ff)
            for ff in ("off", "model")}


def test_variant_feedforward_keeps_the_nominal_load(ema, runs):
    """The +30 % variant's peak error is that of one run of the +30 % scene whose feedforward
    assumes the nominal load, and larger than with a feedforward that knows the variant's."""
    scene, controller = ema
    mc = runs["model"]
    assert mc.settings["feedforward"]["load_inertia"] == scene.load.inertia
    variant = with_load_inertia(scene, 1.3 * scene.load.inertia)
    ref = _reference_of(mc)
    options, _ = sine_run_options(scene, replace(controller, feedforward=Feedforward(
        model=True, load_inertia=scene.load.inertia)), ref)  # the Monte Carlo's model
    errors = {}
    for name, assumed in (("nominal", scene.load.inertia), ("own", None)):
        r = simulate(variant, controller, reference=ref, duration=DURATION, options=options, method="rk4",
                     dt=mc.dt_s, output_dt=mc.dt_s, feedforward=Feedforward(model=True, load_inertia=assumed))
        errors[name] = float(np.max(np.abs(r.output_angle - r.reference_angle)))
        errors["settled_" + name] = r.settled_tracking_error
    assert mc.tracking_error[1] == pytest.approx(errors["nominal"], rel=1e-6)
    # the nominal model is a real mismatch: once the start's transient (which saturates the
    # current either way and sets the whole run's peak) has passed, it tracks worse (0.28 deg
    # against 0.27 deg: the feedforward misses 5 % of the variant's inertia)
    assert errors["settled_own"] < errors["settled_nominal"]


def _reference_of(mc):
    """The Monte Carlo's command as a Reference."""
    from servo_toolkit.sim import Reference
    d = mc.settings["reference"]
    return Reference(d["kind"], d["amplitude"], d["frequency_Hz"], d["offset_rad"], d["t0_s"])


def test_saturated_variant_feedforward_not_worse_than_feedback(ema, runs):
    """4x the load inertia: the current saturates with or without the feedforward; its error
    with the feedforward stays at most the feedback's (without the clamp's back-calculation
    the feedback winds up against the feedforward's current: 3.9 deg by the feedback alone,
    15 deg with the nominal feedforward and 14 deg with one knowing the load; with it 3.5 deg
    by the feedback alone, which the clamp now back-calculates too, 3.0 and 2.4 deg)."""
    scene, controller = ema
    off, on = runs["off"], runs["model"]
    assert off.saturated[2] and on.saturated[2]
    assert on.tracking_error[2] <= off.tracking_error[2] * 1.02
    knowing = montecarlo(scene, {"load_inertia": np.array([4.0 * scene.load.inertia])}, controller=controller,
                         duration=DURATION, progress=False,
                         feedforward=Feedforward(model=True, load_inertia=4.0 * scene.load.inertia))
    assert knowing.saturated[0]
    assert knowing.tracking_error[0] <= off.tracking_error[2] * 1.02
    # below the limit the feedforward pays: the nominal variant's peak, its start's transient
    # included, falls by more than half
    assert on.tracking_error[0] < 0.5 * off.tracking_error[0]
