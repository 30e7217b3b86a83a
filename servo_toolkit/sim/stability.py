"""Step-size stability of RK4 from the fastest eigenvalues of the linearized kernel.

The Jacobian of :func:`kernel.rhs` is taken by central differences, compiled
(:func:`servo_toolkit.sim.batch.jacobians`; the held current reference fixed, as between two
samples). RK4 applied to y' = lambda y multiplies y by
R(z) = 1 + z + z^2/2 + z^3/6 + z^4/24, z = lambda dt; a decaying mode must keep
|R(z)| <= 1 (on the negative real axis this holds up to z = -2.785, on the imaginary axis up
to |z| = 2.828). Modes that grow physically (Re lambda >= 0) only bound dt through
|z| <= 2.828, beyond which RK4 is not an approximation of anything.
"""

from __future__ import annotations

import numpy as np

from . import layout as lo
from .batch import jacobians
from .kernel import hermite

IMAG_LIMIT = 2.8284271247461903  # RK4 stability boundary on the imaginary axis, 2*sqrt(2)
REAL_LIMIT = 2.785293563405282   # RK4 stability boundary on the negative real axis


def rk4_amplification(z):
    """RK4's stability polynomial R(z)."""
    z = np.asarray(z, dtype=complex)
    return 1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24


def smooth_parameters(P) -> np.ndarray:
    """P (one row, or rows of variants) without the jump of friction that holds at zero speed
    (Coulomb and static levels 0): a difference quotient across the jump is no eigenvalue,
    only the smooth dynamics bound the step. The viscous friction stays."""
    P = np.asarray(P)
    if not np.any(P[..., lo.STICK] > 0.0):
        return P
    P = P.copy()
    P[..., [lo.STICK, lo.TC, lo.TS_M, lo.TC_L, lo.TS_L]] = 0.0
    return P


def jacobian(model, P, x, t=0.0, iref=0.0) -> np.ndarray:
    """d(rhs)/dx at (t, x) by central differences (of the smooth dynamics:
    :func:`smooth_parameters`): column j from the right-hand side at x +- h e_j,
    h = 1e-7 (1 + |x_j|), the held current reference ``iref`` fixed. One row of the compiled
    :func:`servo_toolkit.sim.batch.jacobians`."""
    x = np.ascontiguousarray(x, dtype=float)
    jac = np.empty((1, x.size, x.size))
    jacobians(x[None], np.array([float(t)]), np.array([float(iref)]), smooth_parameters(P)[None], model.T[None],
              np.zeros(1, np.int64), np.zeros(1, np.int64), jac)
    return jac[0]


def contact_states(model, P, X) -> np.ndarray:
    """Each row of ``X`` (states, with its row of ``P``) in its stiffest configuration: the
    drivetrain pushed just into contact and closing (there the damper part is capped at the
    spring part, f = 2 K z, an undamped stiffness 2 K), and at rest against an elastic end
    stop it has passed (its spring engaged)."""
    Y = np.array(X, dtype=float, copy=True)
    qi = 0 if model.rigid else 2
    past = (P[:, lo.STROKE_MODE] == lo.STROKE_STOP) & ~((P[:, lo.STROKE_LO] <= Y[:, qi]) & (Y[:, qi] <= P[:, lo.STROKE_HI]))
    Y[past, 1] = 0.0
    Y[past, qi + 1] = 0.0
    if model.rigid:
        return Y
    c = P[:, lo.HALF_PLAY]
    d = Y[:, 0] - Y[:, 2]
    side = np.where(d >= 0, 1.0, -1.0)
    inside = np.abs(d) <= c
    Y[inside, 0] = Y[inside, 2] + (c[inside] + 1e-9 + 1e-6 * c[inside]) * side[inside]
    Y[:, 1] = Y[:, 3] + side * np.maximum(np.abs(Y[:, 1] - Y[:, 3]), 1e-3)
    return Y


def max_stable_dt(eigs) -> float:
    """Largest dt with |R(lambda dt)| <= 1 for every decaying mode and |z| <= 2.828 for every
    non-decaying one.

    Along each decaying mode's ray z = s lambda / |lambda| the first exit from |R| <= 1 is
    bracketed on a grid of s in [0.05, 3] and bisected (40 halvings), every mode at once; only
    the modes whose bracket can hold the smallest limit are bisected (the others' brackets
    lie wholly above another mode's)."""
    lam = np.atleast_1d(np.asarray(eigs, complex)).reshape(-1)
    mag = np.abs(lam)
    decaying = (mag != 0) & (lam.real < -1e-9 * mag)
    growing = (mag != 0) & ~decaying
    best = float(np.min(IMAG_LIMIT / mag[growing], initial=np.inf))
    if not np.any(decaying):
        return best
    ray, mag = lam[decaying] / mag[decaying], mag[decaying]
    grid = np.linspace(0.05, 3.0, 60)
    bad = np.abs(rk4_amplification(ray[:, None] * grid)) > 1 + 1e-12
    inside = ~bad.any(axis=1)
    k = np.argmax(bad, axis=1)
    lo_s = np.where(k > 0, grid[np.maximum(k - 1, 0)], 0.0)
    hi_s = grid[k]
    low, high = np.where(inside, 3.0, lo_s) / mag, np.where(inside, 3.0, hi_s) / mag
    keep = low <= min(best, float(np.min(high)))
    ray, mag, lo_s, hi_s, inside = ray[keep], mag[keep], lo_s[keep], hi_s[keep], inside[keep]
    for _ in range(40):
        mid = 0.5 * (lo_s + hi_s)
        out = np.abs(rk4_amplification(ray * mid)) > 1 + 1e-12
        hi_s = np.where(out, mid, hi_s)
        lo_s = np.where(out, lo_s, mid)
    return float(min(best, np.min(np.where(inside, 3.0, lo_s) / mag, initial=np.inf)))


def fastest(model, P, states, times, irefs=None) -> dict:
    """Fastest eigenvalue and the RK4 step limit over a set of states (and their contact
    variants: :func:`contact_states`).

    The Jacobians of every state and its contact variant are taken in one compiled call
    (:func:`servo_toolkit.sim.batch.jacobians`, the steps of :func:`jacobian`), their
    eigenvalues in one stacked call, and the step limit of all the modes at once
    (:func:`max_stable_dt`).

    Returns
    -------
    dict
        ``max_abs_lambda`` (1/s), ``lambda`` (complex as [re, im]), ``t_s`` where it occurs,
        ``dt_limit_s`` (the smallest stable-step limit found).
    """
    worst = {"max_abs_lambda": 0.0, "lambda": [0.0, 0.0], "t_s": 0.0, "dt_limit_s": np.inf}
    times = np.asarray(times, float).reshape(-1)
    if times.size == 0:
        return worst
    irefs = np.zeros(times.size) if irefs is None else np.asarray(irefs, float).reshape(-1)
    X = np.asarray(states, float).reshape(times.size, -1)
    P = np.asarray(P, float)
    rows = np.broadcast_to(P, (times.size, P.size))
    # each state, then its contact variant, in the order of the states
    Y = np.ascontiguousarray(np.stack([X, contact_states(model, rows, X)], axis=1).reshape(2 * times.size, -1))
    J = np.empty((Y.shape[0], Y.shape[1], Y.shape[1]))
    jacobians(Y, np.repeat(times, 2), np.repeat(irefs, 2), smooth_parameters(P)[None], model.T[None],
              np.zeros(1, np.int64), np.zeros(Y.shape[0], np.int64), J)
    eigs = np.linalg.eigvals(J)
    good = np.all(np.isfinite(eigs), axis=1)
    if not np.any(good):
        return worst
    eigs, at = eigs[good], np.repeat(times, 2)[good]
    k = np.argmax(np.abs(eigs), axis=1)
    for lam, t in zip(eigs[np.arange(k.size), k], at):  # the first of the largest, in order
        if abs(lam) > worst["max_abs_lambda"]:
            worst.update(max_abs_lambda=float(abs(lam)), t_s=float(t), **{"lambda": [float(lam.real), float(lam.imag)]})
    worst["dt_limit_s"] = max_stable_dt(eigs)
    return worst


def motor_speed(model, P, x) -> float:
    """omega_m = N(p) p' (rad/s)."""
    return hermite(model.T, lo.T_N, P, x[0])[0] * x[1]
