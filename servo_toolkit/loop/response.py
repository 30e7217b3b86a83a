"""Closed-form frequency responses of the plant and of the loop, vectorized with numpy.

The state-space blocks of :mod:`servo_toolkit.plant.linear` are the reference; these transfer
functions are derived independently from the same physics (and tested against them), so
that thousands of parameter variants can be evaluated as array arithmetic:

    Delta = (J1 s^2 + (c + b1) s + K)(J2 s^2 + (c + b2) s + K + kh) - (c s + K)^2
    theta_1 / tau = (J2 s^2 + (c + b2) s + K + kh) / Delta,  theta / tau = (c s + K) / Delta

with tau = eta N Kt i the motor torque at the output. The current loop closes
i / i_cmd = Cpi / (L s + R + Cpi + Ke N s eta N Kt theta_1/tau), ideal (= 1) without
inductance. The position loop broken at the error is

    L = D Cy P2 / (1 + D Cw N s P1),  P1 = theta_1 / i_cmd,  P2 = theta / i_cmd,

with D the sampling delay, Cy the controller's gain from -theta and Cw from -omega_m.
"""

from __future__ import annotations

import numpy as np

from ..lti.response import solved_response


#: Largest eigenvector condition number for which :func:`state_space_response` uses the
#: modal sum (its rounding error grows with the condition number, ~1e-12 relative here).
MODAL_CONDITION = 1e4


def mechanical_response(s, J1, J2, K, c, b1, b2, kh):
    """theta_1/tau and theta/tau (rad per N*m at the output); arrays broadcast with ``s``.
    ``K = inf`` gives the rigid plant with inertia J1 + J2."""
    s = np.asarray(s, complex)
    J1, J2, K, c, b1, b2, kh = (np.asarray(v, float) for v in (J1, J2, K, c, b1, b2, kh))
    rigid = ~np.isfinite(K)
    Kf = np.where(rigid, 0.0, K)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        a = J1 * s**2 + (c + b1) * s + Kf
        b = J2 * s**2 + (c + b2) * s + Kf + kh
        x = c * s + Kf
        delta = a * b - x * x
        g1 = b / delta
        g2 = x / delta
        if not np.any(rigid):
            return g1, g2
        gr = 1.0 / ((J1 + J2) * s**2 + (b1 + b2) * s + kh)
    return np.where(rigid, gr, g1), np.where(rigid, gr, g2)


def current_response(s, p, g1, kp: float, ki: float):
    """i / i_cmd with the analog current PI; 1 without inductance (ideal current loop)."""
    s = np.asarray(s, complex)
    if p.L <= 0:
        return np.ones(np.broadcast(s, g1).shape, complex)
    cpi = kp + ki / s
    return cpi / (p.L * s + p.R + cpi + p.Ke * p.N * s * p.torque_gain * g1)


def plant_responses(s, p, kp: float, ki: float, J2=None, K=None, c=None):
    """P1 = theta_1/i_cmd and P2 = theta/i_cmd (rad/A) for parameters ``p`` with optional
    arrays replacing J2, K, c (broadcast against ``s``)."""
    J2 = p.J2 if J2 is None else J2
    K = p.K if K is None else K
    c = p.c if c is None else c
    g1, g2 = mechanical_response(s, p.J1, J2, K, c, p.b1, p.b2, p.kh)
    ic = current_response(s, p, g1, kp, ki)
    return p.torque_gain * g1 * ic, p.torque_gain * g2 * ic


def loop_response(s, p1, p2, delay, cy, cw, n: float):
    """Open loop broken at the position error (see module docstring)."""
    s = np.asarray(s, complex)
    return delay * cy * p2 / (1.0 + delay * cw * n * s * p1)


def state_space_response(A, B, C, D, s):
    """``C (s I - A)^-1 B + D`` at every ``s``: shape ``s.shape + (outputs, inputs)``.

    Used for the controller and the sampling delay where a refinement needs them at
    frequencies off any fixed grid. With a well-conditioned eigenvector basis the response
    is the modal sum ``D + sum_k r_k / (s - lambda_k)`` of the balanced ``A`` (a few
    multiplications per point);
    otherwise one batched linear solve per point.
    """
    s = np.asarray(s, complex)
    A, B, C, D = (np.atleast_2d(np.asarray(m, float)) for m in (A, B, C, D))
    n = A.shape[0] if A.size else 0
    if n == 0:
        return np.broadcast_to(D.astype(complex), s.shape + D.shape).copy()
    from scipy.linalg import matrix_balance
    Ab, T = matrix_balance(A)  # A = T Ab T^-1, T a scaled permutation
    lam, V = np.linalg.eig(Ab)
    if np.linalg.cond(V) < MODAL_CONDITION:
        residues = (C @ T @ V)[:, :, None] * np.linalg.solve(T @ V, B)[None, :, :]  # (p, n, m)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.einsum("...k,pkm->...pm", 1.0 / (s[..., None] - lam), residues) + D
    return solved_response(A, B, C, D, s)


