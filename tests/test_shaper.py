"""ZV / ZVD input shapers on the drivetrain's lowest mode."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.signal import lsim

from servo_toolkit.loop.shaper import InputShaper, shaper_for
from servo_toolkit.scene.loader import load_scene

from .conftest import SCENES


def _residual(shaper, f_mode, zeta, j1=1.0, j2=3.0):
    """Residual deflection amplitude of a two-mass chain (mode f_mode, damping zeta) after a
    rigid-body move driven by a force step, shaped or not (shaper None)."""
    wn = 2 * math.pi * f_mode
    m = 1 / j1 + 1 / j2
    k = wn**2 / m
    c = 2 * zeta * wn / m
    # relative deflection x = q1 - q2: x'' = F / j1 - m (k x + c x')
    a = np.array([[0.0, 1.0], [-m * k, -m * c]])
    b = np.array([[0.0], [1.0 / j1]])
    t = np.linspace(0.0, 40.0 / f_mode, 40001)
    step = lambda s: (s >= 0).astype(float)  # noqa: E731
    force = step(t) if shaper is None else shaper.shape(t, step)
    _, x, _ = lsim((a, b, np.array([[1.0, 0.0]]), np.zeros((1, 1))), force, t)
    x_ss = 1.0 / (j1 * m * k)
    tail = t > (t[-1] - 3.0 / f_mode)
    return float(np.max(np.abs(x[tail] - x_ss)))


@pytest.mark.parametrize("kind", ["zv", "zvd"])
def test_shaper_cancels_the_residual_vibration_to_the_theory_level(kind):
    zeta = 0.0
    shaper = InputShaper.design(kind, 10.0, zeta)
    bare = _residual(None, 10.0, zeta)
    assert _residual(shaper, 10.0, zeta) < 5e-3 * bare  # 0 in theory; lsim interpolates the steps
    for f in (9.0, 11.5):  # a mode off the design: the theory's percentage vibration
        assert _residual(shaper, f, zeta) / _residual(None, f, zeta) == pytest.approx(shaper.residual_vibration(f, zeta), rel=0.03, abs=2e-3)
    assert shaper.residual_vibration(10.0) == pytest.approx(0.0, abs=1e-12)
    assert sum(shaper.amplitudes) == pytest.approx(1.0)


def test_damped_zv_and_its_stated_delay():
    shaper = InputShaper.design("zv", 10.0, 0.1)
    assert shaper.residual_vibration(10.0) == pytest.approx(0.0, abs=1e-12)
    assert shaper.delay == pytest.approx(0.5 / (10.0 * math.sqrt(1 - 0.01)))
    assert InputShaper.design("zvd", 10.0, 0.1).delay == pytest.approx(2 * shaper.delay)
    assert "delay" in shaper.describe() and shaper.to_dict()["delay_s"] == shaper.delay
    # ZVD is less sensitive to an error in the mode's frequency than ZV
    assert InputShaper.design("zvd", 10.0).residual_vibration(11.0) < InputShaper.design("zv", 10.0).residual_vibration(11.0)


def test_shaper_from_the_reference_ema_mode():
    scene = load_scene(SCENES / "ema_reference.toml")
    shaper = shaper_for(scene, "zv")
    assert 10.0 < shaper.frequency < 1000.0
    assert shaper.delay == pytest.approx(0.5 / shaper.frequency / math.sqrt(1 - shaper.damping_ratio**2))
    with pytest.raises(ValueError):
        InputShaper.design("zz", 10.0)

