"""The C cam kernels (servo_toolkit/_physics/cam.h) equal the numba ones
(servo_toolkit.components.cam.kernels) they replace, and the cam studies give the same numbers
with them.

Agreement is exact (bit for bit): the numba cam kernels were compiled without fastmath, so the
C code (same operations in the same order, no contraction: x86-64 without -march has no FMA,
and -std=c99 turns off GCC's contraction anyway) rounds as they did; sin, cos and tanh are the
C library's in both (numba's math.sin/cos/tanh call libm). These comparison tests go with
numba.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from servo_toolkit import load_scene
from servo_toolkit.components.cam import kernels as nb
from servo_toolkit.components.cam.drive import CamDrive
from servo_toolkit._physics import _kernels as ck

from .conftest import SCENES


@pytest.fixture(scope="module")
def drive():
    return CamDrive.from_scene(load_scene(SCENES / "cam_follower.toml"))


def _agree(cfun, nfun, *args):
    """cfun(*args) equals nfun(*args) to the bit; where numba raised ZeroDivisionError (its
    njit default, error_model='python', raises on a float division by zero: a pack_cam array's
    motor entries are zero, J = 0, a zero radius), C divides in IEEE arithmetic and the result
    is non-finite."""
    c = cfun(*args)
    try:
        n = nfun(*args)
    except ZeroDivisionError:
        assert not np.isfinite(np.asarray(c, dtype=float)).all()
        return
    _same(c, n)


def _same(a, b):
    """Equal to the bit (tuples, arrays, floats; NaN equals NaN)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    assert a.shape == b.shape
    ok = (a == b) | (np.isnan(a) & np.isnan(b))
    assert ok.all(), (a[~ok], b[~ok])
    # signed zeros too
    assert (np.signbit(a) == np.signbit(b)).all()


def _params(drive, rng, n):
    """The scene's pack array and n random variations of it (friction, gravity, clearance,
    radii, motor), each a contiguous float64 array."""
    base = nb.pack(drive)
    out = [base, nb.pack_cam(drive.cam)]
    for _ in range(n):
        p = base.copy()
        p[0] *= rng.uniform(0.3, 3.0)          # A
        p[1] *= rng.uniform(0.1, 5.0)          # m
        p[2] = rng.choice([0.0, rng.uniform(0.0, 0.6)])  # mu
        p[3] = rng.normal(0.0, 10.0)           # G_x
        p[4] = rng.normal(0.0, 10.0)           # G_y
        p[5] = abs(rng.normal(0.0, 10.0))      # |G_z|
        p[6] *= rng.uniform(0.5, 2.0)          # r0
        p[8] *= rng.uniform(0.5, 2.0)          # J_m
        p[9] = rng.uniform(0.0, 0.05)          # M_f
        p[13] = rng.choice([0.0, rng.uniform(0.0, 2e-3)])  # clearance
        out.append(p)
    return out


def _angles(rng, n):
    b = np.arange(-16, 17) * (math.pi / 4)  # every segment boundary, both signs
    near = np.concatenate([np.nextafter(b, np.inf), np.nextafter(b, -np.inf)])
    return np.concatenate([b, near, rng.uniform(-30, 30, n), [0.0, -0.0, 2 * math.pi, -2 * math.pi, 1e-300]])


def test_law(drive):
    rng = np.random.default_rng(1)
    for a in [0.035, 1.0, 0.0, -0.2, 3.7]:
        for th in _angles(rng, 200):
            _same(ck.cam_law(float(th), a), nb.law(float(th), a))


def test_friction_and_speed_step(drive):
    rng = np.random.default_rng(2)
    for p in _params(drive, rng, 30):
        for _ in range(40):
            th = rng.uniform(-10, 10)
            s, d1, _ = nb.law(th, p[0])
            sigma = float(rng.choice([-1.0, 0.0, 1.0, rng.uniform(-1, 1)]))
            fl = rng.normal(0.0, 20.0)
            f0 = float(rng.choice([0.0, rng.uniform(0, 5)]))
            _agree(ck.cam_friction, nb.friction, p, s, d1, sigma, fl, f0)
            args = (rng.uniform(-10, 10), rng.uniform(-50, 300), rng.normal(0, 0.1),
                    p[8] * rng.uniform(0.5, 3), rng.choice([1e-5, 1e-3, 0.02]))
            _agree(ck.cam_speed_step, nb.speed_step, p, *args)


def test_shaft_acceleration_and_rhs(drive):
    rng = np.random.default_rng(3)
    for p in _params(drive, rng, 30):
        for th in _angles(rng, 40):
            th = float(th)
            w = float(rng.choice([0.0, -0.0, rng.normal(0, 50), rng.uniform(-1e-6, 1e-6)]))
            _, d1, d2 = nb.law(th, p[0])
            j = p[8] + p[1] * d1 * d1 * rng.uniform(1, 2)
            args = (th, w, rng.normal(0, 0.5), j, p[1] * d1 * d2 * w * w,
                    float(rng.choice([0.0, 1e3, rng.uniform(0, 10)])))
            _agree(ck.cam_shaft_acceleration, nb.shaft_acceleration, p, *args)
            for dc in (False, True):
                u = float(rng.uniform(-5, 12))
                _agree(ck.cam_rhs, nb.rhs, p, u, th, w, dc)


@pytest.mark.parametrize("corrected", [False, True])
def test_discrete(drive, corrected):
    rng = np.random.default_rng(4)
    for i, p in enumerate(_params(drive, rng, 12)[:1] + _params(drive, rng, 12)[2:]):
        for voltage, n, step in [(3.5, 2000, 1e-3), (rng.uniform(-2, 12), 700, rng.choice([1e-4, 5e-3, 0.05])),
                                 (12.0, 0, 1e-3), (1e6, 50, 1e-2)]:
            c_th, c_om, c_st = ck.cam_discrete(p, voltage, n, float(step), corrected)
            n_th, n_om, n_st = nb.discrete(p, voltage, n, float(step), corrected)
            assert c_st == n_st
            _same(c_th, n_th)
            _same(c_om, n_om)


def test_statuses_are_all_reached(drive):
    """The comparison above covers the three outcomes: ok, non-finite, reversed."""
    p = nb.pack(drive)
    assert ck.cam_discrete(p, 3.5, 200, 1e-3, True)[2] == 0
    assert ck.cam_discrete(p, -3.5, 200, 1e-3, True)[2] == 2
    q = p.copy()
    q[8] = 0.0  # J_m = 0: a division by zero at the first step (numba raises, C: non-finite)
    assert ck.cam_discrete(q, 3.5, 10, 1e-3, True)[2] == 1
    with pytest.raises(ZeroDivisionError):
        nb.discrete(q, 3.5, 10, 1e-3, True)
    q = p.copy()
    q[10] = 1e-300  # R tiny: an infinite speed without a division by zero
    assert ck.cam_discrete(q, 3.5, 10, 1e-3, True)[2] == nb.discrete(q, 3.5, 10, 1e-3, True)[2] == 1


class _CKernels:
    """The C kernels under the numba module's names, for the studies."""
    law = staticmethod(ck.cam_law)
    friction = staticmethod(ck.cam_friction)
    speed_step = staticmethod(ck.cam_speed_step)
    discrete = staticmethod(ck.cam_discrete)
    shaft_acceleration = staticmethod(ck.cam_shaft_acceleration)
    rhs = staticmethod(ck.cam_rhs)


def _patch(monkeypatch):
    for name in ("law", "friction", "speed_step", "discrete", "shaft_acceleration", "rhs"):
        monkeypatch.setattr(nb, name, getattr(_CKernels, name))


def test_studies_give_the_same_numbers(drive, monkeypatch):
    """The cam studies (voltage.py: the discrete schemes, the accurate solver, the convergence
    ladder; estimation.py: true acceleration and the Kalman scheme) called with the C kernels
    in the numba ones' place (they call them as ``kernels.<name>``) give the same results."""
    from servo_toolkit.studies.cam.estimation import compare_on_reference, rms_jerk, true_acceleration
    from servo_toolkit.studies.cam.voltage import accurate, constant_voltage, discrete_scheme

    def runs():
        out = []
        for scheme in ("seed", "corrected"):
            tr = discrete_scheme(drive, 3.5, 0.6, 1e-3, scheme)
            out += [tr.t, tr.theta, tr.omega]
        ref = accurate(drive, 3.5, 0.3, t_eval=np.arange(301) * 1e-3)
        out += [ref.theta, ref.omega]
        out.append(true_acceleration(drive, 3.5, ref.theta, ref.omega, True))
        out.append(true_acceleration(drive, 3.5, ref.theta, ref.omega, False))
        est = compare_on_reference(drive, 3.5, ref, 4096)
        out += _arrays(est)
        cv = constant_voltage(drive, 3.5, 0.3, 1e-3)
        out += _arrays(cv)
        loose = replace(drive, cam=replace(drive.cam, clearance=1e-4))  # eqs 6-8, discrete only
        out += _arrays(constant_voltage(loose, 3.5, 0.3, 1e-3))
        jerk = rms_jerk(out[8], 1e-3, 100)  # of the true acceleration
        for scheme in ("seed", "corrected"):
            kal = discrete_scheme(drive, 3.5, 0.3, 1e-3, scheme, "kalman", 4096, jerk)
            out += [kal.theta, kal.omega, kal.estimate.speed]
        return out

    ref_runs = runs()
    _patch(monkeypatch)
    assert nb.rhs is ck.cam_rhs
    c_runs = runs()
    assert len(ref_runs) == len(c_runs) and len(c_runs) > 10
    for a, b in zip(c_runs, ref_runs):
        _same(a, b)


def _arrays(obj, depth=0):
    """Every float array and float in a result object (dataclasses, dicts, lists), in order."""
    import dataclasses
    if depth > 6:
        return []
    if isinstance(obj, np.ndarray):
        return [obj] if obj.dtype.kind in "fi" else []
    if isinstance(obj, (float, int)) and not isinstance(obj, bool):
        return [np.asarray(float(obj))]
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return [a for f in dataclasses.fields(obj) for a in _arrays(getattr(obj, f.name), depth + 1)]
    if isinstance(obj, dict):
        return [a for k in obj for a in _arrays(obj[k], depth + 1)]
    if isinstance(obj, (list, tuple)):
        return [a for v in obj for a in _arrays(v, depth + 1)]
    return []
