"""The Jacobian's definition, for the tests of the compiled one: d(rhs)/dx by central
differences of :func:`servo_toolkit.sim.kernel.rhs`, column by column, the step
h = 1e-7 (1 + |x_j|)."""

from __future__ import annotations

import numpy as np

from servo_toolkit.sim import layout as lo
from servo_toolkit.sim.kernel import rhs


def central_differences(X, times, irefs, P, T, tix, vix):
    """d(rhs)/dx by central differences of :func:`servo_toolkit.sim.kernel.rhs` at the states
    ``X`` of variants ``vix`` (parameter rows ``P[vix]``, tables ``T[tix[vix]]``); and 1e-12
    of each row's full scale over the step (the rounding of f, scaled by its terms, over
    2 h), per entry."""
    m, n = X.shape
    J, scale = np.empty((m, n, n)), np.empty((m, n))
    f, fp, fm, aux = np.empty(n), np.empty(n), np.empty(n), np.empty(lo.NAUX)
    for i in range(m):
        p, t = P[vix[i]], T[tix[vix[i]]]
        rhs(times[i], X[i].copy(), p, t, irefs[i], f, aux)
        scale[i] = np.abs(f)
        for j in range(n):
            h = 1e-7 * (1.0 + abs(X[i, j]))
            xp, xm = X[i].copy(), X[i].copy()
            xp[j] += h
            xm[j] -= h
            rhs(times[i], xp, p, t, irefs[i], fp, aux)
            rhs(times[i], xm, p, t, irefs[i], fm, aux)
            J[i, :, j] = (fp - fm) / (2 * h)
    h = 1e-7 * (1.0 + np.abs(X))
    tol = 1e-12 * np.maximum(scale, np.max(scale, axis=0))[:, :, None] / h[:, None, :]
    return J, tol
