"""Frequency response and coherence from time logs of a broadband excitation (chirp,
multisine, noise): the H1 estimator with Welch averaging.

``H1(f) = P_uy(f) / P_uu(f)``, the cross spectrum of input and output over the input's own
(scipy.signal.csd and welch, Hann windows, half-overlapping segments, means removed): noise
on the output averages out of it. The coherence ``|P_uy|^2 / (P_uu P_yy)`` says, per
frequency, how much of the output the input explains (1: all of it; noise, nonlinearity or
leakage lower it). Only the frequencies the input excites (power within
:data:`EXCITED_DB` of its peak) are kept.

A log is a CSV with a ``time_s`` column (equally spaced) and one column per signal, e.g.
``time_s,current_A,motor_angle_rad``. The response of an angle's derivative (a speed, as the
``plant`` fit compares) is the angle's response times ``j 2 pi f``.
"""

from __future__ import annotations

import csv
import math

import numpy as np
from scipy import signal

from ..core.inputs import read_input_text
from ..errors import SceneError
from .data import MAX_DATA_BYTES, FrequencyData

#: input power below its peak (dB) under which a frequency counts as not excited
EXCITED_DB = 40.0
#: fewest Welch segments the default segment length gives
DEFAULT_AVERAGES = 8
#: largest deviation of a time step from the mean step (relative)
SPACING_TOLERANCE = 0.01
#: shortest segment (samples)
MIN_SEGMENT = 16


def read_log(path) -> tuple[np.ndarray, dict]:
    """Time and signals of a log CSV (header ``time_s,NAME,...``).

    Returns
    -------
    time_s : numpy.ndarray
    columns : dict of str to numpy.ndarray

    Raises
    ------
    SceneError
        Naming the file and the header or row: no ``time_s`` column, a value that is not a
        finite number, times not increasing equally spaced, fewer than 2 * MIN_SEGMENT rows.
    """
    src = str(path)
    text = read_input_text(path, "(file)", MAX_DATA_BYTES, source=src, what="log")
    try:
        rows = [r for r in csv.reader(text.splitlines()) if r and any(c.strip() for c in r)]
    except csv.Error as exc:
        raise SceneError("(file)", f"cannot read the log: not a CSV table ({exc})", src) from None
    if not rows:
        raise SceneError("header", "empty file; expected a header time_s,SIGNAL,...", src)
    header = [c.strip() for c in rows[0]]
    if "time_s" not in header or len(header) < 3 or len(set(header)) != len(header):
        raise SceneError("header", f"expected time_s and at least two distinct signal names, got {','.join(header)!r}",
                         src)
    values = []
    for n, row in enumerate(rows[1:], start=2):
        if len(row) != len(header):
            raise SceneError(f"row {n}", f"expected {len(header)} values, got {len(row)}", src)
        try:
            v = [float(c) for c in row]
        except ValueError:
            raise SceneError(f"row {n}", f"values must be numbers (got {','.join(row)!r})", src) from None
        if not all(math.isfinite(x) for x in v):
            raise SceneError(f"row {n}", "values must be finite numbers", src)
        values.append(v)
    if len(values) < 2 * MIN_SEGMENT:
        raise SceneError("(data)", f"{len(values)} rows; a spectrum needs at least {2 * MIN_SEGMENT}", src)
    cols = np.array(values, float).T
    columns = dict(zip(header, cols))
    t = columns.pop("time_s")
    step = np.diff(t)
    dt = (t[-1] - t[0]) / (t.size - 1)  # times written with few digits: each step within 1 % of the mean
    bad = np.flatnonzero((step <= 0) | (np.abs(step - dt) > SPACING_TOLERANCE * dt))
    if bad.size:
        raise SceneError(f"row {bad[0] + 3}", "time_s must increase equally spaced", src)
    return t, columns


def estimate_frf(time_s, u, y, *, segment: int | None = None, band=None, derivative: bool = False,
                 source: str | None = None) -> FrequencyData:
    """H1 estimate of the response y / u, with its coherence.

    Parameters
    ----------
    time_s : array_like
        Equally spaced sample times (s).
    u, y : array_like
        Input (the excitation: a current, a voltage, a command) and output samples.
    segment : int, optional
        Samples per Welch segment (frequency resolution 1 / (segment dt)); default the
        largest power of two giving at least :data:`DEFAULT_AVERAGES` segments.
    band : (float, float), optional
        Keep frequencies in [lo, hi] Hz; default every excited frequency.
    derivative : bool
        Return the response of dy/dt (``j 2 pi f`` times that of y): an angle log gives the
        speed response.
    source : str, optional
        Where the log came from (kept with the data).

    Returns
    -------
    FrequencyData
        Frequencies, gain, phase and coherence of the excited bins.

    Raises
    ------
    SceneError
        A segment shorter than :data:`MIN_SEGMENT` or longer than half the log, an input
        without excitation, a band that keeps no frequency.
    """
    t = np.asarray(time_s, float)
    u = np.asarray(u, float)
    y = np.asarray(y, float)
    n = t.size
    fs = (t.size - 1) / float(t[-1] - t[0])
    if segment is None:
        segment = max(MIN_SEGMENT, 2 ** int(math.floor(math.log2(max(n // DEFAULT_AVERAGES, 1)))))
    if not MIN_SEGMENT <= segment <= n // 2:
        raise SceneError("--segment", f"must lie in [{MIN_SEGMENT}, {n // 2}] samples for a log of {n} "
                         f"(got {segment})", source)
    kw = dict(fs=fs, window="hann", nperseg=segment, noverlap=segment // 2, detrend="constant")
    f, puu = signal.welch(u, **kw)
    _, pyy = signal.welch(y, **kw)
    _, puy = signal.csd(u, y, **kw)
    if not np.any(puu > 0):
        raise SceneError("--input", "the input is constant: nothing excites the response", source)
    keep = (f > 0) & (puu >= puu.max() * 10 ** (-EXCITED_DB / 10))
    if band is not None:
        keep &= (f >= band[0]) & (f <= band[1])
    if not keep.any():
        raise SceneError("--band", "keeps no excited frequency of the log", source)
    h = puy[keep] / puu[keep]
    with np.errstate(invalid="ignore", divide="ignore"):
        coh = np.abs(puy[keep]) ** 2 / (puu[keep] * pyy[keep])
    coh = np.clip(np.nan_to_num(coh, nan=0.0), 0.0, 1.0)
    fk = f[keep]
    if derivative:
        h = h * 2j * math.pi * fk
    h = np.where(h == 0, 1e-300, h)
    return FrequencyData.from_complex(fk, h, coherence=coh, source=source)


def frf_csv(data: FrequencyData) -> str:
    """The CSV that ``fit`` reads: ``frequency_hz,gain_db,phase_deg,coherence``."""
    lines = ["frequency_hz,gain_db,phase_deg,coherence"]
    lines += [f"{f:.9g},{g:.9g},{p:.9g},{c:.6g}" for f, g, p, c in
              zip(data.frequency_hz, data.gain_db, data.phase_deg, data.coherence)]
    return "\n".join(lines) + "\n"
