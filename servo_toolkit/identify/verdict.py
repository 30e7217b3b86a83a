"""The verdict of a fit: the residual against the noise floor the data show.

The residual vector of a frequency response is in standard deviations of its own noise
(:mod:`.noise`: from the coherence and the number of averaged spectra, or from the
scatter of the points about a local fit), and so is that of closed-loop traces (each channel
over its scatter): their floor is 1. The floor of voltage-driven traces is the scatter of
each trace relative to its RMS. The scatter of a densely sampled trace is estimated from
third differences (:func:`scatter_sd`): measurement noise is rough from sample to sample
while a trace is smooth, so the third differences of neighbouring samples are noise (their
variance 20 sigma^2 for white noise) plus a small smooth part; the largest tenth (a step, a
reversal) is left out.

``fits to the noise``
    The residual RMS is at most :data:`MISMATCH_RATIO` times the floor (times the share of
    degrees of freedom the fit leaves).
``model mismatch``
    It is larger, or (time traces of the closed loop) the residual is not white noise: its
    means over blocks of a few milliseconds are larger than the noise leaves them
    (:mod:`.whiteness`; a miss smaller than the noise, that the RMS cannot show, still moves
    the estimates by more than their intervals). The model (or the parameters chosen)
    cannot follow the data; the frequencies or times where it misses most are named.
    Intervals and identifiability mean nothing then, and are not judged.
``not identifiable``
    The fit reaches the noise, yet the Fisher information (the Jacobian at the optimum)
    leaves a parameter without an independent influence, or its interval (from the profile
    of the cost where the Fisher matrix is ill-conditioned,
    :mod:`servo_toolkit.identify.profile`) is wider than its value or unbounded to a bound of
    its physical range.
``noise floor unknown``
    Too few points, or a frequency grid too coarse, to estimate the floor; the fit is
    reported as it is.
"""

from __future__ import annotations

import math

import numpy as np

#: residual RMS over the noise floor above which the model misses the data
MISMATCH_RATIO = 2.0
#: a point (or sample) misses when its residual exceeds this many noise floors
MISS_FLOORS = 3.0
#: fewest points from which a noise floor is estimated
MIN_POINTS = 12
#: share of the largest third differences left out of the estimate
TRIM = 0.1
#: RMS of a unit normal variable over its (1 - TRIM) smallest magnitudes
_TRIMMED_RMS = 0.7897
VERDICTS = ("fits to the noise", "model mismatch", "not identifiable", "noise floor unknown")


def scatter_sd(values) -> float | None:
    """Standard deviation of the point-to-point noise of a smooth sequence (None when it
    has fewer than :data:`MIN_POINTS` values)."""
    v = np.asarray(values, float)
    if v.size < MIN_POINTS:
        return None
    d3 = np.abs(np.diff(v, 3))
    keep = np.sort(d3)[: max(1, int(math.ceil((1 - TRIM) * d3.size)))]
    return float(np.sqrt(np.mean(keep ** 2)) / _TRIMMED_RMS / math.sqrt(20))


def bands(x, miss, unit: str, limit: int = 3) -> list[str]:
    """Contiguous runs of ``miss`` along ``x``, the worst (largest summed miss) first, as
    text (``"18.2-25.1 Hz"``)."""
    runs, start = [], None
    flags = np.asarray(miss) > 0
    for k, flag in enumerate(np.append(flags, False)):
        if flag and start is None:
            start = k
        elif not flag and start is not None:
            runs.append((float(np.sum(miss[start:k])), start, k - 1))
            start = None
    out = []
    for _, a, b in sorted(runs, reverse=True)[:limit]:
        out.append(f"{x[a]:.3g} {unit}" if a == b else f"{x[a]:.3g}-{x[b]:.3g} {unit}")
    return out


def judge(residual_rms: float, floor: float | None, dof: int, size: int, identifiable: bool,
          white: bool = True) -> str:
    """The verdict (one of :data:`VERDICTS`) of a residual against its noise floor; ``white``
    False (time traces whose residual is not white noise, :mod:`.whiteness`) is a mismatch
    whatever the residual's RMS."""
    if floor is None:
        return "noise floor unknown"
    expected = floor * math.sqrt(dof / max(size, 1))
    if residual_rms > MISMATCH_RATIO * expected + 1e-12 or not white:
        return "model mismatch"
    return "fits to the noise" if identifiable else "not identifiable"
