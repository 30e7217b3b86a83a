"""Which tolerance drives a figure: standardized regression where the figure is near-linear
in the tolerances, variance-based Sobol indices where it is not.

Standardized regression coefficients (SRC) come from the variants already run: a least-
squares fit y ~ b0 + sum_k b_k x_k (x_k in log where a tolerance is drawn log-uniformly).
The share of tolerance k is a population quantity, the part of the figure's variance over
the built actuators that k's linear effect carries,

    S_k = b_k^2 V_k / (sum_j b_j^2 V_j + s_e^2),

with V_k the variance of the tolerance's own distribution (not of the columns drawn) and
s_e^2 the fit's residual variance (what the linear part leaves: curvature, interactions).
With independent tolerances the denominator is the population variance of the figure, the
shares sum to the linear part's share of it (the fit's R^2 up to sampling) and never exceed
100 %. Dividing by the sample's own sd(y) instead, the textbook SRC, mixes in the chance
correlation between the drawn columns: at 256 variants a correlation of 0.1 moves a share
by several per cent, and the shares of one sample can sum above 100 %. Signed,
SRC_k = b_k sqrt(V_k) / sqrt(sum_j b_j^2 V_j + s_e^2) (its sign says which end of a tolerance
worsens the figure) and S_k = SRC_k^2. Their intervals come from a pairs bootstrap over the
variants (the fit, V_k aside, redone on :data:`RESAMPLES` resamples, percentile intervals of
SRC_k, squared), so they hold the variation from one sample of the same size to another, not
only the fit's on the one drawn; for a Latin hypercube or a scrambled Sobol sample, whose
estimates vary less than independent draws', they are conservative. When R^2 >=
:data:`R2_LINEAR` the shares account for nearly all of the spread and the figure is ranked
by them. Below it the response is nonlinear or has interactions, and the figure is ranked by
Sobol indices (``scipy.stats.sobol_indices``, Saltelli 2010: first-order S_k, the share k
explains alone, and total S_Tk, with its interactions), at n (d + 2) further evaluations,
their intervals bootstrapped. A tolerance known not to enter the figure at all (it moves
nothing the figure is computed from) gets exactly 0, stated as such, not estimated.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np

#: R^2 of the linear fit at or above which the figure is ranked by standardized regression
R2_LINEAR = 0.9
#: bootstrap resamples of the standardized regression's intervals
RESAMPLES = 1000
#: numbers held at once by one chunk of bootstrap resamples
_CHUNK_NUMBERS = 4_000_000


@dataclass(frozen=True)
class Sensitivity:
    """The ranking of the tolerances on one figure.

    Attributes
    ----------
    figure : str
        Its name (``phase_margin``, ``tracking_error``, ...).
    label, unit : str
    keys : tuple of str
    method : {"src", "sobol", "none"}
        ``"none"``: the figure does not vary over the variants (nothing to rank).
    share : numpy.ndarray
        Per key, the share of the figure's variance: SRC^2 (of its population variance, see
        the module notes), or the total Sobol index.
    low, high : numpy.ndarray
        Its confidence interval.
    src : numpy.ndarray
        Signed standardized regression coefficients b_k sqrt(V_k) / sqrt(Var(y)) (always
        computed: their sign says which end of a tolerance worsens the figure).
    first : numpy.ndarray or None
        First-order Sobol indices (Sobol only).
    r2 : float
        R^2 of the linear fit.
    inert : numpy.ndarray of bool
        Keys known not to enter the figure (share exactly 0).
    samples : int
        Evaluations the ranking used.
    confidence : float
    reason : str
        Which method and why, in words.
    """

    figure: str
    label: str
    unit: str
    keys: tuple
    method: str
    share: np.ndarray
    low: np.ndarray
    high: np.ndarray
    src: np.ndarray
    first: np.ndarray | None
    r2: float
    inert: np.ndarray
    samples: int
    confidence: float
    reason: str

    def ranking(self) -> list[tuple]:
        """(key, share, low, high) from the largest share down."""
        order = np.argsort(-np.nan_to_num(self.share, nan=-1.0), kind="stable")
        return [(self.keys[i], float(self.share[i]), float(self.low[i]), float(self.high[i])) for i in order]

    @property
    def top(self) -> str | None:
        """The key with the largest share (None when nothing varies)."""
        return None if self.method == "none" else self.ranking()[0][0]

    def to_dict(self) -> dict:
        """JSON-ready."""
        return {"figure": self.figure, "label": self.label, "unit": self.unit, "method": self.method,
                "r2": self.r2, "samples": self.samples, "confidence": self.confidence, "reason": self.reason,
                "ranking": [{"key": k, "share": s, "low": lo, "high": hi,
                             "src": float(self.src[self.keys.index(k)]),
                             "first_order": None if self.first is None else float(self.first[self.keys.index(k)]),
                             "does_not_enter": bool(self.inert[self.keys.index(k)])}
                            for k, s, lo, hi in self.ranking()]}


def regression(X, y, confidence: float = 0.95, *, variances=None, resamples: int = RESAMPLES, seed: int = 0):
    """Standardized regression coefficients of ``y`` on the columns of ``X``, scaled by the
    population variances (see the module notes).

    Parameters
    ----------
    X : numpy.ndarray
        (n, d) the regressors.
    y : numpy.ndarray
        (n,)
    confidence : float
    variances : array_like, optional
        (d,) each column's population variance (its distribution's, of the logarithm for a
        column regressed on it); default: the sample's own (recomputed in each resample).
    resamples : int
        Bootstrap resamples of the intervals.
    seed : int
        Seed of the resampling (the intervals are the same in every process).

    Returns
    -------
    src, low, high : numpy.ndarray
        Coefficients b_k sqrt(V_k) / sqrt(sum_j b_j^2 V_j + s_e^2) and their percentile
        bootstrap intervals (pairs resampled over the rows).
    r2 : float
        R^2 of the fit on the sample.
    """
    X = np.asarray(X, float)
    y = np.asarray(y, float)
    n, d = X.shape
    sx, sy = X.std(axis=0), y.std()
    if sy == 0 or n <= d + 1:
        z = np.zeros(d)
        return z, z, z, 0.0
    live = sx > 0
    Z = np.column_stack([np.ones(n), (X[:, live] - X[:, live].mean(axis=0)) / sx[live]])
    v = (y - y.mean()) / sy
    coef, *_ = np.linalg.lstsq(Z, v, rcond=None)
    resid = v - Z @ coef
    dof = n - Z.shape[1]
    scale = None if variances is None else np.sqrt(np.asarray(variances, float)[live]) / sx[live]
    point = _scaled(coef[None, 1:], (resid @ resid / dof)[None], np.ones((1, Z.shape[1] - 1)) if scale is None
                    else scale[None])[0]
    boot = _bootstrap(Z, v, scale, dof, resamples, seed)
    alpha = 50.0 * (1.0 - confidence)
    lo, hi = np.percentile(boot, [alpha, 100.0 - alpha], axis=0)
    src, low, high = np.zeros(d), np.zeros(d), np.zeros(d)
    src[live], low[live], high[live] = point, np.minimum(lo, point), np.maximum(hi, point)
    return src, low, high, float(1.0 - (resid @ resid) / n)


def _scaled(beta, s2, scale):
    """Per row: b_k sqrt(V_k) / sqrt(sum_j b_j^2 V_j + s_e^2) from the coefficients on the
    sample-standardized columns ``beta``, the residual variance ``s2`` and ``scale`` =
    sqrt(V_k) / sd_k."""
    b = beta * scale
    total = np.sum(b ** 2, axis=1) + np.clip(s2, 0.0, None)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(total[:, None] > 0, b / np.sqrt(total)[:, None], 0.0)


def _bootstrap(Z, v, scale, dof, resamples, seed):
    """(resamples, p - 1) the scaled coefficients of resamples of the rows of (Z, v), each a
    least-squares fit through its normal equations (weights: how often a row was drawn; one
    product gives every resample's sums); ``scale`` None: each resample's own column sd's."""
    n, p = Z.shape
    rng = np.random.default_rng(seed)
    # per row: Z Z^T, Z v, v^2, and the columns and their squares (the resample's variances)
    F = np.column_stack([(Z[:, :, None] * Z[:, None, :]).reshape(n, p * p), Z * v[:, None], v ** 2,
                         Z[:, 1:], Z[:, 1:] ** 2])
    out = []
    step = max(1, min(int(resamples), _CHUNK_NUMBERS // max(n, F.shape[1])))
    for start in range(0, int(resamples), step):
        m = min(step, int(resamples) - start)
        idx = rng.integers(0, n, (m, n)) + n * np.arange(m)[:, None]
        S = np.bincount(idx.ravel(), minlength=m * n).reshape(m, n).astype(float) @ F
        A, g, vv = S[:, :p * p].reshape(m, p, p), S[:, p * p:p * p + p], S[:, p * p + p]
        try:
            beta = np.linalg.solve(A, g[:, :, None])[:, :, 0]
        except np.linalg.LinAlgError:  # a resample with too few distinct rows: the least-norm fit
            beta = (np.linalg.pinv(A) @ g[:, :, None])[:, :, 0]
        s2 = (vv - np.sum(beta * g, axis=1)) / dof
        if scale is None:  # the resample's own column variances
            mean, square = S[:, p * p + p + 1:p * p + 2 * p] / n, S[:, p * p + 2 * p:] / n
            sc = np.sqrt(np.clip(square - mean ** 2, 0.0, None))
        else:
            sc = np.broadcast_to(scale, (m, p - 1))
        out.append(_scaled(beta[:, 1:], s2, sc))
    return np.concatenate(out)


def _square_interval(lo, hi):
    """The interval of x^2 for x in [lo, hi]."""
    a, b = lo ** 2, hi ** 2
    low = np.where((lo <= 0) & (hi >= 0), 0.0, np.minimum(a, b))
    return low, np.maximum(a, b)


def sobol(func, dists, n: int, *, seed: int = 0, confidence: float = 0.95, resamples: int = 200):
    """First-order and total Sobol indices of ``func`` with bootstrap intervals.

    Parameters
    ----------
    func : callable
        ``func(x)`` with ``x`` of shape (d, m) -> (s, m) finite figures.
    dists : sequence
        Per input, an object with a ``ppf`` method (a :class:`~servo_toolkit.scene.tolerances.Tolerance`).
    n : int
        Base sample (rounded up to a power of 2); ``n (d + 2)`` evaluations.
    seed : int
    confidence : float
    resamples : int
        Bootstrap resamples of the intervals.

    Returns
    -------
    dict
        ``first``, ``total`` (s, d) and their ``*_low``, ``*_high`` intervals; ``n``.
    """
    from scipy.stats import bootstrap, sobol_indices
    n = 1 << max(1, int(math.ceil(math.log2(max(int(n), 2)))))
    dists = list(dists)
    calls = []

    def recorded(x):
        y = np.atleast_2d(np.asarray(func(x), float))
        calls.append(y)
        return y
    res = sobol_indices(func=recorded, n=n, dists=dists, rng=np.random.default_rng(seed))
    f_A, f_B, f_AB = calls  # the order sobol_indices evaluates them in: A, B, then every AB_i
    f_AB = np.moveaxis(f_AB.reshape((-1, n, len(dists))), -1, 0)  # (d, s, n)
    mean = np.mean([f_A, f_B], axis=(0, -1)).reshape(-1, 1)
    f_A, f_B, f_AB = f_A - mean, f_B - mean, f_AB - mean

    def statistic(idx):  # Saltelli 2010, the estimators of sobol_indices, on resampled rows
        a, b, ab = f_A[:, idx], f_B[:, idx], f_AB[..., idx]
        var = np.var([a, b], axis=(0, -1))
        with np.errstate(divide="ignore", invalid="ignore"):
            first = np.mean(b * (ab - a), axis=-1) / var
            total = 0.5 * np.mean((a - ab) ** 2, axis=-1) / var
        return np.stack([first.T, total.T])

    # seeded here: the intervals are the same in every process (scipy's own bootstrap of a
    # Sobol result draws from an unseeded generator)
    with warnings.catch_warnings():  # an undefined BCa interval is replaced below
        warnings.simplefilter("ignore")
        boot = bootstrap([np.arange(n)], statistic, method="BCa", n_resamples=resamples,
                         confidence_level=confidence, rng=np.random.default_rng(seed + 1))
    low, high = _interval(boot, confidence)
    shape = (f_A.shape[0], len(dists))  # (s, d): scipy drops the input axis of a single input
    return {"first": np.reshape(res.first_order, shape), "total": np.reshape(res.total_order, shape),
            "first_low": low[0], "first_high": high[0], "total_low": low[1], "total_high": high[1], "n": n}


def _interval(boot, confidence: float):
    """(low, high), each (2, s, d), of a bootstrap result: its BCa interval, or where that
    is undefined (a degenerate bootstrap distribution, e.g. an input that enters nothing:
    every resample gives the same index) the percentile interval of the resamples."""
    low = np.asarray(boot.confidence_interval.low, float)
    high = np.asarray(boot.confidence_interval.high, float)
    bad = ~(np.isfinite(low) & np.isfinite(high))
    if bad.any():
        alpha = 100.0 * (1.0 - confidence) / 2.0
        dist = np.asarray(boot.bootstrap_distribution, float)
        p_low, p_high = np.percentile(dist, [alpha, 100.0 - alpha], axis=-1)
        low, high = np.where(bad, p_low, low), np.where(bad, p_high, high)
    return low, high


def _share_cap(high, share):
    """An interval's upper end of a share of the variance, at most 1 (all of it) unless the
    estimate itself lies above (estimator noise, kept visible)."""
    return np.minimum(high, np.maximum(1.0, share))


def rank(figure: str, label: str, unit: str, keys, X, y, *, inert=None, log_keys=None, confidence: float = 0.95,
         sobol_run=None, variances=None, seed: int = 0) -> Sensitivity:
    """The ranking of ``keys`` on ``y`` (one value per row of ``X``; non-finite rows left
    out).

    Parameters
    ----------
    figure, label, unit : str
    keys : sequence of str
    X : numpy.ndarray
        (n, d) tolerance values of the variants.
    y : numpy.ndarray
        (n,) the figure.
    inert : array_like of bool, optional
        Keys known not to enter the figure.
    log_keys : array_like of bool, optional
        Keys drawn log-uniformly (regressed on their logarithm).
    confidence : float
    sobol_run : callable, optional
        ``sobol_run(live)`` -> the :func:`sobol` dict of the figure over the keys ``live``
        (a mask), called when the linear fit explains less than :data:`R2_LINEAR`; without it
        the figure is ranked by its regression anyway and the reason says so.
    variances : array_like, optional
        Per key, the variance of its distribution (of its logarithm for a key in
        ``log_keys``): the shares' V_k (default: the sample's, see the module notes).
    seed : int
        Seed of the regression's bootstrap.
    """
    keys = tuple(keys)
    d = len(keys)
    X = np.asarray(X, float)
    y = np.asarray(y, float)
    inert = np.zeros(d, bool) if inert is None else np.asarray(inert, bool)
    log_keys = np.zeros(d, bool) if log_keys is None else np.asarray(log_keys, bool)
    ok = np.isfinite(y) & np.all(np.isfinite(X), axis=1)
    Xr = np.where(log_keys, np.log(np.where(log_keys, np.abs(X), 1.0)), X)[ok]
    live = ~inert
    zero = np.zeros(d)
    left = "" if ok.all() else f" ({int((~ok).sum())} variants without a finite figure left out)"
    if not live.any() or (ok.sum() >= 2 and np.ptp(y[ok]) == 0):
        return Sensitivity(figure, label, unit, keys, "none", zero, zero, zero, zero, None, 0.0, inert,
                           int(ok.sum()), confidence, "the figure does not vary over the variants" + left)
    src, lo_src, hi_src = zero.copy(), zero.copy(), zero.copy()
    notes = " Keys known not to enter it: 0 exactly." if inert.any() else ""
    few = int(ok.sum()) < int(live.sum()) + 2  # a regression on d keys needs d + 2 variants (a residual)
    if few:
        short = (f"{int(ok.sum())} variants cannot fit a regression on {int(live.sum())} tolerances "
                 f"(at least {int(live.sum()) + 2} are needed)")
        if sobol_run is None:
            return Sensitivity(figure, label, unit, keys, "none", zero, zero, zero, zero, None, math.nan, inert,
                               int(ok.sum()), confidence, short + ": not ranked" + left)
        r2 = math.nan
    else:
        s, lo, hi, r2 = regression(Xr[:, live], y[ok], confidence, seed=seed,
                                   variances=None if variances is None else np.asarray(variances, float)[live])
        src[live], lo_src[live], hi_src[live] = s, lo, hi
    share_lo, share_hi = _square_interval(lo_src, hi_src)
    if not few and (r2 >= R2_LINEAR or sobol_run is None):
        why = (f"near-linear (R^2 = {r2:.3f} >= {R2_LINEAR:g}): standardized regression, shares SRC^2 of the "
               f"population variance (bootstrap intervals over the variants)"
               if r2 >= R2_LINEAR else
               f"R^2 = {r2:.3f} < {R2_LINEAR:g}: nonlinear, ranked by standardized regression without "
               "variance-based indices (the shares explain only R^2 of the spread)")
        return Sensitivity(figure, label, unit, keys, "src", src ** 2, share_lo, _share_cap(share_hi, src ** 2), src,
                           None, r2, inert,
                           int(ok.sum()), confidence, why + left + "." + notes)
    res = sobol_run(live)
    total, first = zero.copy(), zero.copy()
    tlo, thi = zero.copy(), zero.copy()
    total[live], first[live] = res["total"][0], res["first"][0]
    tlo[live], thi[live] = res["total_low"][0], res["total_high"][0]
    why = ((short if few else f"R^2 = {r2:.3f} < {R2_LINEAR:g}: nonlinear or interacting")
           + f", variance-based Sobol indices (total S_T; {res['n']} x {int(live.sum()) + 2} evaluations, "
             "bootstrap intervals)")
    return Sensitivity(figure, label, unit, keys, "sobol", total, np.clip(tlo, 0.0, None), _share_cap(thi, total),
                       src, first, r2,
                       inert, res["n"] * (int(live.sum()) + 2), confidence, why + left + "." + notes)


__all__ = ["R2_LINEAR", "RESAMPLES", "Sensitivity", "rank", "regression", "sobol"]
