"""The random error of the margins read off a measured plant response (``--plant-frf``), and
their 95 % intervals.

From the estimate to the loop
-----------------------------
An H1 estimate from ``n`` averaged spectra at coherence ``coh`` carries a random error whose
relative standard deviation in magnitude and whose standard deviation of phase (rad) are
alike (Bendat and Piersol, Random Data, ch. 9): a circular error of ``ln H``, independent from
point to point. Its size is ``sqrt((1 - coh) / (2 (n - 1) coh))``: the coherence measures the
part of the response that does not repeat from spectrum to spectrum, estimated from the same
``n`` spectra, so with ``n - 1`` degrees of freedom (Bendat and Piersol's large-``n`` form has
``n``; for a periodic excitation averaged over ``n`` periods the form with ``n - 1`` is exact),
and the interval is Student's t with ``2 (n - 1)`` degrees of freedom (2.45 standard
deviations for 4 averages, the normal's 1.96 for many). The loop on the measured response is
a function of the response at each point, so ``d ln L = S d ln H`` with ``S = d ln L / d ln H``
(1 for a loop proportional to the plant, small where an inner loop of high gain hides the
plant); a circular error times a complex number stays circular, ``|S|`` times as large.

To the margins
--------------
A crossing is interpolated between two points (``log |L|`` and the phase linear in
``log f``, :func:`~servo_toolkit.loop.measured.sampled_crossings`); its margin is carried to
first order through that interpolation, the weights ``1 - t`` and ``t`` of the two points
included:

- phase margin (at ``|L| = 1``): the phase's error, plus the crossing's shift from the
  magnitude's error times the local phase slope: ``dPM = dphi - (dphi/dx) / (dg/dx) dg``;
- gain margin (at ``arg L = -180 deg``): the magnitude's error, plus the crossing's shift
  from the phase's error times the local magnitude slope: ``dGM = -20 (dg - (dg/dx) /
  (dphi/dx) dphi)`` (``g = log10 |L|``, ``x = log10 f``);
- where the model's transmission is moved by the ratio of the measured mode to the model's
  (:mod:`.measured_mode`), the error of the points that reading rests on moves the ratio and
  so the loop at the crossing: added, with its correlation to the bracketing points';
- Ms at the point where it peaks: ``d ln |1 / (1 + L)| = -Re(L / (1 + L) d ln L)``, standard
  deviation ``|L / (1 + L)| |S| s``.

A margin is the smallest over the crossings, and the noise can add one: where the loop comes
within the interval's reach of a crossing without crossing (the phase within its 95 % band of
-180 deg, or ``|L|`` of 1), the margin a crossing there would have, less its own reach, takes
the interval's lower end down (:func:`near_approach`).

Where the response file carries the error the logged signals' rounding leaves at each point
(``resolution_db``, ``resolution_deg``: an encoder's counts, which under a periodic excitation
repeat in every period, so the coherence does not see them; :mod:`servo_toolkit.identify.resolution`),
it is a second independent part of ``ln H``'s error, carried the same way and added in power
(:func:`combined`); its variance is known, not estimated, so the quantile is Student's t of the
Welch-Satterthwaite degrees of freedom.

The interval states the estimate's random error only: not the grid's (a crossing between
points, an Ms between them), nor a bias of the estimator (leakage of a window), nor the model's
parts of the loop. It is first order: with a coherence low enough that the noise makes and
unmakes crossings along a stretch where the phase runs close to -180 deg, the figure jumps
between crossings and the interval understates it.
"""

from __future__ import annotations

import math

import numpy as np

from ..core.spectra import coherence_sd

#: what the intervals add when the response file carries the logged signals' rounding
RESOLUTION_NOTE = (", with the logged signals' rounding added in power (the file's resolution_db and resolution_deg, "
                   "an error that repeats in every period and that the coherence does not see; Student's t of the "
                   "Welch-Satterthwaite degrees of freedom, nearer the normal's quantile where the rounding "
                   "dominates)")
#: two-sided 95 % quantile of the normal distribution
Z95 = 1.959963984540054
#: relative step of the plant response for the loop's sensitivity to it
_STEP = 1e-7
_LN10 = math.log(10.0)


def quantile(averages: int | None) -> float:
    """Two-sided 95 % quantile for an error whose variance the coherence of ``averages``
    spectra estimates: Student's t with ``2 (averages - 1)`` degrees of freedom (the normal's
    :data:`Z95` for many averages); NaN below two averages."""
    if averages is None or averages < 2:
        return math.nan
    from scipy.stats import t
    return float(t.ppf(0.975, 2 * (averages - 1)))


def point_sd(coherence, averages: int | None) -> np.ndarray | None:
    """Standard deviation of ``ln H`` (nepers, and rad of phase) at each point,
    ``sqrt((1 - coh) / (2 (averages - 1) coh))``, or None when the number of spectra
    averaged is unknown or 1 (a single spectrum's coherence is 1 whatever the noise)."""
    if averages is None or averages < 2:
        return None
    return coherence_sd(coherence, averages - 1)


def combined(sd_coherence: float, sd_resolution: float, averages: int | None) -> tuple[float, float]:
    """``(sd, q)``: the standard deviation of an error of two independent parts and its
    two-sided 95 % quantile. The coherence's part (``sd_coherence``) is estimated with
    ``2 (averages - 1)`` degrees of freedom; the logged signals' rounding (``sd_resolution``)
    has a variance known from their steps. Student's t of the Welch-Satterthwaite degrees of
    freedom, ``2 (n - 1) (v_c + v_r)^2 / v_c^2``: the coherence's quantile without rounding,
    the normal's where the rounding dominates."""
    vc, vr = sd_coherence ** 2, sd_resolution ** 2
    sd = math.sqrt(vc + vr)
    if not vr > 0:
        return sd, quantile(averages)
    if averages is None or averages < 2:
        return sd, math.nan
    if not vc > 0:
        return sd, Z95
    from scipy.stats import t
    return sd, float(t.ppf(0.975, 2 * (averages - 1) * (vc + vr) ** 2 / vc ** 2))


def sensitivity(loop_of, response) -> np.ndarray:
    """``d ln L / d ln H`` at each point, by a step of :data:`_STEP` in ``H`` (``loop_of(H)``
    gives ``L`` point by point)."""
    h = np.asarray(response, complex)
    return (loop_of(h * (1.0 + _STEP)) / loop_of(h) - 1.0) / _STEP


def bracket_weights(kind: str, t: float, g0: float, g1: float, p0: float, p1: float) -> tuple:
    """``(w0, w1, c)``: a crossing at fraction ``t`` between two points of ``log10 |L|``
    ``g0``, ``g1`` and phase ``p0``, ``p1`` (deg) moves its margin (deg for a gain crossing,
    dB for a phase crossing) by ``Re(c (w0 e0 + w1 e1))`` for errors ``e0``, ``e1`` of
    ``ln L`` at the two points (module notes); ``c`` None when the crossing's place is
    undefined (the other quantity flat between the points)."""
    rad = math.degrees(1.0)
    if kind == "gain":  # dPM = dphi + (p1 - p0) / (g0 - g1) dg
        if g1 == g0:
            return 1 - t, t, None
        return 1 - t, t, (p1 - p0) / ((g0 - g1) * _LN10) - 1j * rad
    if p1 == p0:  # dGM = -20 (dg - (g1 - g0) / (p1 - p0) dphi)
        return 1 - t, t, None
    return 1 - t, t, -20.0 / _LN10 - 1j * 20.0 * (g1 - g0) / (p1 - p0) * rad


def crossing_sd(kind: str, t: float, k: int, loop, sens, sd, ratio_gradient=None, per_ratio: float = 0.0) -> float:
    """Standard deviation of the margin of a crossing between points ``k`` and ``k + 1``.

    Parameters
    ----------
    kind : {"gain", "phase"}
    t : float
        The crossing's fraction of the way from point ``k`` (in ``log f``).
    loop : numpy.ndarray
        The loop on the measured response at each point.
    sens : numpy.ndarray
        ``d ln L / d ln H`` at each point.
    sd : numpy.ndarray
        Standard deviation of ``ln H`` at each point (real and imaginary parts alike).
    ratio_gradient : dict of int to float, optional
        ``d ratio / d ln |H|`` at the points the mode's reading rests on (the model's
        transmission moved by the ratio, :mod:`.measured_mode`).
    per_ratio : float
        The margin's change per unit of that ratio.
    """
    g = np.log10(np.abs(loop[k:k + 2]))
    ph = np.degrees(np.unwrap(np.angle(loop[k:k + 2])))
    w0, w1, c = bracket_weights(kind, t, g[0], g[1], ph[0], ph[1])
    if c is None:
        return math.nan
    coef = {k: c * w0 * sens[k], k + 1: c * w1 * sens[k + 1]}
    for q, d_ratio in (ratio_gradient or {}).items():  # a real error of ln |H| moves the ratio
        coef[q] = coef.get(q, 0.0) + per_ratio * d_ratio
    return float(math.sqrt(sum(abs(v) ** 2 * sd[q] ** 2 for q, v in coef.items())))


def sensitivity_sd_db(loop, sd) -> np.ndarray:
    """Standard deviation (dB) of ``|1 / (1 + L)|`` at each point."""
    return 20.0 / _LN10 * np.abs(loop / (1.0 + loop)) * sd


def interval(value, sd, q: float = Z95) -> tuple[float, float] | None:
    """The 95 % interval ``value -+ q sd`` (None without a finite figure, deviation or
    quantile)."""
    if value is None or sd is None or not (math.isfinite(value) and math.isfinite(sd) and math.isfinite(q)):
        return None
    return (float(value - q * sd), float(value + q * sd))


def _offsets(loop, sd, kind: str, q: float):
    """``(off, value, spread, near)`` at each point: the distance from the crossing's level
    (``|ln |L||``, or the phase's from -180 deg in rad), the margin a crossing there would
    have and its standard deviation, and whether the distance is within ``q`` of ``sd``."""
    ln_mag = np.log(np.abs(loop))
    phase = np.unwrap(np.angle(loop))
    if kind == "gain":
        off, value, spread = np.abs(ln_mag), np.degrees(np.remainder(phase, 2 * np.pi)) - 180.0, np.degrees(sd)
    else:
        off = np.abs(np.angle(-loop))  # the phase's distance from -180 deg (mod 360)
        value, spread = -20.0 / _LN10 * ln_mag, 20.0 / _LN10 * sd
    return off, value, spread, off <= q * sd


def near_approach(f, loop, sd, good, crossings, kind: str, q: float) -> float | None:
    """The lowest 95 % bound of a margin at a near approach: a run of neighbouring points of
    good coherence where the loop comes within ``q`` standard deviations of a crossing
    (``|L| = 1`` for ``kind`` "gain", ``arg L = -180 deg`` for "phase") without a crossing
    of that kind bracketed by its points, where the noise can make one (None: no such run)."""
    _, value, spread, near = _offsets(loop, sd, kind, q)
    near = good & near
    bracketed = {x for c in crossings if c.source == "measured" for x in (c.low_hz, c.high_hz)}
    lowest, k = None, 0
    while k < f.size:
        if not near[k]:
            k += 1
            continue
        end = k
        while end + 1 < f.size and near[end + 1]:
            end += 1
        run = np.arange(k, end + 1)
        if not any(float(f[j]) in bracketed for j in run):
            bound = float(np.min(value[run] - q * spread[run]))
            lowest = bound if lowest is None else min(lowest, bound)
        k = end + 1
    return lowest


def reaches(bounds, required: float, sense: str) -> bool:
    """The interval ``bounds`` reaches past ``required`` on the failing side of ``sense``."""
    if bounds is None:
        return False
    return bounds[0] < required if sense == ">=" else bounds[1] > required


def basis_note(averages: int | None, resolution: bool = False) -> str:
    """What the margins' intervals rest on (``resolution``: the logged signals' rounding is in
    them), or why there are none."""
    if averages is None:
        return ("no interval on the measured margins: the file does not record the number of spectra averaged "
                "behind its coherence (an averages column, as frf -o writes, or a '# averages: N' line before "
                "the header), without which the coherence does not give the estimate's random error")
    if averages < 2:
        return ("no interval on the measured margins: the response rests on a single spectrum, whose coherence is "
                "1 whatever the noise")
    return (f"95 % intervals (two-sided) of the measured margins: the H1 estimate's random error from the coherence "
            f"of {averages} averaged spectra, sqrt((1 - coh) / (2 ({averages} - 1) coh)) relative in magnitude and in "
            f"rad of phase (Bendat and Piersol), carried through the loop and the crossings' interpolation to first "
            f"order, +-{quantile(averages):.3g} standard deviations (Student's t, {2 * (averages - 1)} degrees of "
            "freedom)" + (RESOLUTION_NOTE if resolution else "")
            + "; the grid's resolution and the model's parts of the loop are not in them")


__all__ = ["RESOLUTION_NOTE", "Z95", "basis_note", "bracket_weights", "combined", "crossing_sd", "interval", "near_approach", "point_sd", "quantile",
           "reaches", "sensitivity", "sensitivity_sd_db"]
