"""Phase and gain crossings of a SISO loop, found on the loop's own frequency response.

python-control's ``stability_margins`` converts a state-space loop into polynomials and
takes the real roots of ``Im L(jw)`` and ``|L(jw)| - 1``; at high frequency rounding in
those coefficients yields roots that are no crossings of the loop at all (a gain margin of
572 dB at 2.6 MHz for ``1 / (s^3 + 2 s^2 + 3 s + 4)``). Here every crossing is a root of
``Im L(jw)`` (phase) or ``log |L(jw)|`` (gain) bracketed on a grid refined until no step
turns ``L`` by more than 30 deg, refined by Brent's method, and kept only when ``L`` itself,
evaluated there, is real and negative (phase crossing) or of unit magnitude (gain crossing).
python-control's roots are used as extra grid points, never as crossings on their own word.
"""

from __future__ import annotations

import control as ct
import numpy as np
from scipy.optimize import brentq

from .response import solved_response

#: a phase crossing's ``|Im L| / |L|`` and a gain crossing's ``| |L| - 1 |`` at most this
CROSSING_TOL = 1e-6
#: the search spans this factor below the smallest and above the largest pole or zero
SPAN = 1e4
#: a seed this close (relative) to a bracketed root is that root
SEED_NEAR = 1e-4
#: grid refinement: no step of the grid turns ``L`` by more than this (rad)
MAX_TURN = np.pi / 6


def response_of(loop):
    """``L(s)`` of the SISO loop as a vectorized callable: complex frequencies -> values (1-D).

    A continuous state-space loop is evaluated as python-control does without Slycot
    (``C (s I - A)^-1 B + D`` by a linear solve per point), with the matrices read once and
    every point solved in one batched call; a root search asking for one point at a time
    pays a few microseconds instead of python-control's call overhead. A point on a pole
    gives ``inf`` (as python-control). Other systems are called as they are.
    """
    if not (isinstance(loop, ct.StateSpace) and loop.isctime() and loop.nstates > 1
            and loop.ninputs == 1 and loop.noutputs == 1):
        def call(s):
            with np.errstate(all="ignore"):
                return np.asarray(loop(np.asarray(s, complex)), complex).reshape(-1)
        return call
    A, B, C, D = (np.asarray(m, float) for m in (loop.A, loop.B, loop.C, loop.D))

    def solve(s):
        return solved_response(A, B, C, D, np.atleast_1d(np.asarray(s, complex)).reshape(-1))[:, 0, 0]
    return solve


def _evaluate(loop, w):
    """``L(jw)`` at real frequencies ``w`` (rad/s); ``loop`` a :func:`response_of` callable."""
    with np.errstate(all="ignore"):
        return loop(1j * np.asarray(w, float))


def _span(loop):
    """Frequencies (rad/s) from ``SPAN`` below the smallest to ``SPAN`` above the largest
    nonzero pole or zero: outside, the phase of ``L`` is within ~1/SPAN rad of its asymptote
    and moves monotonically towards it, so no phase crossing lies there (an apparent one is
    rounding)."""
    roots = np.concatenate([np.atleast_1d(ct.poles(loop)), np.atleast_1d(ct.zeros(loop))])
    mags = np.abs(roots[np.isfinite(roots)])
    mags = mags[mags > 0]
    return (mags.min() / SPAN, mags.max() * SPAN) if mags.size else (1 / SPAN, SPAN)


def _grid(loop, seeds) -> np.ndarray:
    """Positive frequencies (rad/s) around every pole and zero and every seed, refined where
    ``L`` turns."""
    roots = np.concatenate([np.atleast_1d(ct.poles(loop)), np.atleast_1d(ct.zeros(loop))])
    roots = roots[np.isfinite(roots)]
    seeds = np.asarray(seeds, float)
    seeds = seeds[np.isfinite(seeds) & (seeds > 0)]
    lo, hi = _span(loop)
    if seeds.size:
        lo, hi = min(lo, seeds.min() / 10), max(hi, seeds.max() * 10)
    parts = [np.geomspace(lo, hi, 2000)]
    for r in roots:  # a lightly damped pole or zero turns L within a few |Re r| of |Im r|
        if abs(r.imag) > 0:
            parts.append(abs(r.imag) + abs(r.real) * np.linspace(-8.0, 8.0, 33))
    parts += [seeds * (1 - 1e-3), seeds, seeds * (1 + 1e-3)]
    w = np.unique(np.concatenate(parts))
    w = w[(w >= lo) & (w <= hi)]
    response = response_of(loop)
    for _ in range(10):
        lw = _evaluate(response, w)
        with np.errstate(all="ignore"):
            turn = np.abs(np.angle(lw[1:] / lw[:-1]))
        bad = np.nonzero(turn > MAX_TURN)[0]
        if not bad.size:
            break
        w = np.unique(np.concatenate([w, np.sqrt(w[bad] * w[bad + 1])]))
    return w


def _roots(fun, w, seeds=()) -> list:
    """Roots of ``fun`` bracketed by sign changes on ``w`` (Brent's method), plus each seed
    that no bracketed root lies near (a tangency a sign change cannot show)."""
    v = fun(w)
    ok = np.isfinite(v)
    out = [w[i] for i in np.nonzero(ok & (v == 0))[0]]
    for i in np.nonzero(ok[:-1] & ok[1:] & (np.sign(v[:-1]) * np.sign(v[1:]) < 0))[0]:
        try:
            out.append(brentq(lambda x: float(fun(np.array([x]))[0]), w[i], w[i + 1],
                              xtol=1e-15 * w[i], rtol=4e-15, maxiter=200))
        except (ValueError, RuntimeError):
            continue
    found = np.asarray(out, float)
    out += [x for x in seeds if not np.any(np.abs(found - x) <= SEED_NEAR * x)]
    return out


def _unique(w, rel=1e-7) -> np.ndarray:
    w = np.sort(np.asarray(w, float))
    if w.size == 0:
        return w
    keep = np.concatenate([[True], np.diff(w) > rel * w[1:]])
    return w[keep]


def crossings(loop):
    """Every phase crossing and gain crossing of the SISO loop ``L`` at ``0 < w < inf``.

    Parameters
    ----------
    loop : control.LTI
        Continuous-time SISO open loop.

    Returns
    -------
    phase_crossings : numpy.ndarray
        Frequencies (rad/s) where ``L(jw)`` is real and negative (-180 deg, modulo 360),
        ascending.
    gain_margins : numpy.ndarray
        ``1 / |L(jw)|`` at each phase crossing.
    gain_crossings : numpy.ndarray
        Frequencies (rad/s) where ``|L(jw)| = 1``, ascending.
    phase_margins_deg : numpy.ndarray
        ``arg L(jw) + 180 deg`` at each gain crossing, in [-180, 180) (python-control's
        convention).
    """
    with np.errstate(all="ignore"):
        _, _, _, wpc0, wgc0, _ = ct.stability_margins(loop, returnall=True)
    lo, hi = _span(loop)
    wpc0 = np.atleast_1d(np.asarray(wpc0, float))
    wpc0 = wpc0[(wpc0 >= lo) & (wpc0 <= hi)]
    w = _grid(loop, np.concatenate([wpc0, np.atleast_1d(wgc0)]))
    loop = response_of(loop)

    def im(x):
        lw = _evaluate(loop, x)
        return lw.imag / np.abs(lw)

    def log_mag(x):
        with np.errstate(all="ignore"):
            return np.log(np.abs(_evaluate(loop, x)))

    seeds_g = [x for x in np.atleast_1d(wgc0) if np.isfinite(x) and x > 0]
    wpc = _unique(_roots(im, w[(w >= lo) & (w <= hi)], list(wpc0)))
    lp = _evaluate(loop, wpc)
    real_negative = np.isfinite(lp) & (lp.real < 0) & (np.abs(lp.imag) <= CROSSING_TOL * np.abs(lp))
    wpc, lp = wpc[real_negative], lp[real_negative]
    wgc = _unique(_roots(log_mag, w, seeds_g))
    lg = _evaluate(loop, wgc)
    unit = np.isfinite(lg) & (np.abs(np.abs(lg) - 1) <= CROSSING_TOL)
    wgc, lg = wgc[unit], lg[unit]
    pm = np.remainder(np.angle(lg, deg=True), 360.0) - 180.0
    return wpc, 1.0 / np.abs(lp), wgc, pm
