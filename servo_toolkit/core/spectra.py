"""Frequency-response estimates from sampled input and output signals, shared by the rig's
logs (``frf``) and the simulated multisine sweep, so both are compared the same way.

Two estimators of the H1 response ``H = S_uy / S_uu`` with its coherence
``|S_uy|^2 / (S_uu S_yy)``:

:func:`welch_h1`
    Hann-windowed, half-overlapping segments (scipy.signal.welch and csd, means removed):
    for noise and chirp excitations. The window's leakage biases the estimate around a
    sharp resonance (and lowers the coherence there).
:func:`periodic_h1`
    One rectangular window per period of a periodic excitation (a multisine), the periods
    averaged: exact for a periodic steady state (every excited line falls on a bin of the
    period's DFT, no leakage), and the coherence measures only what does not repeat from
    period to period (noise, drift, a transient not yet settled).

Both keep only the frequencies the input excites (power within ``excited_db`` of its peak,
and for the Hann window not merely a stronger line's leakage, :func:`leakage_lines`) and report how many spectra they averaged (segments or periods): the coherence's random
error depends on it (:mod:`servo_toolkit.identify.verdict`). :func:`find_period` recognises a
periodic input.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: input power below its peak (dB) under which a frequency counts as not excited
EXCITED_DB = 40.0
#: largest power of the period-to-period difference of a periodic input, relative to its own
PERIODIC_TOLERANCE = 1e-2
#: least mean of that relative difference over the lags shorter than a period (1 for a
#: periodic signal, near 0 for a slow signal at a short lag)
REPEAT_MEAN = 0.5
#: largest standard deviation (rad) of a line's phase that the unwrapping follows
UNWRAP_SD = 0.1
#: shortest period or segment (samples)
MIN_SEGMENT = 16
#: a time log's comment lines (``# KEY: VALUE``, before its header) that record its period
#: (samples), the periods its response settles over and the bins of the period's DFT its
#: excitation excites (``FIRST:LAST``), read as the periodic window's defaults
#: (``servo-toolkit excite`` writes them)
PERIOD_KEY = "period_samples"
SETTLE_KEY = "settle_periods"
LINES_KEY = "excited_bins"
#: a time log's comment key (``# resolution_COLUMN: STEP``, before its header) that records the
#: step a column's values are rounded to, in the column's unit (an encoder's count)
RESOLUTION_PREFIX = "resolution_"


@dataclass(frozen=True)
class Spectrum:
    """An H1 estimate at the excited frequencies.

    Attributes
    ----------
    frequency_hz : numpy.ndarray
    response : numpy.ndarray
        Complex y / u.
    coherence : numpy.ndarray
        In [0, 1]; identically 1 from a single spectrum.
    averages : int
        Spectra averaged (Welch segments, or periods).
    window : str
        ``"hann"`` or ``"periodic"``.
    input_power, output_power : numpy.ndarray or None
        The input's and the output's power at each frequency, per spectrum averaged, in the
        scale of ``white_power``.
    white_power : float or None
        The power a white sequence of unit variance has at each frequency in that scale (the
        period's length for a period's DFT, 2 / fs for Welch's one-sided density).
    """

    frequency_hz: np.ndarray
    response: np.ndarray
    coherence: np.ndarray
    averages: int
    window: str
    input_power: np.ndarray | None = None
    output_power: np.ndarray | None = None
    white_power: float | None = None


def hann_leakage(x):
    """The power a Hann window's spectrum of a tone puts ``x`` bins from it, relative to the
    tone's own bin: ``(sinc(x) / (1 - x^2))^2`` (0.72 at half a bin, 0.25 at one, 0.029 at
    1.5, 0 at 2, 5.9e-4 at 2.5)."""
    x = np.abs(np.asarray(x, float))
    with np.errstate(invalid="ignore", divide="ignore"):
        w = np.where(np.abs(x - 1.0) < 1e-9, 0.5, np.sinc(x) / (1.0 - x * x))
    return w * w


#: how far (lines) a line's power is compared with a stronger line's leakage (a Hann tone's
#: falls below 1e-9 of its peak beyond it)
LEAKAGE_REACH = 32
#: a line within this factor of the most a stronger line's leakage can put on it counts as
#: that leakage (the floating point of an exact half-line tone)
LEAKAGE_MARGIN = 1.05


def leakage_lines(suu) -> np.ndarray:
    """The lines of a Hann estimate whose input power a stronger line's leakage explains.

    A tone puts at most ``P_j / W(1/2) W(d - 1/2)`` on a line ``d >= 2`` lines from the line
    ``j`` it shows at with power ``P_j`` (:func:`hann_leakage` ``W``: the tone lies within half
    a line of ``j`` and its own power is at most ``P_j / W(1/2)``, Hann's scalloping), and the
    segments' leftover mean (the DC line, a source exactly on its line, whose one-sided
    density is not doubled) ``2 P_0 W(d)`` on line ``d``. A line at or below that (within
    :data:`LEAKAGE_MARGIN`) holds the stronger one's leakage: its H1 is that one's response,
    not one at its own frequency. A broadband input
    (noise, a chirp) has no line that far below another two lines off: nothing is dropped
    there."""
    p = np.asarray(suu, float)
    n = p.size
    drop = np.zeros(n, bool)
    for d in range(1, min(LEAKAGE_REACH, n - 1) + 1):
        if d >= 2:
            bound = LEAKAGE_MARGIN * float(hann_leakage(d - 0.5) / hann_leakage(0.5))
            drop[d:] |= p[d:] <= bound * p[:-d]  # below a stronger line d lines lower ...
            drop[:-d] |= p[:-d] <= bound * p[d:]  # ... or d lines higher
        drop[d] |= p[d] <= LEAKAGE_MARGIN * float(hann_leakage(d)) * 2.0 * p[0]  # a one-sided DC line is not doubled
    drop[0] = False
    return drop


def _finish(f, suu, syy, suy, averages, window, excited_db, band, lines=None, white=None) -> Spectrum:
    if not np.any(suu[f > 0] > 0):
        raise ValueError("the input is constant: nothing excites the response")
    if lines is None:
        keep = (f > 0) & (suu >= suu[f > 0].max() * 10 ** (-excited_db / 10))
        if window == "hann":  # a tone's Hann leakage into its neighbours is not their excitation
            keep &= ~leakage_lines(suu)
    else:
        keep = np.zeros(f.size, bool)
        keep[np.asarray(lines, int)] = True
        keep &= f > 0
    if band is not None:  # a band edge on a bin keeps it, whatever the digits of the log's times
        keep &= (f >= band[0] * (1 - 1e-6)) & (f <= band[1] * (1 + 1e-6))
    if not keep.any():
        raise LookupError("no excited frequency in the band")
    h = suy[keep] / suu[keep]
    with np.errstate(invalid="ignore", divide="ignore"):
        coh = np.abs(suy[keep]) ** 2 / (suu[keep] * syy[keep])
    coh = np.clip(np.nan_to_num(coh, nan=0.0), 0.0, 1.0)
    per = 1.0 if window == "hann" else 1.0 / averages  # Welch's densities are means already
    return Spectrum(f[keep], h, coh, int(averages), window, suu[keep] * per, syy[keep] * per, white)


def resolution_sd(spectrum: Spectrum, input_step: float = 0.0, output_step: float = 0.0) -> np.ndarray:
    """Standard deviation (nepers of magnitude, and radians of phase, alike) of an estimate's
    error at each frequency from signals logged in steps of ``input_step`` and
    ``output_step`` (their units; 0: not rounded).

    Rounding to a step ``q`` leaves an error uniform over one step, of variance ``q^2 / 12``,
    white when the signal crosses many steps (Widrow's model of quantisation). Under a
    periodic excitation the signal repeats each period, and so does its rounding error: the
    same in every spectrum averaged, it is not averaged down and the coherence does not see
    it (1). Its power at a frequency, over the signal's power there, is the relative error of
    the response: ``sqrt(white q^2 / (24 P))`` in each of its real and imaginary parts
    (``white`` the power of unit white noise, ``P`` the signal's, per spectrum); the input's
    and the output's add in power."""
    if spectrum.white_power is None:
        raise ValueError("the spectrum does not carry its powers")
    var = spectrum.white_power / 2.0 * ((input_step ** 2 / 12.0) / spectrum.input_power
                                        + (output_step ** 2 / 12.0) / spectrum.output_power)
    return np.sqrt(var)


def coherence_sd(coherence, averages: int) -> np.ndarray:
    """Standard deviation (nepers of magnitude, and radians of phase, alike) of an H1 estimate
    from ``averages`` spectra at each coherence: ``sqrt((1 - coh) / (2 averages coh))`` (Bendat
    and Piersol, Random Data, the random errors of frequency-response estimates; inf at zero
    coherence). The error is circular: its real and imaginary parts relative to the response
    are independent, each of this standard deviation."""
    c = np.clip(np.asarray(coherence, float), 0.0, 1.0)
    with np.errstate(divide="ignore"):
        return np.sqrt((1.0 - c) / (2.0 * averages * c))


def measured_phase(response, coherence, averages: int | None) -> np.ndarray:
    """The phase (rad) of an estimate at increasing frequencies, unwrapped along its
    well-measured lines and every other line on the branch nearest them.

    A line is well measured when the standard deviation of its phase (:func:`coherence_sd`
    of ``averages`` spectra, 1 when unknown) is at most :data:`UNWRAP_SD`: two neighbours
    then differ by a turn's fraction the noise cannot fake, and unwrapping them follows the
    response. A poorly coherent line's phase is noise of up to half a turn; unwrapped with
    the others it would shift every line after it by whole turns. It is put on the branch
    nearest the well-measured phase interpolated to it (the nearest one's, outside them).
    Without a well-measured line, every line is unwrapped in turn."""
    h = np.asarray(response, complex)
    raw = np.angle(h)
    good = np.flatnonzero(coherence_sd(coherence, averages or 1) <= UNWRAP_SD)
    if good.size == 0:
        return np.unwrap(raw)
    along = np.unwrap(raw[good])
    near = np.interp(np.arange(raw.size), good, along)
    phase = near + (raw - near + np.pi) % (2 * np.pi) - np.pi
    phase[good] = along
    return phase


def welch_segments(n: int, segment: int) -> int:
    """Half-overlapping segments of ``segment`` samples in ``n`` (what scipy.signal.welch
    averages)."""
    step = segment - segment // 2
    return (n - segment) // step + 1


def welch_h1(fs: float, u, y, segment: int, *, excited_db: float = EXCITED_DB, band=None) -> Spectrum:
    """H1 with Welch averaging: Hann windows of ``segment`` samples, half overlap.

    Parameters
    ----------
    fs : float
        Sample rate (Hz).
    u, y : array_like
        Input and output samples.
    segment : int
        Samples per segment (resolution fs / segment), at most half the samples.
    excited_db : float
        Frequencies whose input power is more than this below its peak are left out.
    band : (float, float), optional
        Keep frequencies in [lo, hi] Hz.

    Raises
    ------
    ValueError
        A constant input.
    LookupError
        No excited frequency in the band.
    """
    from scipy import signal
    u, y = np.asarray(u, float), np.asarray(y, float)
    kw = dict(fs=fs, window="hann", nperseg=segment, noverlap=segment // 2, detrend="constant")
    f, suu = signal.welch(u, **kw)
    _, syy = signal.welch(y, **kw)
    _, suy = signal.csd(u, y, **kw)
    return _finish(f, suu, syy, suy, welch_segments(u.size, segment), "hann", excited_db, band, white=2.0 / fs)


def below_lowest_line(fs: float, u, segment: int) -> tuple[float, float]:
    """``(share, median_hz)``: the share of the input's power (mean removed, the whole log's
    DFT) at frequencies below the lowest line ``fs / segment`` of Welch segments of
    ``segment`` samples, and the median frequency of that power (the lowest frequency up to
    which it holds half).

    A segment sees what lies below its lowest line as its mean and slow trend: its lines then
    hold the Hann window's leakage of it, not a response at their frequencies."""
    u = np.asarray(u, float) - float(np.mean(u))
    p = np.abs(np.fft.rfft(u)) ** 2
    f = np.fft.rfftfreq(u.size, 1.0 / fs)
    total = float(p[1:].sum())
    if not total > 0:
        return 0.0, 0.0
    share = float(p[1:][f[1:] < fs / segment * (1 - 1e-9)].sum()) / total
    median = float(f[1:][np.searchsorted(np.cumsum(p[1:]) / total, 0.5)])
    return share, median


def periodic_h1(fs: float, u, y, period: int, *, settle: int = 0, excited_db: float = EXCITED_DB,
                band=None, lines=None) -> Spectrum:
    """H1 from whole periods of a periodic excitation, rectangular window, no overlap.

    The last whole periods after ``settle`` of them are used (a partial period at the start
    is left out with the settling ones); each period's DFT is one spectrum.

    Parameters
    ----------
    fs : float
        Sample rate (Hz).
    u, y : array_like
        Input and output samples.
    period : int
        Samples per period (resolution fs / period).
    settle : int
        Periods left out at the start (transients).
    excited_db, band
        As :func:`welch_h1`.
    lines : array_like of int, optional
        Keep these bins of the period's DFT (the lines a multisine excites) instead of the
        bins whose input power is within ``excited_db`` of the peak.

    Raises
    ------
    ValueError
        Fewer than one period after the settling ones, or a constant input.
    LookupError
        No excited frequency in the band.
    """
    u, y = np.asarray(u, float), np.asarray(y, float)
    periods = u.size // period - settle
    if period < MIN_SEGMENT or periods < 1:
        raise ValueError(f"{u.size} samples hold {u.size // period} periods of {period}; {settle} settling "
                         "periods leave none to estimate from")
    start = u.size - periods * period
    uu = np.fft.rfft(u[start:].reshape(periods, period), axis=1)
    yy = np.fft.rfft(y[start:].reshape(periods, period), axis=1)
    f = np.fft.rfftfreq(period, 1.0 / fs)
    suu = np.sum(np.abs(uu) ** 2, axis=0)
    syy = np.sum(np.abs(yy) ** 2, axis=0)
    suy = np.sum(np.conj(uu) * yy, axis=0)
    return _finish(f, suu, syy, suy, periods, "periodic", excited_db, band, lines, white=float(period))


def response_csv(frequency_hz, gain_db, phase_deg, coherence, averages: int | None = None,
                 resolution_db=None, resolution_deg=None) -> str:
    """A frequency response as the CSV ``fit`` reads:
    ``frequency_hz,gain_db,phase_deg,coherence[,averages[,resolution_db,resolution_deg]]``
    (the coherence with all its digits: its distance from 1 sets the noise; the last two, the
    standard deviations of the gain and the phase that the logged signals' resolution leaves,
    with the number of spectra averaged)."""
    res = averages is not None and resolution_db is not None
    head = ("frequency_hz,gain_db,phase_deg,coherence" + (",averages" if averages is not None else "")
            + (",resolution_db,resolution_deg" if res else ""))
    tail = "" if averages is None else f",{int(averages):d}"
    rows = zip(frequency_hz, gain_db, phase_deg, coherence)
    lines = [head] + [f"{f:.9g},{g:.9g},{p:.9g},{c:.17g}{tail}" for f, g, p, c in rows]
    if res:
        lines[1:] = [f"{line},{rd:.6g},{rp:.6g}" for line, rd, rp in zip(lines[1:], resolution_db, resolution_deg)]
    return "\n".join(lines) + "\n"


def find_period(u, *, min_period: int = MIN_SEGMENT, tolerance: float = PERIODIC_TOLERANCE) -> int | None:
    """The shortest period (samples) with which ``u`` repeats, or None.

    A lag L is a period when the energy of ``u[L:] - u[:-L]`` is at most ``tolerance`` times
    that of the two parts (mean removed; 1 for unrelated parts, 0 for an exact repeat), is
    least there among its neighbouring lags, the signal holds at least two periods, and the
    signal does not nearly repeat at the shorter lags: over the lags 1 to L - 1 that relative
    difference averages at least :data:`REPEAT_MEAN` (a periodic signal's autocorrelation,
    its mean removed, averages zero over a period, so the difference averages 1 there). A
    slow, smooth signal differs little from itself over a few samples, and a signal held
    for some samples (a staircase) repeats its values: neither makes a short lag a period.
    """
    u = np.asarray(u, float) - float(np.mean(u))
    n = u.size
    power = float(u @ u)
    if n < 2 * min_period or not power > 0:
        return None
    last = n // 2 + 1  # one lag past the longest period two of which fit, to compare with its neighbour
    spec = np.fft.rfft(u, 2 * n)
    acf = np.fft.irfft(np.abs(spec) ** 2)[: last + 1]
    lags = np.arange(last + 1)
    energy = np.concatenate(([0.0], np.cumsum(u * u)))
    both = (power - energy[lags]) + energy[n - lags]  # of u[L:] and of u[:-L]
    with np.errstate(invalid="ignore", divide="ignore"):
        diff = np.where(both > 0, (both - 2.0 * acf) / both, 1.0)
    diff[0] = 0.0
    inner = diff[1:-1]
    dips = np.flatnonzero((inner <= tolerance) & (inner <= diff[:-2]) & (inner <= diff[2:])) + 1
    mean_below = np.cumsum(diff) / np.maximum(lags, 1)  # mean over the lags 1 .. L - 1, at index L - 1
    for L in dips[(dips >= min_period) & (dips <= n // 2)]:
        if mean_below[L - 1] >= REPEAT_MEAN:
            return int(L)
    return None


__all__ = ["EXCITED_DB", "LEAKAGE_MARGIN", "LEAKAGE_REACH", "LINES_KEY", "MIN_SEGMENT", "PERIOD_KEY", "RESOLUTION_PREFIX", "SETTLE_KEY", "Spectrum",
           "below_lowest_line", "coherence_sd", "find_period", "hann_leakage", "leakage_lines", "measured_phase", "periodic_h1", "resolution_sd",
           "response_csv", "welch_h1", "welch_segments"]
