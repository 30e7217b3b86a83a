"""Phase and gain crossings of a SISO loop, found on the loop's own frequency response.

python-control's ``stability_margins`` converts a state-space loop into polynomials and
takes the real roots of ``Im L(jw)`` and ``|L(jw)| - 1``; at high frequency rounding in
those coefficients yields roots that are no crossings of the loop at all (a gain margin of
572 dB at 2.6 MHz for ``1 / (s^3 + 2 s^2 + 3 s + 4)``). Here every crossing is a root of
``Im L(jw)`` (phase) or ``log |L(jw)|`` (gain) bracketed on a grid refined until no step
turns ``L`` by more than 30 deg, refined by Brent's method (every bracket in one batched
search), and kept only when ``L`` itself, evaluated there, is real and negative (phase
crossing) or of unit magnitude (gain crossing).
python-control's roots are used as extra grid points, never as crossings on their own word.

A crossing is also kept only when double precision resolves it (:func:`resolvable`): the
margin speaks of ``1 + L(jw)``, which rounds to 1 when ``|L|`` is far below machine epsilon
and to ``L`` when ``|L|`` is far above its inverse, and the computed ``L(jw)`` itself carries
a rounding error (:func:`rounding_bound`) that must stay below the crossing tolerance. A
phase crossing at ``|L| = 1e-22`` (a "gain margin" of 427 dB at 6.5 kHz) or one where the
phase of ``L`` only wanders in the rounding of an ill-conditioned evaluation is no crossing.
"""

from __future__ import annotations

import numpy as np

from ..lti.analysis import stability_margins
from ..lti.response import evaluate
from ..lti.system import as_system
from .brent import brentq
from .response import solved_response

#: a phase crossing's ``|Im L| / |L|`` and a gain crossing's ``| |L| - 1 |`` at most this
CROSSING_TOL = 1e-6
#: the search spans this factor below the smallest and above the largest pole or zero
SPAN = 1e4
#: a seed this close (relative) to a bracketed root is that root
SEED_NEAR = 1e-4
#: grid refinement: no step of the grid turns ``L`` by more than this (rad)
MAX_TURN = np.pi / 6
#: machine epsilon of the float64 evaluation
EPS = float(np.finfo(float).eps)
#: ``|L|`` range (dB) in which both terms of ``1 + L`` are resolved to :data:`CROSSING_TOL`:
#: ``EPS / CROSSING_TOL <= |L| <= CROSSING_TOL / EPS`` (about +-193 dB); a gain margin beyond
#: it is no figure double precision can speak of
RESOLVABLE_DB = float(20 * np.log10(CROSSING_TOL / EPS))


def response_of(loop):
    """``L(s)`` of the SISO loop as a vectorized callable: complex frequencies -> values (1-D).

    A continuous state-space loop (the toolkit's own or python-control's) is evaluated as
    python-control does without Slycot (``C (s I - A)^-1 B + D`` by a linear solve per
    point), with the matrices read once and every point solved in one batched call; a root
    search asking for one point at a time pays a few microseconds instead of python-control's
    call overhead. A point on a pole gives ``inf`` (as python-control). Other systems are
    called as they are.
    """
    try:
        loop = as_system(loop)
    except TypeError:  # a transfer function: python-control evaluates it
        def call(s):
            with np.errstate(all="ignore"):
                return np.asarray(loop(np.asarray(s, complex)), complex).reshape(-1)
        return call
    A, B, C, D = loop.A, loop.B, loop.C, loop.D
    if not (loop.isctime() and loop.nstates > 1 and loop.issiso()):
        def call(s):
            with np.errstate(all="ignore"):
                return evaluate(A, B, C, D, np.atleast_1d(np.asarray(s, complex)).reshape(-1))[:, 0, 0]
        return call

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
    roots = np.concatenate([loop.poles(), loop.zeros()])
    mags = np.abs(roots[np.isfinite(roots)])
    mags = mags[mags > 0]
    return (mags.min() / SPAN, mags.max() * SPAN) if mags.size else (1 / SPAN, SPAN)


def _grid(loop, seeds, response):
    """Positive frequencies (rad/s) around every pole and zero and every seed, refined where
    ``L`` turns, and ``L`` there (``response`` a :func:`response_of` callable): each
    refinement evaluates the new points only."""
    roots = np.concatenate([loop.poles(), loop.zeros()])
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
    lw = _evaluate(response, w)
    for _ in range(10):
        with np.errstate(all="ignore"):
            turn = np.abs(np.angle(lw[1:] / lw[:-1]))
        bad = np.nonzero(turn > MAX_TURN)[0]
        if not bad.size:
            break
        new = np.sqrt(w[bad] * w[bad + 1])
        w, first = np.unique(np.concatenate([w, new]), return_index=True)
        lw = np.concatenate([lw, _evaluate(response, new)])[first]
    return w, lw


def _roots(fun, w, seeds=(), v=None) -> list:
    """Roots of ``fun`` bracketed by sign changes on ``w`` (Brent's method, every bracket at
    once: :func:`.brent.brentq`, scipy's steps and tolerances), plus each seed that no
    bracketed root lies near (a tangency a sign change cannot show). A bracket where ``fun``
    turns NaN or that does not converge gives no root. ``v``: ``fun(w)`` when the caller has
    it."""
    v = fun(w) if v is None else v
    ok = np.isfinite(v)
    out = [w[i] for i in np.nonzero(ok & (v == 0))[0]]
    i = np.nonzero(ok[:-1] & ok[1:] & (np.sign(v[:-1]) * np.sign(v[1:]) < 0))[0]
    roots, solved = brentq(fun, w[i], w[i + 1], xtol=1e-15 * w[i], rtol=4e-15, maxiter=200)
    out += [float(x) for x in roots[solved]]
    found = np.asarray(out, float)
    out += [x for x in seeds if not np.any(np.abs(found - x) <= SEED_NEAR * x)]
    return out


def _unique(w, rel=1e-7) -> np.ndarray:
    w = np.sort(np.asarray(w, float))
    if w.size == 0:
        return w
    keep = np.concatenate([[True], np.diff(w) > rel * w[1:]])
    return w[keep]


def rounding_bound(loop, w) -> np.ndarray:
    """Bound on the rounding error of ``L(jw)``, relative to ``|L(jw)|``, at frequencies ``w``.

    For a state-space loop ``L = C (jw I - A)^-1 B + D`` solved by LU with partial pivoting
    (componentwise backward stable), the forward error of ``x = (jw I - A)^-1 B`` is at most
    about ``n eps |M^-1| (|M| |x| + |B|)`` with ``M = jw I - A`` (Skeel's bound), so
    ``|dL| <= n eps |C| |M^-1| (|M| |x| + |B|) + eps (|C| |x| + |D|)``. Unlike the normwise
    condition number it is blind to the scaling of the states, so it stays near ``n eps``
    where the evaluation is accurate and grows where it is not (near a pole at the origin, an
    integrator's asymptote evaluated at micro-hertz). Other systems get 0 (no bound known).

    Parameters
    ----------
    loop : control.LTI
        SISO open loop.
    w : array_like
        Angular frequencies (rad/s).

    Returns
    -------
    numpy.ndarray
        ``|dL| / |L|`` per frequency (``inf`` where ``L`` is 0 or not finite).
    """
    w = np.atleast_1d(np.asarray(w, float))
    try:
        loop = as_system(loop)
    except TypeError:
        return np.zeros(w.shape)
    if not (loop.isctime() and loop.nstates > 0 and loop.issiso()):
        return np.zeros(w.shape)
    A, B, C, D = (np.asarray(m, float) for m in (loop.A, loop.B, loop.C, loop.D))
    n = A.shape[0]
    out = np.empty(w.shape)
    for k, wk in enumerate(w):
        M = 1j * wk * np.eye(n) - A
        try:
            Mi = np.linalg.inv(M)
        except np.linalg.LinAlgError:
            out[k] = np.inf
            continue
        x = Mi @ B
        lw = complex((C @ x + D)[0, 0])
        err = (n * EPS * (np.abs(C) @ np.abs(Mi) @ (np.abs(M) @ np.abs(x) + np.abs(B)))[0, 0]
               + EPS * ((np.abs(C) @ np.abs(x))[0, 0] + abs(D[0, 0])))
        with np.errstate(all="ignore"):
            out[k] = err / abs(lw) if np.isfinite(lw) and lw != 0 else np.inf
    return out


def resolvable(loop, w, lw) -> np.ndarray:
    """Which crossings at ``w`` (rad/s), ``L`` there ``lw``, double precision resolves.

    Both rules tie to :data:`CROSSING_TOL`, the tolerance a crossing is accepted to:

    - ``1 + L`` carries each term to ``eps max(1, |L|)``; the crossing is resolved when that is
      at most ``CROSSING_TOL min(1, |L|)``, i.e. ``|20 log10 |L|| <=`` :data:`RESOLVABLE_DB`
      (about 193 dB). Beyond it ``1 + L`` rounds to 1 (or to ``L``): no gain change the
      closed loop can see puts it through -1 there.
    - the computed ``L(jw)`` is within :data:`CROSSING_TOL` of the loop's own value
      (:func:`rounding_bound`); otherwise the sign of ``Im L`` (or of ``|L| - 1``) is rounding.
    """
    lw = np.atleast_1d(np.asarray(lw, complex))
    with np.errstate(all="ignore"):
        db = 20 * np.log10(np.abs(lw))
    return np.isfinite(db) & (np.abs(db) <= RESOLVABLE_DB) & (rounding_bound(loop, w) <= CROSSING_TOL)


def crossings(loop):
    """Every phase crossing and gain crossing of the SISO loop ``L`` at ``0 < w < inf``.

    Parameters
    ----------
    loop : control.LTI
        Continuous-time SISO open loop.

    A crossing double precision cannot resolve (:func:`resolvable`) is left out.

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
    loop = as_system(loop)
    with np.errstate(all="ignore"):
        try:
            _, _, _, wpc0, wgc0, _ = stability_margins(loop, returnall=True)
        except (np.linalg.LinAlgError, ValueError):
            # a long chain's loop: its polynomial coefficients overflow, so python-control
            # gives no seeds and the grid alone brackets the crossings
            wpc0, wgc0 = np.array([]), np.array([])
    lo, hi = _span(loop)
    wpc0 = np.atleast_1d(np.asarray(wpc0, float))
    wpc0 = wpc0[(wpc0 >= lo) & (wpc0 <= hi)]
    system, loop = loop, response_of(loop)
    w, lw = _grid(system, np.concatenate([wpc0, np.atleast_1d(wgc0)]), loop)

    def im(x, lw=None):
        lw = _evaluate(loop, x) if lw is None else lw
        with np.errstate(all="ignore"):
            return lw.imag / np.abs(lw)

    def log_mag(x, lw=None):
        with np.errstate(all="ignore"):
            return np.log(np.abs(_evaluate(loop, x) if lw is None else lw))

    seeds_g = [x for x in np.atleast_1d(wgc0) if np.isfinite(x) and x > 0]
    inside = (w >= lo) & (w <= hi)
    wpc = _unique(_roots(im, w[inside], list(wpc0), im(w[inside], lw[inside])))
    lp = _evaluate(loop, wpc)
    real_negative = np.isfinite(lp) & (lp.real < 0) & (np.abs(lp.imag) <= CROSSING_TOL * np.abs(lp))
    wpc, lp = wpc[real_negative], lp[real_negative]
    keep = resolvable(system, wpc, lp)
    wpc, lp = wpc[keep], lp[keep]
    wgc = _unique(_roots(log_mag, w, seeds_g, log_mag(w, lw)))
    lg = _evaluate(loop, wgc)
    unit = np.isfinite(lg) & (np.abs(np.abs(lg) - 1) <= CROSSING_TOL)
    wgc, lg = wgc[unit], lg[unit]
    keep = resolvable(system, wgc, lg)
    wgc, lg = wgc[keep], lg[keep]
    pm = np.remainder(np.angle(lg, deg=True), 360.0) - 180.0
    return wpc, 1.0 / np.abs(lp), wgc, pm
