"""The cam shaft of the transcribed right-hand side (tests/rhs_reference.py): a rigid chain
ending in a cam, whose follower's weight and guide friction load the shaft (seed 002 eqs 1
and 3, as :mod:`servo_toolkit.components.cam.kernels` solves them: the guide friction's fixed
point). Plain Python, written from the kernels' equations; it calls no kernel. The parameter
array is the cam kernels' ``pack``: [A, m, mu, G_x, G_y, |G_z|, r0, stroke, ...]."""

from __future__ import annotations

import math

#: the cam law's quarter segment (rad) and the fixed point's iteration count and tolerance
QUARTER = math.pi / 4
CAM_ITERATIONS, CAM_TOL = 60, 1e-14


def cam_law(theta, a):
    """Modified constant velocity law: s, ds/dtheta, d2s/dtheta2 (period 2 pi)."""
    th = theta % (2 * math.pi)
    s4, c4 = math.sin(4 * th), math.cos(4 * th)
    tr = th - s4 / 4
    if th < QUARTER:
        return a * tr, a * (1 - c4), 4 * a * s4
    if th < 3 * QUARTER:
        return 2 * a * th - math.pi * a / 4, 2 * a, 0.0
    if th < 4 * QUARTER:
        return math.pi * a / 2 + a * tr, a * (1 - c4), 4 * a * s4
    if th < 5 * QUARTER:
        return 2.5 * math.pi * a - a * tr, -a * (1 - c4), -4 * a * s4
    if th < 7 * QUARTER:
        return 3.75 * math.pi * a - 2 * a * th, -2 * a, 0.0
    return 2 * math.pi * a - a * tr, -a * (1 - c4), -4 * a * s4


def guide_friction(cam, s, d1, force):
    """The follower guide's friction (seed 002 eq 1) for a cam force: mu (|side force| + |G_z|),
    the side force |F| s' / rho + G_y, rho the pitch radius of the flank in contact."""
    rho = cam[6] + s if force >= 0 else cam[6] + cam[7] - s
    side = abs(force) * d1 / rho + cam[4]
    return cam[2] * (abs(side) + cam[5])


def shaft_acceleration(cam, theta, w, torque, inertia, velocity_torque, inv_ws):
    """The cam shaft's w' with the follower's load M_g = (sigma f - G_x) ds/dtheta, the guide
    friction f at the cam force m (s'' w^2 + s' w') - G_x + sigma f, iterated to its fixed
    point (at most 60 passes; the inner fixed point on f at each pass likewise)."""
    s, d1, d2 = cam_law(theta, cam[0])
    m, gx = cam[1], cam[3]
    d1_sign = 1.0 if d1 > 0 else (-1.0 if d1 < 0 else 0.0)
    sigma = d1_sign * math.tanh(w * inv_ws) if inv_ws > 0.0 else (1.0 if d1 * w > 0 else (-1.0 if d1 * w < 0 else 0.0))

    def inner(frictionless, f):
        for _ in range(CAM_ITERATIONS):
            new = guide_friction(cam, s, d1, frictionless + sigma * f)
            if abs(new - f) <= CAM_TOL * (1.0 + new):
                return new
            f = new
        return f

    f = 0.0
    for _ in range(CAM_ITERATIONS):
        dw = (torque - velocity_torque - d1 * (sigma * f - gx)) / inertia
        new = inner(m * (d2 * w * w + d1 * dw) - gx, f)
        if abs(new - f) <= CAM_TOL * (1.0 + new):
            f = new
            break
        f = new
    return (torque - velocity_torque - d1 * (sigma * f - gx)) / inertia
