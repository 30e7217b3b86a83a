"""Compiled (numba) scalar kernels of the cam drive, for the time-stepping loops.

They evaluate exactly the physics of :mod:`servo_toolkit.components.cam.drive` (the tests check
the kernels against the vectorized component law and :meth:`CamDrive.follower_force`).
``p`` is the flat parameter array built by :func:`pack`:

    [A, m, mu, G_x, G_y, |G_z|, r0, stroke, J_m, M_f, R, c_m, c_e, clearance]
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ...core.jit_cache import install as _install_cache

_install_cache()  # before the kernels below are decorated

_Q = math.pi / 4


def pack(drive) -> np.ndarray:
    """Flat parameter array of a :class:`CamDrive`."""
    c = drive.cam
    gx, gy, gz = drive.gravity()
    return np.array([c.profile_constant, c.follower_mass, c.guide_friction_coefficient, gx, gy, abs(gz),
                     c.pitch_base_radius, c.stroke_length, drive.rotor_inertia, drive.shaft_friction,
                     drive.resistance, drive.torque_constant, drive.back_emf_constant, c.clearance])


def pack_cam(cam) -> np.ndarray:
    """:func:`pack` array of a bare :class:`~servo_toolkit.components.cam.geometry.Cam` stage (the
    motor entries zero), for :func:`shaft_acceleration` inside another model's kernel."""
    from .drive import CamDrive
    return pack(CamDrive(cam, 0.0, 0.0, 1.0, 1.0, 0.0))


@njit(cache=True)
def law(theta, a):
    """Modified constant velocity law: s, ds/dtheta, d2s/dtheta2."""
    th = theta % (2 * math.pi)
    s4, c4 = math.sin(4 * th), math.cos(4 * th)
    tr = th - s4 / 4
    if th < _Q:
        return a * tr, a * (1 - c4), 4 * a * s4
    if th < 3 * _Q:
        return 2 * a * th - math.pi * a / 4, 2 * a, 0.0
    if th < 4 * _Q:
        return math.pi * a / 2 + a * tr, a * (1 - c4), 4 * a * s4
    if th < 5 * _Q:
        return 2.5 * math.pi * a - a * tr, -a * (1 - c4), -4 * a * s4
    if th < 7 * _Q:
        return 3.75 * math.pi * a - 2 * a * th, -2 * a, 0.0
    return 2 * math.pi * a - a * tr, -a * (1 - c4), -4 * a * s4


@njit(cache=True)
def friction(p, s, d1, sigma, frictionless, f0):
    """Fixed point of the guide friction for a frictionless cam force; returns (P, f)."""
    f = f0
    for _ in range(60):
        force = frictionless + sigma * f
        rho = p[6] + s if force >= 0 else p[6] + p[7] - s
        side = abs(force) * d1 / rho + p[4]
        new = p[2] * (abs(side) + p[5])
        if abs(new - f) <= 1e-14 * (1.0 + new):
            f = new
            break
        f = new
    return frictionless + sigma * f, f


@njit(cache=True)
def _sign(x):
    return 1.0 if x > 0 else (-1.0 if x < 0 else 0.0)


@njit(cache=True)
def speed_step(p, voltage, w, load, inertia, step):
    """One RK4 step of eq 12 for w with the load torque M and inertia J frozen (step 2 of
    the seed's scheme)."""
    r, cm, ce = p[10], p[11], p[12]
    k1 = (cm * voltage - r * load - ce * cm * w) / (r * inertia)
    k2 = (cm * voltage - r * load - ce * cm * (w + 0.5 * step * k1)) / (r * inertia)
    k3 = (cm * voltage - r * load - ce * cm * (w + 0.5 * step * k2)) / (r * inertia)
    k4 = (cm * voltage - r * load - ce * cm * (w + step * k3)) / (r * inertia)
    return w + step * (k1 + 2 * k2 + 2 * k3 + k4) / 6


@njit(cache=True)
def discrete(p, voltage, n, step, corrected):
    """Seed 002 section 3; ``corrected`` drops the inertia that eq 4 already holds.

    Returns theta, omega (n + 1 samples) and a status: 0 ok, 1 non-finite, 2 reversed.
    """
    a_, m, jm, mf, c = p[0], p[1], p[8], p[9], p[13]
    theta = np.zeros(n + 1)
    omega = np.zeros(n + 1)
    s_in = 0.0
    s_out = 0.0
    v = 0.0
    load = mf
    inertia = jm
    for k in range(n):
        w = omega[k]
        wn = speed_step(p, voltage, w, load, inertia, step)
        if not math.isfinite(wn):
            return theta, omega, 1
        if wn < 0:
            return theta, omega, 2
        omega[k + 1] = wn
        theta[k + 1] = theta[k] + wn * step
        s_new_in, d1, d2 = law(theta[k + 1], a_)
        s_new = s_new_in
        if c > 0:  # eqs 6-8
            if s_new_in > s_in and s_new_in > s_out + c:
                s_new = s_new_in - c
            elif s_new_in < s_in and s_new_in < s_out - c:
                s_new = s_new_in + c
            else:
                s_new = s_out
        vn = (s_new - s_out) / step
        an = (vn - v) / step
        s_in, s_out, v = s_new_in, s_new, vn
        acc = an
        if corrected:  # keep only m s' s'' w^2 of m a: eq 4's J carries m s'^2 w'
            acc = an - d1 * (wn - w) / step
        force, _ = friction(p, s_new_in, d1, _sign(vn), m * acc - p[3], 0.0)
        load = mf + force * d1
        ratio = vn / wn if wn > 0 else d1
        inertia = jm + m * ratio * ratio
    return theta, omega, 0


@njit(cache=True)
def shaft_acceleration(p, theta, w, torque, inertia, velocity_torque, inv_ws):
    """Cam-shaft acceleration with the follower's weight and guide friction (eqs 1, 3).

    Solves ``J w' + velocity_torque = torque - M_g`` with the follower load beyond its
    inertia, ``M_g = (sigma f - G_x) ds/dtheta``, where the guide friction ``f`` (eq 1, via
    :func:`friction`) depends on the cam force ``m a - G_x + sigma f`` and so on ``w'``
    through ``a = s'' w^2 + s' w'``; the fixed point is iterated to round-off.

    Parameters
    ----------
    p : numpy.ndarray
        :func:`pack` array (motor entries unused).
    theta, w : float
        Cam angle (rad) and speed (rad/s).
    torque : float
        Every other torque on the cam shaft, reflected to it (N*m): motor torque after its
        own friction, the scene's load moments.
    inertia, velocity_torque : float
        J(theta) with the follower's ``m s'^2`` (kg*m^2) and the velocity term
        ``J'(theta) w^2 / 2`` (N*m), as the caller's model has them.
    inv_ws : float
        1 / smoothing speed (s/rad) of the friction's direction, ``tanh(w / w_s)``;
        0 for the hard ``sign``.

    Returns
    -------
    dw, m_g : float
        w' (rad/s^2) and M_g (N*m).
    """
    s, d1, d2 = law(theta, p[0])
    m = p[1]
    if inv_ws > 0.0:
        sigma = _sign(d1) * math.tanh(w * inv_ws)
    else:
        sigma = _sign(d1 * w)
    f = 0.0
    dw = 0.0
    for _ in range(60):
        dw = (torque - velocity_torque - d1 * (sigma * f - p[3])) / inertia
        acc = d2 * w * w + d1 * dw
        _, new = friction(p, s, d1, sigma, m * acc - p[3], f)
        if abs(new - f) <= 1e-14 * (1.0 + new):
            f = new
            break
        f = new
    dw = (torque - velocity_torque - d1 * (sigma * f - p[3])) / inertia
    return dw, d1 * (sigma * f - p[3])


@njit(cache=True)
def rhs(p, voltage, theta, w, double_count):
    """d(theta)/dt, dw/dt of J w' + J' w^2 / 2 = c_m i - M (``double_count``: the seed's
    continuous limit, with the follower inertia in both J and m a)."""
    m, jm, mf, r, cm, ce = p[1], p[8], p[9], p[10], p[11], p[12]
    _, d1, d2 = law(theta, p[0])
    torque = cm * (voltage - ce * w) / r - mf
    j = jm + m * d1 * d1 * (2.0 if double_count else 1.0)
    dw, _ = shaft_acceleration(p, theta, w, torque, j, m * d1 * d2 * w * w, 0.0)
    return w, dw
