"""Many variants of an expensive exact map from a few exact evaluations, verified.

A variant's derived quantities (the linear plant's lumped parameters, the compiled model's
parameter slots and stroke tables) follow from its scene keys through the loader and the
drivetrain: exact, but ~15-200 ms per variant. Physics makes most of them *separable* in a
natural coordinate: an inertia is a sum of masses times squared ratios (linear in each
mass), compliances in series add (the reciprocal of a stiffness is linear in each stage's
compliance), efficiencies and gains multiply (their logarithms add). So

    g(y(x)) ~ g(y0) + sum_k [g(y(x0 + e_k (x_k - x0_k))) - g(y0)] + sum_{k<l} c_kl dx_k dx_l

with ``g`` the identity, the logarithm or the reciprocal, chosen per output; each one-key
map ``y(x0 + e_k t)`` is interpolated (a cubic spline through exact evaluations along the
key, in log(x) for a key drawn log-uniformly, at every integer of an integer key), and the
pair terms (exact for a multilinear dependence, e.g. a rotor inertia weighted by a stage's
efficiency) are added only when the separable sum alone does not verify.

:func:`fit` verifies the result against exact evaluations at the variant farthest from the
nominal one, at randomly chosen variants and at any further inputs the caller names (a box's
corners, where the keys' interactions add up), refines until all of them verify, and reports
the largest relative error: the caller keeps the fit only below its tolerance and evaluates
every variant exactly otherwise.
An output that no key moves is held at its nominal value, bit for bit.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

#: output coordinates: identity, logarithm (positive outputs), reciprocal (outputs of one sign)
COORDINATES = ("identity", "log", "reciprocal")
#: exact evaluations used to verify a fit: the farthest variant and this many random ones
CHECK_RANDOM = 3
#: points along a key on the first and second attempt
GRID_POINTS = (3, 7)
#: integer keys with at most this many values are evaluated at every one
MAX_INTEGER_POINTS = 9
#: default acceptance: largest relative error of a verified fit
DEFAULT_RTOL = 1e-4


def _forward(y, code):
    with np.errstate(divide="ignore", invalid="ignore"):
        return y if code == 0 else np.log(y) if code == 1 else 1.0 / y


def _inverse(z, code):
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        return z if code == 0 else np.exp(z) if code == 1 else 1.0 / z


def _usable(Y, code) -> np.ndarray:
    """Outputs (columns of ``Y``) the coordinate ``code`` can represent over all rows."""
    finite = np.all(np.isfinite(Y), axis=0)
    if code == 0:
        return finite
    if code == 1:
        return finite & np.all(Y > 0, axis=0)
    return finite & (np.all(Y > 0, axis=0) | np.all(Y < 0, axis=0))


@dataclass(frozen=True)
class SeparableFit:
    """A verified separable approximation of ``y(x)`` (see the module notes).

    Attributes
    ----------
    x0 : numpy.ndarray
        Nominal inputs (d,).
    y0 : numpy.ndarray
        Exact outputs at ``x0`` (m,).
    grids : tuple of numpy.ndarray
        Per key, the abscissae of its one-key map (in log(x) where ``log_keys``).
    splines : tuple
        Per key, the interpolant of ``g(y) - g(y0)`` along it, or None (the key moves nothing).
    codes : numpy.ndarray
        Per output, its coordinate (index in :data:`COORDINATES`); -1: held at ``y0``.
    pairs : dict
        ``(k, l)`` -> per-output coefficient of ``dx_k dx_l`` (in the output's coordinate).
    moved : numpy.ndarray
        (d, m) bool: key ``k`` moves output ``j``.
    error : float
        Largest relative error over the verification variants (relative to each output's
        largest magnitude).
    evaluations : int
        Exact evaluations spent.
    log_keys : numpy.ndarray
        (d,) bool: the key's map is in log(x).
    """

    x0: np.ndarray
    y0: np.ndarray
    grids: tuple
    splines: tuple
    codes: np.ndarray
    pairs: dict
    moved: np.ndarray
    error: float
    evaluations: int
    log_keys: np.ndarray

    def _coordinate(self, X):
        X = np.atleast_2d(np.asarray(X, float))
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(self.log_keys, np.log(np.where(self.log_keys, X, 1.0)), X)

    def __call__(self, X) -> np.ndarray:
        """Approximate outputs at inputs ``X`` (n, d): shape (n, m)."""
        X = np.atleast_2d(np.asarray(X, float))
        T = self._coordinate(X)
        n, m = X.shape[0], self.y0.size
        out = np.broadcast_to(self.y0, (n, m)).copy()
        groups = [(code, np.flatnonzero(self.codes == code)) for code in range(len(COORDINATES))]
        groups = [(code, cols) for code, cols in groups if cols.size]
        Z = [np.broadcast_to(_forward(self.y0[cols], code), (n, cols.size)).copy() for code, cols in groups]
        # each key's interpolant evaluated once for every output, then read by each coordinate's
        # outputs (each output's sum in the same order as one coordinate at a time)
        for k, spline in enumerate(self.splines):
            s = None
            for (code, cols), z in zip(groups, Z):
                if spline is not None and np.any(self.moved[k, cols]):
                    s = spline(T[:, k]) if s is None else s
                    z += s[:, cols]
        for (code, cols), z in zip(groups, Z):
            for (k, l), c in self.pairs.items():
                z += np.outer((X[:, k] - self.x0[k]) * (X[:, l] - self.x0[l]), c[cols])
            out[:, cols] = _inverse(z, code)
        return out


def _grid(lo, hi, x0, points, integer, log, grade=0.0):
    if integer:
        values = np.arange(np.ceil(min(lo, x0)), np.floor(max(hi, x0)) + 1.0)
        if values.size <= MAX_INTEGER_POINTS:
            return values
    if grade > 0 and not log:  # spacing growing as (x - lo + grade): dense where the map bends
        a, b = min(lo, x0), max(hi, x0)
        values = a - grade + np.geomspace(grade, b - a + grade, points)
        values[0], values[-1] = a, b
        values = np.sort(np.unique(np.concatenate([values, [x0]])))
        return np.round(values) if integer else values
    a, b = (np.log(v) for v in (min(lo, x0), max(hi, x0))) if log else (min(lo, x0), max(hi, x0))
    t = np.linspace(a, b, points)
    t = np.sort(np.unique(np.concatenate([t, [np.log(x0) if log else x0]])))
    values = np.exp(t) if log else t
    return np.round(values) if integer else values


def _splines(grids, Ylist, y0, codes_try, log_keys):
    """Per key, per coordinate, the spline of g(y) - g(y0) along its grid."""
    from scipy.interpolate import make_interp_spline
    out = []
    for k, (xs, Y) in enumerate(zip(grids, Ylist)):
        t = np.log(xs) if log_keys[k] else xs
        t, idx = np.unique(t, return_index=True)
        per = []
        for code in codes_try:
            with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
                z = _forward(Y[idx], code) - _forward(y0, code)
            z = np.where(np.isfinite(z), z, 0.0)
            per.append(make_interp_spline(t, z, k=min(3, t.size - 1)) if t.size > 1 else None)
        out.append(per)
    return out


def fit(evaluate, x0, samples, *, integer=None, log_keys=None, rtol: float = DEFAULT_RTOL, seed: int = 0,
        pairs: bool = True, scale=None, points=GRID_POINTS, grade=None, checks=None) -> SeparableFit:
    """Fit and verify the separable approximation of ``evaluate`` over ``samples``.

    Parameters
    ----------
    evaluate : callable
        ``evaluate(X)`` -> exact outputs, X (k, d) -> (k, m).
    x0 : array_like
        Nominal inputs (d,).
    samples : numpy.ndarray
        The variants the fit must serve (n, d): its grids span them, and the verification
        variants are drawn from them.
    integer, log_keys : array_like of bool, optional
        Per key: integer-valued; mapped in log(x).
    rtol : float
        Relative error below which a fit is accepted without refinement.
    seed : int
        Seed of the random verification variants.
    pairs : bool
        Add pair terms when the separable sum does not verify.
    scale : callable, optional
        ``scale(Y)`` -> the magnitude each output's error is relative to, from the exact
        outputs ``Y`` (rows: nominal and verification variants); default each output's
        largest magnitude.
    points : tuple
        Points along each key on successive attempts (default :data:`GRID_POINTS`): per
        attempt an int for every key, or a sequence of one count per key.
    grade : array_like of float, optional
        Per key (not mapped in log(x)), a length: its points are spaced in proportion to
        ``x - low + grade`` (geometrically from the low end of its range, dense where a map
        changes over a scale ``grade`` there); 0: evenly.
    checks : array_like, optional
        Further inputs (k, d) within the samples' box to verify at, besides the farthest and
        the random samples (e.g. the box's corners, which few samples come near).

    Returns
    -------
    SeparableFit
        Its ``error`` may exceed ``rtol``: the caller decides (exact evaluation instead).
    """
    x0 = np.asarray(x0, float)
    S = np.atleast_2d(np.asarray(samples, float))
    d = x0.size
    integer = np.zeros(d, bool) if integer is None else np.asarray(integer, bool)
    log_keys = np.zeros(d, bool) if log_keys is None else np.asarray(log_keys, bool)
    grade = np.zeros(d) if grade is None else np.asarray(grade, float)
    lo, hi = S.min(axis=0), S.max(axis=0)
    y0 = np.asarray(evaluate(x0[None]), float)[0]
    spent = 1
    span = np.where(hi > lo, hi - lo, 1.0)
    far = int(np.argmax(np.sum(np.abs(S - x0) / span, axis=1)))
    rng = np.random.default_rng(seed)
    picks = [far] + [int(i) for i in rng.choice(S.shape[0], size=min(CHECK_RANDOM, S.shape[0]), replace=False)]
    Xc = S[sorted(set(picks))]
    if checks is not None:
        Xc = np.unique(np.vstack([Xc, np.atleast_2d(np.asarray(checks, float))]), axis=0)
    Yc = np.asarray(evaluate(Xc), float)
    spent += Xc.shape[0]
    both = np.vstack([y0[None], Yc])
    scale = (np.max(np.abs(np.where(np.isfinite(both), both, 0.0)), axis=0) if scale is None
             else np.asarray(scale(both), float))
    scale = np.where(scale > 0, scale, 1.0)
    best, grids, Ylist = None, [None] * d, [None] * d
    for count in points:
        for k in range(d):
            xs = _grid(lo[k], hi[k], x0[k], count if np.ndim(count) == 0 else int(count[k]), integer[k], log_keys[k],
                       grade[k])
            if grids[k] is not None and np.array_equal(xs, grids[k]):
                continue  # an integer key: already every value
            X = np.repeat(x0[None], xs.size, axis=0)
            X[:, k] = xs
            Ylist[k] = np.asarray(evaluate(X), float)
            grids[k] = xs
            spent += xs.size
        result = _assemble(x0, y0, grids, Ylist, log_keys, Xc, Yc, scale, {}, spent)
        best = result
        if result.error <= rtol:
            return result
    if not pairs:
        return best
    # pair terms for keys that move a common output the separable sum misses
    pair_terms = {}
    for k, l in itertools.combinations(range(d), 2):
        common = best.moved[k] & best.moved[l]
        if not np.any(common):
            continue
        X = np.repeat(x0[None], 4, axis=0)
        for r, (a, b) in enumerate(itertools.product((lo[k], hi[k]), (lo[l], hi[l]))):
            X[r, k], X[r, l] = a, b
        Y = np.asarray(evaluate(X), float)
        spent += 4
        pair_terms[(k, l)] = (X, Y)
    with_pairs = _assemble(x0, y0, grids, Ylist, log_keys, Xc, Yc, scale, pair_terms, spent)
    return with_pairs if with_pairs.error < best.error else best


def _assemble(x0, y0, grids, Ylist, log_keys, Xc, Yc, scale, pair_data, spent):
    """The fit with the coordinate per output that verifies best, its pair
    terms from ``pair_data`` and its verified error."""
    d, m = x0.size, y0.size
    allY = np.vstack([y0[None], Yc] + list(Ylist) + [Y for _, Y in pair_data.values()])
    moved = np.array([np.any(~_same(Y, y0), axis=0) for Y in Ylist]) if d else np.zeros((0, m), bool)
    held = ~np.any(moved, axis=0) & np.all(_same(Yc, y0), axis=0)
    for _, Y in pair_data.values():
        held &= np.all(_same(Y, y0), axis=0)
    tries = range(len(COORDINATES))
    splines = _splines(grids, Ylist, y0, list(range(len(COORDINATES))), log_keys)
    errors = np.full((len(COORDINATES), m), np.inf)
    fits = {}
    for code in tries:
        ok = _usable(allY, code)
        sp = tuple(None if per[code] is None else per[code] for per in splines)
        pairs = _pair_coefficients(pair_data, x0, y0, sp, code, log_keys)
        trial = SeparableFit(x0, y0, tuple(grids), sp, np.where(ok, code, -1), pairs, moved, 0.0, spent, log_keys)
        P = trial(Xc)
        with np.errstate(invalid="ignore"):
            err = np.max(np.abs(P - Yc), axis=0) / scale
        err = np.where(_same(P, Yc).all(axis=0) | np.isinf(scale), 0.0, err)
        errors[code] = np.where(ok, err, np.inf)
        fits[code] = (sp, pairs)
    choice = np.argmin(errors, axis=0)
    choice = np.where(held, -1, choice)
    bad = (choice >= 0) & ~np.isfinite(errors[np.maximum(choice, 0), np.arange(m)])
    error = float(np.max(np.where(choice >= 0, errors[np.maximum(choice, 0), np.arange(m)], 0.0), initial=0.0))
    if np.any(bad):
        error = float("inf")
    # one spline set per coordinate: each output reads the one of its own coordinate
    merged = _merge(splines, choice, d)
    pairs = {}
    for code in set(choice[choice >= 0].tolist()):
        for key, c in fits[code][1].items():
            pairs.setdefault(key, np.zeros(m))[choice == code] = c[choice == code]
    return SeparableFit(x0, y0, tuple(grids), merged, choice, pairs, moved, error, spent, log_keys)


def _same(A, b):
    """Elementwise equal (NaN equal to NaN)."""
    return (A == b) | (np.isnan(A) & np.isnan(b))


class _Merged:
    """A key's interpolants per coordinate, read by output: column j of the coordinate
    ``choice[j]`` (0 where held)."""

    def __init__(self, per, choice):
        self.per, self.choice = per, choice
        # each coordinate's interpolant on the outputs that read it only (a B-spline's columns
        # are independent: the same values for a fraction of the work)
        self.parts = tuple((cols, _columns(spline, cols)) for cols, spline in
                           ((np.flatnonzero(choice == code), spline) for code, spline in enumerate(per))
                           if spline is not None and cols.size)

    def __call__(self, t):
        t = np.asarray(t, float)
        out = np.zeros((t.size, self.choice.size))
        for cols, spline in self.parts:
            out[:, cols] = spline(t)
        return out


def _columns(spline, cols):
    """The B-spline ``spline`` (values along axis 0) restricted to the output columns ``cols``."""
    from scipy.interpolate import BSpline
    return BSpline.construct_fast(spline.t, np.ascontiguousarray(spline.c[:, cols]), spline.k,
                                  extrapolate=spline.extrapolate, axis=spline.axis)


def _merge(splines, choice, d):
    return tuple(_Merged(splines[k], choice) if any(s is not None for s in splines[k]) else None for k in range(d))


def _pair_coefficients(pair_data, x0, y0, splines, code, log_keys) -> dict:
    """Least-squares coefficient of dx_k dx_l per output from the four corners of each pair,
    on the residual the separable sum leaves there."""
    out = {}
    for (k, l), (X, Y) in pair_data.items():
        base = SeparableFit(x0, y0, (), splines, np.full(y0.size, code), {}, np.ones((x0.size, y0.size), bool),
                            0.0, 0, log_keys)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            resid = _forward(Y, code) - _forward(base(X), code)
        resid = np.where(np.isfinite(resid), resid, 0.0)
        w = (X[:, k] - x0[k]) * (X[:, l] - x0[l])
        denom = float(w @ w)
        out[(k, l)] = (w @ resid) / denom if denom > 0 else np.zeros(y0.size)
    return out


__all__ = ["COORDINATES", "DEFAULT_RTOL", "SeparableFit", "fit"]
