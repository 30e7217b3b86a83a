"""The noise of a measured frequency response, per point, in its gain and its phase: what the
fit weighs its residuals by and judges them against (:mod:`.verdict`).

From the coherence, when the data carry it with the number of spectra averaged behind it
(what ``frf`` and the multisine sweep write): an H1 estimate from ``n`` averaged spectra at
coherence ``coh`` has a random error of variance ``(1 - coh) / (2 n coh)`` in its
log-magnitude (nepers^2) and in its phase (rad^2) alike (Bendat and Piersol, Random Data,
the random errors of frequency-response estimates): the noise that changes from spectrum to
spectrum (the output's noise is what lowers the coherence). What repeats in every spectrum
the coherence cannot see: a logged signal's resolution (an encoder's counts) under a periodic
excitation rounds each period alike. Its standard deviation, when the data carry it
(``resolution_db``, ``resolution_deg``, what ``frf`` writes from a log with a resolution,
:func:`servo_toolkit.core.spectra.resolution_sd`), adds to the coherence's in power. A single
spectrum (``n`` = 1) has a coherence of 1 whatever the noise, and tells nothing.

Else from the scatter of the points about a local fit: each point is predicted by a
quadratic in log frequency through its :data:`SMOOTH_HALF` neighbours either side (itself
left out), and the prediction errors, scaled by their own standard deviation for white
noise, are noise plus what the quadratic cannot follow. A sharp resonance on a coarse grid
is such a part, but it is local: a robust scale (the median absolute error, then the RMS of
the errors within :data:`CLIP` of it) leaves it out as long as it touches fewer than half
of the points. Below :data:`MIN_PER_DECADE` points per decade, or with fewer than
:data:`MIN_POINTS` points, the grid is too coarse to tell noise from the response's own
shape, and the noise is unknown (the verdict says so instead of guessing).

Every standard deviation is at least :data:`PRECISION_DB` (or deg): the digits a response
file carries.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..core.angles import DEG_PER_RAD
from ..core.spectra import coherence_sd
from .data import DB_PER_NEPER

#: fewest points from which the scatter gives a noise estimate
MIN_POINTS = 12
#: fewest points per decade of frequency (over the data's span) for the scatter
MIN_PER_DECADE = 10.0
#: neighbours either side of a point in its local fit, and the fit's degree
SMOOTH_HALF, SMOOTH_DEGREE = 3, 2
#: prediction errors beyond this many robust standard deviations are the response's shape
CLIP = 3.0
#: smallest standard deviation of a gain (dB) or a phase (deg)
PRECISION_DB = 1e-6


@dataclass(frozen=True)
class FrequencyNoise:
    """Standard deviations of a response's gain and phase at each point.

    Attributes
    ----------
    gain_db, phase_deg : numpy.ndarray or None
        Per point (None: unknown).
    basis : str
        Where they come from, as text.
    """

    gain_db: np.ndarray | None
    phase_deg: np.ndarray | None
    basis: str

    @property
    def known(self) -> bool:
        """True when the noise was estimated."""
        return self.gain_db is not None


def _truncated_sd_factor(c: float) -> float:
    """Standard deviation of a unit normal variable within +-c."""
    phi = math.exp(-0.5 * c * c) / math.sqrt(2 * math.pi)
    mass = math.erf(c / math.sqrt(2))
    return math.sqrt(1.0 - 2.0 * c * phi / mass)


def smoother_sd(x, values) -> float | None:
    """Standard deviation of the point-to-point noise of ``values`` on the grid ``x`` (log
    frequency), from leave-one-out prediction errors of a local quadratic, robustly scaled
    (None with fewer than :data:`MIN_POINTS` values)."""
    x, v = np.asarray(x, float), np.asarray(values, float)
    n = v.size
    if n < MIN_POINTS:
        return None
    width = 2 * SMOOTH_HALF + 1
    errors = np.empty(n)
    for i in range(n):
        lo = min(max(i - SMOOTH_HALF, 0), n - width)
        idx = np.r_[lo:i, i + 1:lo + width]
        basis = np.vander(x[idx] - x[i], SMOOTH_DEGREE + 1)
        gram_inv = np.linalg.inv(basis.T @ basis)
        coef = gram_inv @ (basis.T @ v[idx])
        # the prediction at x_i is the constant term; its error variance sigma^2 (1 + g_00)
        errors[i] = (v[i] - coef[-1]) / math.sqrt(1.0 + gram_inv[-1, -1])
    scale = float(np.median(np.abs(errors))) / 0.6745
    if not scale > 0:
        return 0.0
    inside = errors[np.abs(errors) <= CLIP * scale]
    return float(np.sqrt(np.mean(inside ** 2))) / _truncated_sd_factor(CLIP)


def per_decade(frequency_hz) -> float:
    """Points per decade of frequency over the data's span."""
    f = np.asarray(frequency_hz, float)
    span = math.log10(f[-1] / f[0]) if f.size > 1 else 0.0
    return (f.size - 1) / span if span > 0 else math.inf


def frequency_noise(data) -> FrequencyNoise:
    """The noise of a :class:`~.data.FrequencyData`: from its coherence when it carries the
    number of spectra averaged (at least 2), else from its scatter about a local fit when the
    grid is fine enough, else unknown."""
    n = data.points
    if data.averages is not None and data.averages >= 2:
        sd = coherence_sd(data.coherence, data.averages)
        gain, phase = DB_PER_NEPER * sd, DEG_PER_RAD * sd
        basis = f"coherence of {data.averages} averaged spectra"
        if data.resolution_db is not None:
            gain, phase = np.hypot(gain, data.resolution_db), np.hypot(phase, data.resolution_deg)
            basis += " and the logged signals' resolution"
        return FrequencyNoise(np.maximum(gain, PRECISION_DB), np.maximum(phase, PRECISION_DB), basis)
    density = per_decade(data.frequency_hz)
    if n < MIN_POINTS or density < MIN_PER_DECADE:
        why = (f"{n} points, fewer than {MIN_POINTS}" if n < MIN_POINTS else
               f"{density:.3g} points per decade, fewer than {MIN_PER_DECADE:g}")
        return FrequencyNoise(None, None, f"unknown: {why} (too coarse a grid to tell noise from the response)")
    x = np.log10(data.frequency_hz)
    sg = smoother_sd(x, data.gain_db)
    sp = smoother_sd(x, np.degrees(np.unwrap(np.radians(data.phase_deg))))
    return FrequencyNoise(np.full(n, max(sg, PRECISION_DB)), np.full(n, max(sp, PRECISION_DB)),
                          "scatter about a local fit")


__all__ = ["FrequencyNoise", "MIN_PER_DECADE", "coherence_sd", "frequency_noise", "per_decade", "smoother_sd"]
