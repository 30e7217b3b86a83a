"""Loop figures from frequency responses on a grid, vectorized over leading axes.

Used for the fast design search and the robustness study; the reported margins of a design
come from python-control (:mod:`servo_toolkit.loop.margins`), and tests check that both agree.
On the grid alone a crossing is located to the grid's resolution (a steep crossing near a
drivetrain resonance can be off by tenths of a degree); given the exact loop response as a
function (``response``), the grid only brackets each crossing, the sensitivity peak and the
bandwidth, and :func:`refined_figures` solves for them to solver precision, vectorized over
every bracket of every variant at once (scipy's elementwise bracketed root finder and
minimizer).
"""

from __future__ import annotations

import numpy as np


def low_end_margin(L) -> np.ndarray:
    """|gain margin| (dB) of a crossing at w -> 0: where the loop at the grid's first
    frequency is finite and within 6 deg of the negative real axis, as for an
    open-loop-unstable plant with L(0) < 0 (the figure is |L| there, which tends to L(0) as
    the grid starts lower); ``inf`` elsewhere. With integrators L there is huge, so the
    figure is large and never the smallest."""
    l0 = np.asarray(L, complex)[..., 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        real_negative = np.isfinite(l0) & (l0.real < 0) & (np.abs(l0.imag) <= 0.105 * np.abs(l0.real))
        return np.where(real_negative, np.abs(20 * np.log10(np.abs(l0))), np.inf)


def grid_figures(w, L, phase_freq: float | None = None, response=None):
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
    response : callable, optional
        ``response(rows, w)`` -> the loop response of the given rows (leading axes of ``L``
        flattened) at angular frequencies ``w``; with it every figure is refined
        (:func:`refined_figures`), without it figures are interpolated on the grid
        (:func:`grid_margins` and :func:`grid_closed_loop`).

    Returns
    -------
    dict of numpy.ndarray
        ``gain_margin_db``, ``phase_margin_deg``, ``sensitivity_peak_db``, ``bandwidth_hz``,
        ``phase_at_freq_deg``; ``inf`` where there is no crossing.
    """
    L = np.asarray(L, complex)
    if response is not None:
        return refined_figures(w, L, response, phase_freq)
    return {**grid_margins(w, L), **grid_closed_loop(w, L, phase_freq)}


def _crossing_values(f, value, where):
    """At every grid interval where ``f`` (2-D) changes sign, both ends finite, and ``where``
    holds: (rows, ``value`` interpolated linearly in ``f`` to its zero)."""
    f0, f1 = f[:, :-1], f[:, 1:]
    sign = np.sign(f)
    rows, k = np.nonzero((sign[:, :-1] != sign[:, 1:]) & np.isfinite(f0) & np.isfinite(f1) & where)
    a, b = f0[rows, k], f1[rows, k]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = a / (a - b)
    return rows, value[rows, k] + t * (value[rows, k + 1] - value[rows, k])


def unwrap(p) -> np.ndarray:
    """``numpy.unwrap(p, axis=-1)``, its correction computed only at the steps it applies to
    (a step of at least pi, or NaN), the rest being zero: the same phases to the last bit."""
    p = np.asarray(p, float)
    dd = np.diff(p, axis=-1)
    correct = np.zeros_like(dd)
    at = np.nonzero(~(np.abs(dd) < np.pi))
    d = dd[at]
    dmod = np.mod(d - (-np.pi), 2 * np.pi) + (-np.pi)
    np.copyto(dmod, np.pi, where=(dmod == -np.pi) & (d > 0))
    correct[at] = dmod - d
    out = p.copy()
    out[..., 1:] = p[..., 1:] + correct.cumsum(axis=-1)
    return out


def grid_margins(w, L) -> dict:
    """The margins of :func:`grid_figures` interpolated on the grid: minimum gain margin
    (dB, at the crossings of the negative real axis and at the grid's low end), minimum
    phase margin (deg, at ``|L| = 1``) and sensitivity peak (dB), each figure computed at the
    grid intervals that hold a crossing only."""
    L = np.asarray(L, complex)
    shape = L.shape[:-1]
    L2 = L.reshape(-1, len(w))
    n = L2.shape[0]
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        mag_db = 20 * np.log10(np.abs(L2))
        S = 1 / (1 + L2)
        # gain margins: crossings of the negative real axis
        neg = (np.real(L2[:, :-1]) < 0) | (np.real(L2[:, 1:]) < 0)
        rows, mag_at = _crossing_values(np.imag(L2), mag_db, neg)
        gm = np.minimum(_per_row_min(n, rows, np.abs(mag_at)), low_end_margin(L2))
        # phase margins: |L| = 1
        ph = np.degrees(unwrap(np.angle(L2)))
        rows, ph_at = _crossing_values(mag_db, ph, True)
        pm = _per_row_min(n, rows, (ph_at % 360.0) - 180.0)
        ms = 20 * np.log10(np.nanmax(np.abs(S), axis=-1))
    out = {"gain_margin_db": gm, "phase_margin_deg": pm, "sensitivity_peak_db": ms}
    return {key: v.reshape(shape) for key, v in out.items()}


def grid_closed_loop(w, L, phase_freq: float | None = None) -> dict:
    """The closed-loop figures of :func:`grid_figures` interpolated on the grid: the -3 dB
    bandwidth (Hz) and, given ``phase_freq`` (Hz), the phase (deg) there."""
    L = np.asarray(L, complex)
    logw = np.log(w)
    # bandwidth: first drop of |T| below -3 dB (python-control's drop) of the unit DC gain
    # of a position loop with an integrator
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        t_db = 20 * np.log10(np.abs(L / (1 + L)))
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
    out = {"bandwidth_hz": bw}
    if phase_freq is not None:
        out["phase_at_freq_deg"] = _phase_at(w, L, phase_freq)
    return out


def _phase_at(w, L, phase_freq):
    """Closed-loop phase (deg, unwrapped from the grid's start) at ``phase_freq`` (Hz),
    interpolated in log frequency (exact at a grid frequency)."""
    x = np.log(2 * np.pi * phase_freq)
    logw = np.log(w)
    k = int(np.clip(np.searchsorted(logw, x), 1, len(w) - 1))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        pt = np.degrees(np.unwrap(np.angle(L[..., :k + 1] / (1 + L[..., :k + 1])), axis=-1))
    t = np.clip((x - logw[k - 1]) / (logw[k] - logw[k - 1]), 0.0, 1.0)
    return pt[..., k - 1] + t * (pt[..., k] - pt[..., k - 1])


# --- refinement: crossings and the sensitivity peak to solver precision ---------------------

#: Bracketed root tolerances in x = ln(w): a crossing frequency is exact to ~1e-13 relative,
#: far below any figure's resolution (a phase slope of 1000 deg per unit ln(w) moves the
#: phase margin by 1e-10 deg).
ROOT_TOLERANCES = {"xatol": 1e-13, "xrtol": 1e-13, "fatol": 1e-15}
#: Bracketed minimum tolerances in x = ln(w): at an extremum the value errs by the curvature
#: times the square of the step, ~1e-14 times the curvature (per unit ln(w) squared).
MIN_TOLERANCES = {"xatol": 1e-7, "xrtol": 0.0}


def _brackets(f, x, fun=None, within: float = 0.0, where=None):
    """Root brackets of ``f`` (2-D, on abscissae ``x``): every grid interval where ``f``
    changes sign, both ends finite; with ``fun``, also the pairs of roots one grid step
    hides: every grid extremum of ``f`` that turns back towards zero within ``within`` of
    it (and at ``where``, a mask like ``f``) is solved for with scipy's elementwise bracketed
    minimizer, and where the extremum lies across zero it splits its two intervals into two
    brackets. Returns (rows, x0, x1, f0, f1)."""
    f0, f1 = f[:, :-1], f[:, 1:]
    rows, k = np.nonzero(((f0 < 0) != (f1 < 0)) & np.isfinite(f0) & np.isfinite(f1))
    out = [rows, x[k], x[k + 1], f0[rows, k], f1[rows, k]]
    if fun is None:
        return out
    from scipy.optimize import elementwise
    left, mid, right = f[:, :-2], f[:, 1:-1], f[:, 2:]
    sg = np.sign(mid)
    turn = (sg * mid < sg * left) & (sg * mid <= sg * right) & (np.abs(mid) < within) & (mid != 0)
    turn &= np.isfinite(left) & np.isfinite(right) & (True if where is None else where[:, 1:-1])
    prow, k = np.nonzero(turn)
    if prow.size == 0:
        return out
    k = k + 1
    sgn = sg[prow, k - 1]
    res = elementwise.find_minimum(lambda xx, r, g: g * fun(xx, r), (x[k - 1], x[k], x[k + 1]),
                                   args=(prow, sgn), tolerances=MIN_TOLERANCES)
    hit = res.f_x < 0  # the extremum is across zero: two roots
    prow, k, xm, fm = prow[hit], k[hit], res.x[hit], sgn[hit] * res.f_x[hit]
    add = [np.concatenate(pair) for pair in ((prow, prow), (x[k - 1], xm), (xm, x[k + 1]),
                                             (f[prow, k - 1], fm), (fm, f[prow, k + 1]))]
    return [np.concatenate([a, b]) for a, b in zip(out, add)]


def _refine_roots(fun, rows, x0, x1, f0, f1):
    """Roots of ``fun(x, rows)`` in [x0, x1] where it is ``f0``, ``f1`` of opposite signs,
    vectorized over the brackets with scipy's elementwise Chandrupatla solver. Raises on a
    bracket that does not converge."""
    from scipy.optimize import elementwise
    if rows.size == 0:
        return np.zeros(0)
    res = elementwise.find_root(fun, (x0, x1), args=(rows,), tolerances=ROOT_TOLERANCES)
    # an exact zero at a grid point is a root, not an invalid bracket
    x = np.where(f0 == 0, x0, np.where(f1 == 0, x1, res.x))
    bad = ~res.success & (f0 != 0) & (f1 != 0)
    if np.any(bad):
        raise FloatingPointError(f"{int(bad.sum())} loop crossings did not converge "
                                 f"(status {sorted(set(res.status[bad].tolist()))})")
    return x


def loop_crossings(w, L, response):
    """Every gain crossing (``|L| = 1``) and phase crossing (``L`` on the negative real axis)
    that the grid brackets, refined to solver precision.

    A pair of crossings inside one grid step (a resonance peak of ``|L|`` just reaching 1
    between two samples) is found from the grid extremum next to it (within 6 dB of
    ``|L| = 1``, within 30 deg of the negative real axis), solved for first. A feature so
    narrow that no grid point sees it turn is not found: the grid must resolve the loop's
    lightest-damped modes to that extent.

    Parameters
    ----------
    w : numpy.ndarray
        Increasing angular frequencies (rad/s).
    L : numpy.ndarray
        Open-loop response on ``w``, shape (..., len(w)); its leading axes are flattened
        into rows 0, 1, ...
    response : callable
        ``response(rows, w)`` -> ``L`` of the given rows at angular frequencies ``w``
        (arrays of one shape): the exact loop response, evaluated wherever the refinement
        needs it.

    Returns
    -------
    dict of numpy.ndarray
        ``gain_rows``, ``gain_crossover`` (rad/s), ``phase_margin_deg`` at each gain
        crossing; ``phase_rows``, ``phase_crossover`` (rad/s), ``gain_margin_db`` (20 log10
        1/|L|, python-control's sign) at each phase crossing.
    """
    L2 = np.asarray(L, complex).reshape(-1, len(w))
    x = np.log(w)

    def log_mag(xx, rows):
        return np.log(np.abs(response(rows, np.exp(xx))))

    def sin_phase(xx, rows):
        lw = response(rows, np.exp(xx))
        return lw.imag / np.abs(lw)

    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        rows, *bracket = _brackets(np.log(np.abs(L2)), x, log_mag, within=np.log(2.0))
        xg = _refine_roots(log_mag, rows, *bracket)
        lg = response(rows, np.exp(xg))
        pm = np.remainder(np.angle(lg, deg=True), 360.0) - 180.0
        # crossings of the real axis; the negative half is kept after refinement
        prow, *bracket = _brackets(L2.imag / np.abs(L2), x, sin_phase, within=0.5, where=L2.real < 0)
        xp = _refine_roots(sin_phase, prow, *bracket)
        lp = response(prow, np.exp(xp))
        neg = lp.real < 0
        gm = -20 * np.log10(np.abs(lp[neg]))
    return {"gain_rows": rows, "gain_crossover": np.exp(xg), "phase_margin_deg": pm,
            "phase_rows": prow[neg], "phase_crossover": np.exp(xp[neg]), "gain_margin_db": gm}


def _per_row_min(n, rows, values):
    out = np.full(n, np.inf)
    np.minimum.at(out, rows, values)
    return out


def sensitivity_peak(w, L, response, within_db: float = 6.0):
    """max |1 / (1 + L)| (dB) per row: every local maximum of the grid within ``within_db``
    of the grid's largest is refined with scipy's elementwise bracketed minimizer of
    ln|1 + L| over ln(w); a maximum at the grid's end stays as sampled."""
    from scipy.optimize import elementwise
    L2 = np.asarray(L, complex).reshape(-1, len(w))
    x = np.log(w)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        g = np.log(np.abs(1 + L2))
        gmin = np.nanmin(g, axis=-1)
        peak = (g[:, 1:-1] < g[:, :-2]) & (g[:, 1:-1] <= g[:, 2:])
        peak &= g[:, 1:-1] <= gmin[:, None] + within_db * np.log(10) / 20
        rows, k = np.nonzero(peak)
        k = k + 1
        best = gmin.copy()
        if rows.size:
            def fun(xx, r):
                return np.log(np.abs(1 + response(r, np.exp(xx))))
            res = elementwise.find_minimum(fun, (x[k - 1], x[k], x[k + 1]), args=(rows,),
                                           tolerances=MIN_TOLERANCES)
            ok = res.success  # a flat |1 + L| (an all-pass loop) has no peak to converge on:
            np.minimum.at(best, rows[ok], res.f_x[ok])  # its grid value is the peak
    return -20 * best / np.log(10)


def bandwidth(w, L, response, drop_db: float = -3.0):
    """Closed-loop bandwidth (Hz): the first frequency where |L / (1 + L)| falls below
    ``drop_db`` of the unit DC gain of a position loop with an integrator, bracketed on the
    grid and refined (python-control's ``bandwidth`` definition)."""
    L2 = np.asarray(L, complex).reshape(-1, len(w))
    x = np.log(w)
    level = drop_db * np.log(10) / 20

    def fun(xx, rows):
        lw = response(rows, np.exp(xx))
        return np.log(np.abs(lw)) - np.log(np.abs(1 + lw)) - level

    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        f = np.log(np.abs(L2)) - np.log(np.abs(1 + L2)) - level
    below = f < 0
    first = np.argmax(below, axis=-1)
    anyb = below.any(axis=-1)
    out = np.where(anyb, w[0], np.inf) / (2 * np.pi)
    rows = np.nonzero(anyb & (first > 0))[0]
    k = first[rows]
    out[rows] = np.exp(_refine_roots(fun, rows, x[k - 1], x[k], f[rows, k - 1], f[rows, k])) / (2 * np.pi)
    return out


def refined_figures(w, L, response, phase_freq: float | None = None) -> dict:
    """:func:`grid_figures` with every crossing, the sensitivity peak and the bandwidth
    refined to solver precision by evaluating ``response`` (see :func:`loop_crossings`)."""
    L = np.asarray(L, complex)
    shape = L.shape[:-1]
    n = int(np.prod(shape))
    c = loop_crossings(w, L, response)
    out = {"gain_margin_db": _per_row_min(n, c["phase_rows"], np.abs(c["gain_margin_db"])),
           "phase_margin_deg": _per_row_min(n, c["gain_rows"], c["phase_margin_deg"]),
           "sensitivity_peak_db": sensitivity_peak(w, L, response),
           "bandwidth_hz": bandwidth(w, L, response)}
    out = {key: v.reshape(shape) for key, v in out.items()}
    out["gain_margin_db"] = np.minimum(out["gain_margin_db"], low_end_margin(L))
    if phase_freq is not None:
        out["phase_at_freq_deg"] = _phase_at(w, L, phase_freq)
    return out
