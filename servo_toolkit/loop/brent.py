"""Brent's bracketed root finder run on many brackets at once.

:func:`brentq` takes the steps of scipy's ``brentq`` (Brent 1973, the Charles Harris C
implementation: inverse quadratic extrapolation, secant interpolation, bisection when a step
is not short enough) on every bracket together, with one vectorized call of the function per
iteration for the brackets not yet converged. Each bracket goes through the same arithmetic
as a scalar ``scipy.optimize.brentq`` call with the same tolerances, so a function that gives
the same value at a point whether it is evaluated alone or among others gives the same roots,
to the last bit; a crossing search over a few hundred brackets then costs a few dozen batched
evaluations instead of thousands of scalar calls.
"""

from __future__ import annotations

import numpy as np


def brentq(fun, a, b, xtol, rtol: float, maxiter: int = 100):
    """Roots of ``fun`` in the brackets ``[a, b]``, vectorized over the brackets.

    Parameters
    ----------
    fun : callable
        1-D array of abscissae -> 1-D array of values (float).
    a, b : array_like
        Bracket ends, one pair per bracket.
    xtol : array_like or float
        Absolute tolerance, per bracket or shared (> 0).
    rtol : float
        Relative tolerance (at least 4 machine epsilons, as scipy requires).
    maxiter : int
        Iterations before a bracket counts as not converged.

    Returns
    -------
    roots : numpy.ndarray
        The root per bracket (NaN where ``ok`` is False).
    ok : numpy.ndarray
        False where scipy's ``brentq`` raises: the function is NaN at a point it asks for,
        ``fun(a)`` and ``fun(b)`` have the same sign, or no convergence in ``maxiter``.
    """
    xpre = np.atleast_1d(np.asarray(a, float)).copy()
    xcur = np.atleast_1d(np.asarray(b, float)).copy()
    n = xpre.size
    xtol = np.broadcast_to(np.asarray(xtol, float), (n,)).copy()
    roots, ok = np.full(n, np.nan), np.zeros(n, bool)
    if n == 0:
        return roots, ok
    fpre, fcur = _values(fun, xpre), _values(fun, xcur)
    live = ~(np.isnan(fpre) | np.isnan(fcur))
    for x, f in ((xpre, fpre), (xcur, fcur)):
        hit = live & (f == 0)
        roots[hit], ok[hit], live = x[hit], True, live & ~hit
    live &= np.signbit(fpre) != np.signbit(fcur)
    idx = np.nonzero(live)[0]
    xpre, xcur, fpre, fcur, xtol = xpre[idx], xcur[idx], fpre[idx], fcur[idx], xtol[idx]
    xblk, fblk, spre, scur = (np.zeros(idx.size) for _ in range(4))
    with np.errstate(all="ignore"):
        for _ in range(maxiter):
            cross = (fpre != 0) & (fcur != 0) & (np.signbit(fpre) != np.signbit(fcur))
            xblk, fblk = np.where(cross, xpre, xblk), np.where(cross, fpre, fblk)
            spre, scur = np.where(cross, xcur - xpre, spre), np.where(cross, xcur - xpre, scur)
            swap = np.abs(fblk) < np.abs(fcur)
            xpre, xcur, xblk = np.where(swap, xcur, xpre), np.where(swap, xblk, xcur), np.where(swap, xcur, xblk)
            fpre, fcur, fblk = np.where(swap, fcur, fpre), np.where(swap, fblk, fcur), np.where(swap, fcur, fblk)
            delta = (xtol + rtol * np.abs(xcur)) / 2
            sbis = (xblk - xcur) / 2
            done = (fcur == 0) | (np.abs(sbis) < delta)
            roots[idx[done]], ok[idx[done]] = xcur[done], True
            keep = ~done
            if not keep.any():
                return roots, ok
            idx, xpre, xcur, xblk, fpre, fcur, fblk, spre, scur, xtol, delta, sbis = (
                v[keep] for v in (idx, xpre, xcur, xblk, fpre, fcur, fblk, spre, scur, xtol, delta, sbis))
            interpolate = xpre == xblk
            dpre = (fpre - fcur) / (xpre - xcur)
            dblk = (fblk - fcur) / (xblk - xcur)
            stry = np.where(interpolate, -fcur * (xcur - xpre) / (fcur - fpre),
                            -fcur * (fblk * dblk - fpre * dpre) / (dblk * dpre * (fblk - fpre)))
            bound = np.where(np.abs(spre) < 3 * np.abs(sbis) - delta, np.abs(spre), 3 * np.abs(sbis) - delta)
            short = (np.abs(spre) > delta) & (np.abs(fcur) < np.abs(fpre)) & (2 * np.abs(stry) < bound)
            spre, scur = np.where(short, scur, sbis), np.where(short, stry, sbis)
            xpre, fpre = xcur, fcur
            xcur = np.where(np.abs(scur) > delta, xcur + scur, xcur + np.where(sbis > 0, delta, -delta))
            fcur = _values(fun, xcur)
            good = ~np.isnan(fcur)
            if not good.all():
                idx, xpre, xcur, xblk, fpre, fcur, fblk, spre, scur, xtol = (
                    v[good] for v in (idx, xpre, xcur, xblk, fpre, fcur, fblk, spre, scur, xtol))
    return roots, ok


def _values(fun, x) -> np.ndarray:
    return np.asarray(fun(x), float).reshape(-1) if x.size else np.zeros(0)


__all__ = ["brentq"]
