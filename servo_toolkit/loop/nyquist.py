"""The Nyquist criterion's count of the closed-loop right-half-plane poles of a loop, from
the winding of ``1 + L`` along a contour a hair right of the imaginary axis (what
:func:`.margins.loop_margins` cross-checks the closed-loop poles with).
"""

from __future__ import annotations

import numpy as np

from ..lti.system import as_system
from .crossings import response_of


def _scale(poles, zeros) -> float:
    mags = np.abs(np.concatenate([np.atleast_1d(poles), np.atleast_1d(zeros)]))
    mags = mags[np.isfinite(mags) & (mags > 0)]
    return float(mags.max()) if mags.size else 1.0


def nyquist_count(loop, rhp_poles: int) -> int:
    """Closed-loop right-half-plane poles of ``1 + L`` by the Nyquist criterion.

    The Nyquist contour runs up the line Re s = sigma, a hair right of the imaginary axis
    (so that integrators and undamped open-loop poles lie outside it, the usual indentation),
    and closes through the right half plane, where ``1 + L`` tends to ``1 + L(inf)``. The
    winding of ``1 + L`` along it is accumulated on a grid refined until no step turns the
    phase by more than 45 deg; Z = P - winding (the contour is clockwise).
    """
    loop = as_system(loop)
    poles, zeros = loop.poles(), loop.zeros()
    scale = _scale(poles, zeros)
    sigma = 1e-7 * scale
    w_pos = np.unique(np.concatenate([np.geomspace(1e-7 * scale, 1e4 * scale, 4000),
                                      np.abs(np.imag(np.concatenate([poles, zeros])))]))
    response = response_of(loop)
    w, f = _finite_points(response, sigma, np.concatenate([-w_pos[::-1], [0.0], w_pos]))
    for _ in range(12):  # each refinement evaluates its new points only
        step = np.abs(np.angle(f[1:] / f[:-1]))
        bad = np.nonzero(~(step < np.pi / 4))[0]
        if not bad.size:
            break
        wn, fn = _finite_points(response, sigma, 0.5 * (w[bad] + w[bad + 1]))
        order = np.argsort(np.concatenate([w, wn]), kind="stable")
        w, f = np.concatenate([w, wn])[order], np.concatenate([f, fn])[order]
    winding = np.sum(np.angle(f[1:] / f[:-1])) / (2 * np.pi)
    return int(rhp_poles - round(winding))


def _finite_points(response, sigma, w):
    """``(w, 1 + L(sigma + j w))`` at the points where it is finite and nonzero (``response``
    a :func:`.crossings.response_of` callable): a point on a pole (``inf``) or one whose value
    underflows to zero (a loop gain of 1e-30 times a zero at 1e30) turns no measurable phase,
    and a NaN there would stop the count."""
    with np.errstate(all="ignore"):
        f = 1.0 + response(sigma + 1j * w)
    keep = np.isfinite(f) & (f != 0)
    return w[keep], f[keep]
