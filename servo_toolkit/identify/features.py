"""Features of a motor current -> motor speed response that the data show by themselves.

A drive's current -> speed response is an inertia line (``|H| = N^2 eta Kt / (w J)``) bent by
the drivetrain's modes: each antiresonance (the load side held still, a notch) and the
resonance above it (a peak). With the integrator removed, ``g(f) = ln(|H| 2 pi f)`` is flat
at low frequency (its level is the total inertia) and has a notch at each antiresonance and
a peak at each resonance. :func:`response_features` finds the level, the first notch and
the first peak above it (prominence at least :data:`PROMINENCE_DB`, located between grid
points by a parabola in log frequency); :func:`feature_mismatch` compares two responses'
features, so a search can start where the model shows the data's own features.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import signal

#: smallest depth of a notch or height of a peak of ln(|H| w) taken as a feature (dB)
PROMINENCE_DB = 3.0
#: mismatch given to a feature that one response shows and the other does not (nepers)
MISSING = 3.0
#: points at the low end of the band whose median gives the inertia-line level
LEVEL_POINTS = 5


def _vertex(x, y, k):
    """Abscissa of the parabola through the points k-1, k, k+1 (k itself at an edge)."""
    if k <= 0 or k >= len(x) - 1:
        return float(x[k])
    x0, x1, x2 = x[k - 1:k + 2]
    y0, y1, y2 = y[k - 1:k + 2]
    den = (x0 - x1) * (x0 - x2) * (x1 - x2)
    a = (x2 * (y1 - y0) + x1 * (y0 - y2) + x0 * (y2 - y1)) / den
    b = (x2 ** 2 * (y0 - y1) + x1 ** 2 * (y2 - y0) + x0 ** 2 * (y1 - y2)) / den
    if a == 0:
        return float(x1)
    return float(np.clip(-b / (2 * a), x0, x2))


def response_features(frequency_hz, response) -> tuple:
    """The level of the inertia line and the first antiresonance and resonance.

    Parameters
    ----------
    frequency_hz : array_like
        Increasing frequencies (Hz).
    response : array_like
        Complex current -> speed response at those frequencies.

    Returns
    -------
    tuple
        ``(level, ln_f_antiresonance, ln_f_resonance)``: the median of ln(|H| 2 pi f) over
        the lowest points, and the natural logarithms of the notch and peak frequencies (Hz;
        None where the response shows none).
    """
    f = np.asarray(frequency_hz, float)
    g = np.log(np.abs(np.asarray(response, complex)) * 2 * math.pi * f)
    x = np.log(f)
    prom = PROMINENCE_DB / 20 * math.log(10)
    notches, _ = signal.find_peaks(-g, prominence=prom)
    notch = _vertex(x, -g, int(notches[0])) if notches.size else None
    start = int(notches[0]) if notches.size else 0
    peaks, _ = signal.find_peaks(g[start:], prominence=prom)
    peak = _vertex(x, g, start + int(peaks[0])) if peaks.size else None
    stop = int(notches[0]) if notches.size else len(g)
    level = float(np.median(g[:max(1, min(LEVEL_POINTS, stop))]))
    return level, notch, peak


def feature_mismatch(model_features, data_features) -> np.ndarray:
    """The differences of two responses' features (nepers and ln Hz), :data:`MISSING` for
    a feature that one shows and the other does not, 0 for one that neither shows."""
    out = [model_features[0] - data_features[0]]
    for m, d in zip(model_features[1:], data_features[1:]):
        out.append(0.0 if m is None and d is None else MISSING if m is None or d is None else m - d)
    return np.array(out)
