"""Command shaping through the toolkit's simulation: a ZV shaper on the closed loop's mode
cancels the residual vibration a fast move leaves in the two-mass chain to the theory's
level; the move's feedforward tracking; the shaper's mode and damping from the model."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from servo_toolkit.loop.shaper import drivetrain_modes, shaper_for
from servo_toolkit.plant.linear import DEFAULT_STRUCTURAL_DAMPING
from servo_toolkit.sim import ModelOptions, Reference, simulate


#: the two-mass chain with what would blur a mode left out: no lash, no Coulomb friction, no
#: loss switching with the power flow, J(q0) along the stroke, no encoder quantization
LINEAR = ModelOptions(chain="two_mass", play=0.0, friction="off", efficiency=False, variable_inertia=False,
                      quantization=False, damping_ratio=DEFAULT_STRUCTURAL_DAMPING)
#: a fast 0.5 deg move (12 ms, shorter than the 33 ms mode period: it rings the mode)
MOVE = Reference.move(math.radians(0.5), math.radians(100), math.radians(2e4), math.radians(1e7), at=0.01)
DURATION = 0.4
REC = 5e-4


def _pencil(y, order):
    """Poles (per sample) of the damped exponentials in y (matrix pencil)."""
    n = y.size
    cols = n // 3
    H = np.array([y[i:i + cols + 1] for i in range(n - cols)])
    _, _, vt = np.linalg.svd(H, full_matrices=False)
    v = vt[:order].T
    return np.linalg.eigvals(np.linalg.pinv(v[:-1]) @ v[1:])


def _amplitudes(y, poles):
    """Least-squares complex amplitudes of y[k] = sum c_j z_j^k."""
    k = np.arange(y.size)[:, None]
    c, *_ = np.linalg.lstsq(poles[None, :] ** k, y.astype(complex), rcond=None)
    return c


def test_zv_cancels_the_residual_vibration_through_the_simulation(ema):
    scene, controller = ema
    shaper = shaper_for(scene, "zv", controller=controller)
    assert shaper.mode == "closed_loop"
    deflection = {}
    for name, sh in (("bare", None), ("zv", shaper)):
        r = simulate(scene, controller, reference=MOVE, duration=DURATION, options=LINEAR, method="rk4",
                     dt=1e-4, output_dt=REC, shaper=sh if sh is not None else "off")
        deflection[name] = r.trace("motor_side_angle_rad") - r.output_angle
    t = np.arange(deflection["bare"].size) * REC
    window = t >= 0.01 + MOVE.profile.duration + shaper.delay + 0.005  # the command is at rest
    poles = _pencil(deflection["bare"][window] - deflection["bare"][-1], 10)
    f = np.abs(np.angle(poles)) / (2 * math.pi * REC)
    zeta = -np.log(np.abs(poles)) / np.abs(np.log(poles.astype(complex)))
    k = int(np.argmin(np.where((f > 20) & (f < 40), np.abs(f - shaper.frequency), np.inf)))
    f_mode, z_mode = float(f[k]), float(zeta[k])
    # the simulated mode is the closed loop's pair the shaper was designed on (within 2 %)
    assert f_mode == pytest.approx(shaper.frequency, rel=0.02)
    amps = {name: abs(_amplitudes(y[window] - y[-1], poles)[k]) for name, y in deflection.items()}
    measured = amps["zv"] / amps["bare"]
    theory = shaper.residual_vibration(f_mode, z_mode)
    assert measured < 0.06  # the bare move's ring is cancelled ...
    assert measured == pytest.approx(theory, abs=0.03)  # ... to the theory's level at the simulated mode
    # a shaper on the free-free mode (the wrong one here) leaves what the theory says it does
    free = shaper_for(scene, "zv", controller=controller, mode="free")
    assert free.residual_vibration(f_mode, z_mode) > 3 * max(measured, 0.02)


def test_shaper_damping_from_the_model(ema):
    scene, controller = ema
    modes = drivetrain_modes(scene, controller)
    f_free, z_free = modes["free"]
    f_lock, _ = modes["locked"]
    f_cl, z_cl = modes["closed_loop"]
    assert z_free == DEFAULT_STRUCTURAL_DAMPING  # the plant's structural damping, not a fixed 0.05
    assert f_lock < f_cl < f_free  # the loop stiffens the motor side: between locked and free
    assert z_cl > z_free
    sh = shaper_for(scene, "zvd", controller=controller)
    assert (sh.frequency, sh.damping_ratio) == (f_cl, z_cl)
    assert sh.delay == pytest.approx(1.0 / (f_cl * math.sqrt(1 - z_cl**2)))


def test_move_feedforward_tracks_with_small_error(ema):
    """A 10 deg move along the stroke: the model-based feedforward cuts the feedback's peak
    error several times, and the run ends at the distance."""
    scene, controller = ema
    move = Reference.move(math.radians(10), math.radians(200), math.radians(4000), math.radians(2e5))
    err = {}
    for ff in ("off", "model"):
        r = simulate(scene, controller, reference=move, duration=0.25, feedforward=ff)
        err[ff] = float(np.max(np.abs(r.output_angle - r.reference_angle)))
        assert r.reference_angle[-1] - r.reference_angle[0] == pytest.approx(math.radians(10), rel=1e-9)
    assert err["model"] < 0.2 * err["off"], err
    assert err["model"] < 0.02 * math.radians(10)  # within 2 % of the move (0.17 deg; the mode's lag)
    with pytest.raises(ValueError):
        replace(move, profile=None)
