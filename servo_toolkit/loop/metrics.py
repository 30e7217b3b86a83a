"""Loop figures from frequency responses on a grid, vectorized over leading axes.

Used for the fast design search and the robustness study; the reported margins of a design
come from python-control (:mod:`servo_toolkit.loop.margins`), and tests check that both agree.
"""

from __future__ import annotations

import numpy as np


def _interp_crossings(w, f, value):
    """Where ``f`` crosses zero between grid points: mask (..., n-1) and the fraction t."""
    f0, f1 = f[..., :-1], f[..., 1:]
    mask = (np.sign(f0) != np.sign(f1)) & np.isfinite(f0) & np.isfinite(f1)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(mask, f0 / (f0 - f1), 0.0)
    v = value[..., :-1] + t * (value[..., 1:] - value[..., :-1])
    return mask, v


def grid_figures(w, L, phase_freq: float | None = None):
    """Minimum gain margin (dB), minimum phase margin (deg), sensitivity peak (dB),
    closed-loop -3 dB bandwidth (Hz) and closed-loop phase (deg) at ``phase_freq`` (Hz).

    Parameters
    ----------
    w : numpy.ndarray
        Increasing angular frequencies (rad/s), last axis of ``L``.
    L : numpy.ndarray
        Open-loop response, shape (..., len(w)).
    phase_freq : float, optional
        Must be one of the grid frequencies / (2 pi) up to interpolation.

    Returns
    -------
    dict of numpy.ndarray
        ``gain_margin_db``, ``phase_margin_deg``, ``sensitivity_peak_db``, ``bandwidth_hz``,
        ``phase_at_freq_deg``; ``inf`` where there is no crossing.
    """
    L = np.asarray(L, complex)
    logw = np.log(w)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        mag_db = 20 * np.log10(np.abs(L))
        T = L / (1 + L)
        S = 1 / (1 + L)
    # gain margins: crossings of the negative real axis
    mask, mag_at = _interp_crossings(w, np.imag(L), mag_db)
    neg = (np.real(L[..., :-1]) < 0) | (np.real(L[..., 1:]) < 0)
    gm = np.where(mask & neg, np.abs(mag_at), np.inf).min(axis=-1)
    # phase margins: |L| = 1
    ph = np.degrees(np.unwrap(np.angle(L), axis=-1))
    mask, ph_at = _interp_crossings(w, mag_db, ph)
    pm = np.where(mask, (ph_at % 360.0) - 180.0, np.inf).min(axis=-1)
    ms = 20 * np.log10(np.nanmax(np.abs(S), axis=-1))
    # bandwidth: first drop of |T| below -3 dB (python-control's drop) of the unit DC gain
    # of a position loop with an integrator
    t_db = 20 * np.log10(np.abs(T))
    below = t_db < -3.0
    first = np.argmax(below, axis=-1)
    anyb = below.any(axis=-1)
    k = np.clip(first, 1, len(w) - 1)
    a = np.take_along_axis(t_db, (k - 1)[..., None], -1)[..., 0]
    b = np.take_along_axis(t_db, k[..., None], -1)[..., 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.clip((-3.0 - a) / (b - a), 0, 1)
    bw = np.exp(logw[k - 1] + t * (logw[k] - logw[k - 1])) / (2 * np.pi)
    bw = np.where(anyb & (first > 0), bw, np.where(anyb, w[0] / (2 * np.pi), np.inf))
    out = {"gain_margin_db": gm, "phase_margin_deg": pm, "sensitivity_peak_db": ms, "bandwidth_hz": bw}
    if phase_freq is not None:
        pt = np.degrees(np.unwrap(np.angle(T), axis=-1))
        out["phase_at_freq_deg"] = np.array([np.interp(np.log(2 * np.pi * phase_freq), logw, row)
                                             for row in pt.reshape(-1, len(w))]).reshape(pt.shape[:-1])
    return out
