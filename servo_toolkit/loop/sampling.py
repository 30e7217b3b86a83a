"""Sampling of parameter ranges for the robustness studies (``check --vary``, a scene's
``[robustness]``, ``montecarlo --vary``) and of a scene's ``[tolerances]``.

A range of positive values spanning more than a decade (``hi / lo > 10``, e.g. a stiffness
factor ``1e-3:1e3``) is sampled with logarithmic spacing: uniform in ``log(value)`` for the
Monte Carlo draws, geometric for a grid. Linear sampling of ``1e-12:1e12`` puts every draw
above ``1e11``, leaving the soft end of the range unseen. Narrower ranges, and ranges that
include 0 (a load inertia ``0:4``), keep linear spacing. Every Monte Carlo sample holds the
corners of the box (every combination of the ranges' ends) as its first variants, so its
ends are always covered; a grid holds them by construction.

Tolerances (:func:`sample_tolerances`) are drawn as points of the unit hypercube, one
coordinate per tolerance, mapped through each tolerance's inverse CDF: a Latin hypercube
(``scipy.stats.qmc.LatinHypercube``: every tolerance's range cut in ``n`` equal-probability
strata, one draw in each), a scrambled Sobol sequence (``scipy.stats.qmc.Sobol``, balanced
for ``n`` a power of 2) or independent draws. No corners are added: every variant is a draw
of the distributions, so the fraction meeting a requirement estimates the yield.
"""

from __future__ import annotations

import itertools
import warnings

import numpy as np

from ..errors import SceneError
from ..scene.tolerances import LOG_RATIO, METHODS


def is_log_range(lo: float, hi: float) -> bool:
    """True when ``lo..hi`` is sampled with logarithmic spacing (positive, over a decade)."""
    return lo > 0 and hi > LOG_RATIO * lo


def _spaced(lo: float, hi: float, n: int) -> np.ndarray:
    return np.geomspace(lo, hi, n) if is_log_range(lo, hi) else np.linspace(lo, hi, n)


def _drawn(rng, lo: float, hi: float, n: int) -> np.ndarray:
    if is_log_range(lo, hi):
        return np.exp(rng.uniform(np.log(lo), np.log(hi), n))
    return rng.uniform(lo, hi, n)


def corners(ranges: dict) -> dict:
    """Every combination of the ranges' distinct ends (``2 ** len(ranges)`` variants, fewer
    when a range is a single value)."""
    ends = [(lo, hi) if hi != lo else (lo,) for lo, hi in ranges.values()]
    combos = np.array(list(itertools.product(*ends)), float)
    return {k: combos[:, j] for j, k in enumerate(ranges)}


def grid_per_axis(samples: int, axes: int) -> int:
    """Points per range of a grid of about ``samples`` points over ``axes`` ranges: the
    nearest whole ``samples ** (1 / axes)``, at least 2 (each range's ends)."""
    return max(2, int(round(samples ** (1 / axes))))


def variant_count_text(ranges: dict, samples: int, grid: bool) -> str:
    """The variants :func:`sample_variants` draws over ``ranges`` (name -> (lo, hi)) for
    ``samples``, in words: ``"200 monte carlo variants"``; a grid's points per range to the
    power of the ranges (``"196 grid variants (14 x 14, the grid nearest the 200 asked)"``)
    and a Monte Carlo sample grown to the corners of the ranges say why they are not the
    number asked."""
    axes = len(ranges)
    if grid and axes:
        per = grid_per_axis(samples, axes)
        n = per ** axes
        if n == samples:
            return f"{n} grid variants"
        return f"{n} grid variants ({' x '.join([str(per)] * axes)}, the grid nearest the {samples} asked)"
    m = next(iter(corners(ranges).values())).size if axes else 0
    if samples < m:
        return f"{m} monte carlo variants (the corners of the ranges, more than the {samples} asked)"
    return f"{samples} {'grid' if grid else 'monte carlo'} variants"


def sample_variants(variants=None, samples: int = 1000, grid: bool = False, seed: int = 0,
                    defaults=None) -> dict:
    """Arrays of parameter values: explicit arrays are kept; (lo, hi) ranges are sampled on a
    grid of ``samples`` points in total (ends included) or by seeded Monte Carlo draws whose
    first variants are the corners of the ranges (a sample smaller than the corners grows to
    them); see the module notes for the spacing.

    Parameters
    ----------
    variants : dict, optional
        name -> (lo, hi) or an array of values; default ``defaults``.
    samples : int
    grid : bool
    seed : int
    defaults : dict, optional
        The variations used when ``variants`` is None.
    """
    variants = dict((defaults or {}) if variants is None else variants)
    ranges = {k: v for k, v in variants.items() if isinstance(v, tuple) and len(v) == 2}
    out = {k: np.asarray(v, float).ravel() for k, v in variants.items() if k not in ranges}
    if grid and ranges:
        per = grid_per_axis(samples, len(ranges))
        mesh = np.meshgrid(*[_spaced(lo, hi, per) for lo, hi in ranges.values()], indexing="ij")
        out.update({k: m.ravel() for k, m in zip(ranges, mesh)})
    elif ranges:
        rng = np.random.default_rng(seed)
        drawn = {k: _drawn(rng, lo, hi, samples) for k, (lo, hi) in ranges.items()}
        ends = corners(ranges)
        m = next(iter(ends.values())).size
        if samples < m:
            drawn = ends
        else:
            for k in drawn:
                drawn[k][:m] = ends[k]
        out.update(drawn)
    sizes = {v.size for v in out.values()}
    if len(sizes) != 1:
        raise SceneError("vary", f"explicit variant arrays must have one length, got {sorted(sizes)}")
    return out


def unit_sample(d: int, n: int, method: str = "lhs", seed: int = 0) -> np.ndarray:
    """``n`` points of the unit hypercube in ``d`` dimensions, shape (n, d), strictly inside
    (0, 1).

    Parameters
    ----------
    d, n : int
    method : {"lhs", "sobol", "random"}
        Latin hypercube, scrambled Sobol (balanced for ``n`` a power of 2; scipy warns
        otherwise, the sequence is still a valid draw), or independent uniform draws.
    seed : int
    """
    if method not in METHODS:
        raise SceneError("tolerances.method", f"must be one of {list(METHODS)} (got {method!r})")
    from scipy.stats import qmc
    if method == "lhs":
        u = qmc.LatinHypercube(d, seed=seed).random(n)
    elif method == "sobol":
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # n not a power of 2: still a valid draw
            u = qmc.Sobol(d, scramble=True, seed=seed).random(n)
    else:
        u = np.random.default_rng(seed).random((n, d))
    tiny = np.finfo(float).eps
    return np.clip(u, tiny, 1.0 - tiny)


def sample_tolerances(tolerances, samples: int | None = None, method: str | None = None,
                      seed: int | None = None) -> dict:
    """Values of every tolerance per variant: key path -> array (SI).

    Parameters
    ----------
    tolerances : Tolerances
        A scene's ``[tolerances]`` (:mod:`servo_toolkit.scene.tolerances`).
    samples, method, seed : optional
        Override the table's.
    """
    n = tolerances.samples if samples is None else int(samples)
    u = unit_sample(len(tolerances.items), n, method or tolerances.method,
                    tolerances.seed if seed is None else int(seed))
    return {t.key: t.ppf(u[:, j]) for j, t in enumerate(tolerances.items)}
