"""Step-size stability of RK4 from the fastest eigenvalues of the linearized kernel.

The Jacobian of :func:`kernel.rhs` is taken by central differences (the held current
reference fixed, as between two samples). RK4 applied to y' = lambda y multiplies y by
R(z) = 1 + z + z^2/2 + z^3/6 + z^4/24, z = lambda dt; a decaying mode must keep
|R(z)| <= 1 (on the negative real axis this holds up to z = -2.785, on the imaginary axis up
to |z| = 2.828). Modes that grow physically (Re lambda >= 0) only bound dt through
|z| <= 2.828, beyond which RK4 is not an approximation of anything.
"""

from __future__ import annotations

import numpy as np

from . import layout as lo
from .kernel import hermite, rhs

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
    :func:`smooth_parameters`)."""
    P = smooth_parameters(P)
    n = x.size
    jac = np.empty((n, n))
    f1, f2, aux = np.empty(n), np.empty(n), np.empty(lo.NAUX)
    for j in range(n):
        h = 1e-7 * (1.0 + abs(x[j]))
        xp, xm = x.copy(), x.copy()
        xp[j] += h
        xm[j] -= h
        rhs(t, xp, P, model.T, iref, f1, aux)
        rhs(t, xm, P, model.T, iref, f2, aux)
        jac[:, j] = (f1 - f2) / (2 * h)
    return jac


def contact_variant(model, P, x) -> np.ndarray:
    """The same state in its stiffest configuration: the drivetrain pushed just into contact
    and closing (there the damper part is capped at the spring part, f = 2 K z, an undamped
    stiffness 2 K), and at rest against an elastic end stop it has passed (its spring
    engaged). One state of one parameter row (:func:`contact_states` for many)."""
    return contact_states(model, np.asarray(P)[None], np.asarray(x)[None])[0]


def contact_states(model, P, X) -> np.ndarray:
    """:func:`contact_variant` of each row of ``X`` (states) with its row of ``P``."""
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
    """Largest dt with |R(lambda dt)| <= 1 for every decaying mode (and |z| <= 2.828 for
    non-decaying ones).

    Along each decaying mode's ray z = s lambda / |lambda| the first exit from the region
    |R| <= 1 is bracketed on a grid of s in [0.05, 3] and bisected (40 halvings), every mode
    at once."""
    lam = np.atleast_1d(np.asarray(eigs, complex)).reshape(-1)
    mag = np.abs(lam)
    lam, mag = lam[mag != 0], mag[mag != 0]
    if lam.size == 0:
        return float(np.inf)
    decaying = lam.real < -1e-9 * mag
    best = np.min(IMAG_LIMIT / mag[~decaying]) if np.any(~decaying) else np.inf
    if not np.any(decaying):
        return float(best)
    ray, mag = lam[decaying] / mag[decaying], mag[decaying]
    grid = np.linspace(0.05, 3.0, 60)
    bad = np.abs(rk4_amplification(ray[:, None] * grid)) > 1 + 1e-12
    inside = ~bad.any(axis=1)
    k = np.argmax(bad, axis=1)
    lo_s = np.where(k > 0, grid[np.maximum(k - 1, 0)], 0.0)
    hi_s = grid[k]
    for _ in range(40):
        mid = 0.5 * (lo_s + hi_s)
        out = np.abs(rk4_amplification(ray * mid)) > 1 + 1e-12
        hi_s = np.where(out, mid, hi_s)
        lo_s = np.where(out, lo_s, mid)
    limit = np.where(inside, 3.0, lo_s) / mag
    return float(min(best, np.min(limit)))


def fastest(model, P, states, times, irefs=None) -> dict:
    """Fastest eigenvalue and the RK4 step limit over a set of states (and their contact
    variants).

    Returns
    -------
    dict
        ``max_abs_lambda`` (1/s), ``lambda`` (complex as [re, im]), ``t_s`` where it occurs,
        ``dt_limit_s`` (the smallest stable-step limit found).
    """
    worst = {"max_abs_lambda": 0.0, "lambda": [0.0, 0.0], "t_s": 0.0, "dt_limit_s": np.inf}
    irefs = np.zeros(len(times)) if irefs is None else irefs
    for x, t, ir in zip(states, times, irefs):
        for y in (x, contact_variant(model, P, x)):
            eigs = np.linalg.eigvals(jacobian(model, P, y, t, ir))
            if not np.all(np.isfinite(eigs)):
                continue
            k = int(np.argmax(np.abs(eigs)))
            limit = max_stable_dt(eigs)
            if abs(eigs[k]) > worst["max_abs_lambda"]:
                worst.update(max_abs_lambda=float(abs(eigs[k])), lam=eigs[k], t_s=float(t),
                             **{"lambda": [float(eigs[k].real), float(eigs[k].imag)]})
            worst["dt_limit_s"] = min(worst["dt_limit_s"], limit)
    worst.pop("lam", None)
    return worst


def motor_speed(model, P, x) -> float:
    """omega_m = N(p) p' (rad/s)."""
    return hermite(model.T, lo.T_N, P, x[0])[0] * x[1]
