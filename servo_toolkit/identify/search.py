"""Global least squares over a box of log-parameters: data-derived start, multi-start, refinement.

A local optimizer started at the scene's values ends in whichever valley it starts in; a
current -> speed response with a mode has many (a resonance matched to the wrong notch, an
inertia that trades against a stiffness). :func:`global_least_squares` therefore

1. scatters ``starts`` points (scrambled Sobol, reproducible) over the whole box of the
   parameters' physical range in log space, plus the initial values, and evaluates each
   once: its residual and, when given, the mismatch of the data's own features (inertia
   line, antiresonance, resonance; :mod:`.features`);
2. from the point whose features match best, fits the features alone (a few evaluations):
   the start derived from the data;
3. refines locally (trust-region least squares within the box) from that start, the initial
   values and the best scattered points, and keeps the lowest residual; it stops at the
   first refinement whose residual reaches the data's noise floor (``enough``).

The box is the bound of the fit: a value outside the physical range is never returned.

Every Jacobian of the fit (the refinement's, the fit of the features', and the profile's
re-fits, :mod:`.profile`) comes from :func:`differences`: central differences of a fixed step in the
coordinates, given to ``least_squares`` as its ``jac``. The coordinates are the logarithm of a
value over the scene's (a signed value's change over its magnitude), so the step is a fixed
share of the value wherever the search stands. scipy's own steps are ``diff_step`` times
``|z|``: at a start on the scene's value (z = -1e-10) that is 1e-16, no model changes, and a
noiseless 30-point fit read the load inertia as having no influence. Central, they see a kink
of the model at the optimum in every parameter that moves the model across it, whichever side
the optimizer stopped on: forward differences of the same step saw the two series stiffnesses'
kink in one column only, took them for independent (correlation -0.05), and gave the link rod
an interval of +-1.3e-6 of its value that missed the truth by 13 %, instead of profiling
the pair.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import optimize
from scipy.stats import qmc

from ..core.progress import progress_bar

#: scattered points of the multi-start per parameter (rounded up to a power of two)
STARTS_PER_PARAMETER = 16
#: most scattered points refined locally, besides the data-derived start and the initial values
REFINED = 2
#: most residual evaluations of one local refinement, per parameter
MAX_NFEV_PER_PARAMETER = 50
#: starts closer than this (in every log-parameter) are refined once
SAME_START = 0.05
#: most evaluations of the fit of the features, per parameter and one: a start, not a result
FEATURE_NFEV_PER_PARAMETER = 5
#: the step of the Jacobians' central differences in the coordinates (a value changes by 1e-6 of
#: itself, or of a signed value's initial magnitude): the truncation costs about the step squared
#: of a derivative, a response's rounding eps / step (2e-10) of its scale
DIFF_STEP = 1e-6
#: the step of the fit of the features' Jacobian (features move by whole points of the data's grid)
FEATURE_DIFF_STEP = 1e-3


@dataclass(frozen=True)
class Search:
    """The lowest residual found.

    Attributes
    ----------
    z : numpy.ndarray
        Log-parameters at the optimum.
    fun, jac : numpy.ndarray
        Residual vector and its Jacobian there.
    nfev : int
        Residual evaluations in all.
    feature_start : numpy.ndarray or None
        The start derived from the data's features (None without features).
    ends : tuple of float
        Cost (half the sum of squares) at the end of each local refinement, best first.
    """

    z: np.ndarray
    fun: np.ndarray
    jac: np.ndarray
    nfev: int
    feature_start: np.ndarray | None
    ends: tuple


def scattered(lower, upper, n: int, seed: int = 0) -> np.ndarray:
    """``n`` (a power of two) scrambled Sobol points in the box [lower, upper]."""
    lower, upper = np.asarray(lower, float), np.asarray(upper, float)
    m = max(0, math.ceil(math.log2(max(n, 1))))
    pts = qmc.Sobol(d=lower.size, scramble=True, seed=seed).random_base2(m)
    return lower + pts * (upper - lower)


def _distinct(points, tol=SAME_START):
    out = []
    for p in points:
        if all(np.max(np.abs(p - q)) > tol for q in out):
            out.append(p)
    return out


def differences(fun, lower, upper, step: float = DIFF_STEP):
    """``jac(z)`` for :func:`scipy.optimize.least_squares`: the Jacobian of ``fun`` by central
    differences of the absolute ``step`` in each coordinate, within the box (the step on the
    other side only, where a bound is nearer than ``step``).

    Parameters
    ----------
    fun : callable
        ``z -> residual vector``.
    lower, upper : array_like
        The box (coordinates).
    step : float
        Half the distance between the two evaluations of a column (coordinates).

    Returns
    -------
    callable
        ``jac(z, *args)``; its ``evaluations`` counts the evaluations of ``fun`` it made.
    """
    lower, upper = np.asarray(lower, float), np.asarray(upper, float)

    def jac(z, *args):
        z = np.asarray(z, float)
        columns = []
        for j in range(z.size):
            a, b = max(z[j] - step, lower[j]), min(z[j] + step, upper[j])
            if not b > a:  # a box of no width: the parameter cannot move
                columns.append(None)
                continue
            za, zb = z.copy(), z.copy()
            za[j], zb[j] = a, b
            fa, fb = np.asarray(fun(za), float), np.asarray(fun(zb), float)
            jac.evaluations += 2
            columns.append((fb - fa) / (b - a))
        m = next((c.size for c in columns if c is not None), None)
        if m is None:
            m = np.asarray(fun(z), float).size
            jac.evaluations += 1
        return np.column_stack([np.zeros(m) if c is None else c for c in columns])

    jac.evaluations = 0
    return jac


def refine(residuals, start, lower, upper):
    """Local least squares (trust region within the box) from ``start``, its Jacobian by
    :func:`differences`: scipy's ``OptimizeResult`` (``x``, ``cost``, ``fun``, ``jac``,
    ``nfev``, ``njev``) with ``evaluations``, the residual evaluations in all."""
    lower = np.asarray(lower, float)
    jac = differences(residuals, lower, upper)
    sol = optimize.least_squares(residuals, np.clip(start, lower, upper), jac=jac, bounds=(lower, upper),
                                 x_scale=1.0, method="trf", ftol=1e-10, xtol=1e-10, gtol=1e-10,
                                 max_nfev=MAX_NFEV_PER_PARAMETER * lower.size)
    sol.evaluations = int(sol.nfev) + jac.evaluations
    return sol


def global_least_squares(residuals, lower, upper, initial, *, probe=None, starts: int | None = None,
                         seed: int = 0, enough: float = 0.0, progress: bool = False) -> Search:
    """Minimize ``sum(residuals(z)**2)`` over the box, from many starts.

    Parameters
    ----------
    residuals : callable
        ``z -> residual vector`` (z: log-parameters).
    lower, upper : array_like
        The box (log-parameters).
    initial : array_like
        A start inside the box (the scene's values).
    probe : callable, optional
        ``z -> (residual vector, feature mismatch vector or None)``: one evaluation giving
        both; default ``residuals`` alone (no feature start).
    starts : int, optional
        Scattered points; default :data:`STARTS_PER_PARAMETER` per parameter.
    seed : int
        Seed of the scrambled Sobol points (the search is reproducible).
    enough : float
        A cost (half the sum of squares) that no other start could improve on in earnest
        (the noise floor's): the refinement stops at the first start that reaches it.
    progress : bool
        Show a progress bar.

    Returns
    -------
    Search
    """
    lower, upper = np.asarray(lower, float), np.asarray(upper, float)
    npar = lower.size
    z0 = np.clip(np.asarray(initial, float), lower, upper)
    probe = probe or (lambda z: (residuals(z), None))
    n = starts if starts is not None else STARTS_PER_PARAMETER * npar
    points = [z0, *(scattered(lower, upper, n, seed) if n > 0 else [])]
    costs, mismatches = [], []
    nfev = 0
    bar = progress_bar(total=len(points) + 2 + REFINED, show=progress, desc="fit", unit="start", leave=False)
    with bar:
        for z in points:
            r, m = probe(z)
            nfev += 1
            costs.append(0.5 * float(r @ r))
            mismatches.append(None if m is None else float(m @ m))
            bar.update()
        feature_start = None
        if all(m is not None for m in mismatches):
            best = points[int(np.argmin(mismatches))]

            def features(z):
                return probe(z)[1]
            jac = differences(features, lower, upper, FEATURE_DIFF_STEP)
            sol = optimize.least_squares(features, best, jac=jac, bounds=(lower, upper),
                                         max_nfev=FEATURE_NFEV_PER_PARAMETER * (npar + 1), method="trf")
            nfev += sol.nfev + jac.evaluations
            feature_start = np.clip(sol.x, lower, upper)
        bar.update()
        order = np.argsort(costs)
        chosen = ([feature_start] if feature_start is not None else []) + [z0] \
            + [points[i] for i in order[:REFINED + 1]]
        ends = []
        best_sol = None
        for start in _distinct(chosen):
            sol = refine(residuals, start, lower, upper)
            nfev += sol.evaluations
            ends.append(float(sol.cost))
            if best_sol is None or sol.cost < best_sol.cost:
                best_sol = sol
            bar.update()
            if best_sol.cost <= enough:
                break
    return Search(z=best_sol.x, fun=best_sol.fun, jac=best_sol.jac, nfev=int(nfev), feature_start=feature_start,
                  ends=tuple(sorted(ends)))
