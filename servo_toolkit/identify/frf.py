"""Frequency response and coherence from time logs of a broadband excitation (chirp,
multisine, noise): the H1 estimator (:mod:`servo_toolkit.core.spectra`, which the simulated
multisine sweep uses too).

``H1(f) = P_uy(f) / P_uu(f)``, the cross spectrum of input and output over the input's own:
noise on the output averages out of it. The coherence ``|P_uy|^2 / (P_uu P_yy)`` says, per
frequency, how much of the output the input explains (1: all of it; noise, nonlinearity or
leakage lower it). Only the frequencies the input excites (power within
:data:`~servo_toolkit.core.spectra.EXCITED_DB` of its peak) are kept.

Two windows. ``periodic``: a periodic excitation (a multisine) is cut into whole periods,
each a rectangular window; every excited line falls on a bin, so the estimate has no
leakage and is exact for a periodic steady state; the first period is left out as settling
when the log holds three or more. ``hann``: Welch averaging of Hann-windowed,
half-overlapping segments, for noise and chirps; segments whose lowest line lies above most
of the input's power are refused (their lines would hold only its leakage). ``auto`` (the
default) takes ``periodic`` when the input repeats
(:func:`~servo_toolkit.core.spectra.find_period`: a real repeat, not a slow signal's
smoothness over a few samples), else ``hann``. The phase is unwrapped along the
well-measured lines, the poorly coherent ones on the branch nearest them.
The number of spectra averaged (periods or segments) goes with the estimate: the
coherence's random error depends on it.

A log is a CSV with a ``time_s`` column (equally spaced) and one column per signal, e.g.
``time_s,current_A,motor_angle_rad``; the traces ``simulate -o`` writes (time column
``t_s``, the run's last step possibly shorter: that sample is left out) read as logs too. The response of an angle's derivative (a speed, as the
``plant`` fit compares) is the angle's response times ``j 2 pi f``. Comment lines before the
header (``# KEY: VALUE``) may record the log's period in samples, the periods its response
settles over and the bins of the period's DFT its excitation excites (``# period_samples:
10000``, ``# settle_periods: 1``, ``# excited_bins: 2:65``, as ``excite`` writes them): they are
the periodic window's defaults, the bins estimated at those lines whatever the input's power
there (an excitation inside a loop reaches the input weakly where the loop's gain is high).
A comment line ``# resolution_COLUMN: STEP`` records the step a column's values are rounded
to (:mod:`.resolution`): the error that rounding leaves in the response goes with it
(:func:`~servo_toolkit.core.spectra.resolution_sd`).
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field

import numpy as np

from ..core.inputs import read_input_text
from ..core.spectra import (LINES_KEY, MIN_SEGMENT, PERIOD_KEY, RESOLUTION_PREFIX, SETTLE_KEY, below_lowest_line,
                             find_period, periodic_h1, resolution_sd, response_csv, welch_h1)
from ..errors import SceneError
from .data import MAX_DATA_BYTES, FrequencyData
from .headers import TIME_COLUMNS

#: fewest Welch segments the default segment length gives
DEFAULT_AVERAGES = 8
#: largest deviation of a time step from the mean step (relative)
SPACING_TOLERANCE = 0.01
#: the windows ``estimate_frf`` offers
WINDOWS = ("auto", "periodic", "hann")
#: a periodic log with at least this many periods leaves its first one out as settling
SETTLE_FROM = 3
#: largest share of the input's power below the lowest line of Hann segments
UNRESOLVED_SHARE = 0.5


@dataclass(frozen=True)
class TimeLog:
    """A time log as :func:`read_time_log` reads it.

    Attributes
    ----------
    time_s : numpy.ndarray
        Equally spaced sample times (s).
    columns : dict of str to numpy.ndarray
        Every signal by its column name (the time column left out).
    time_column : str
        ``time_s``, or ``t_s`` (the traces ``simulate -o`` writes).
    notes : tuple of str
        What was done to the log (a run's last, shorter step left out).
    period_samples, settle_periods : int or None
        The period and the settling periods its comment lines record (None: not recorded).
    excited_bins : (int, int) or None
        The first and last bin of the period's DFT the excitation excites, as recorded.
    resolutions : dict of str to float
        The step each column's values are rounded to, as recorded (``# resolution_COLUMN:
        STEP``, in the column's unit).
    """

    time_s: np.ndarray
    columns: dict
    time_column: str = "time_s"
    notes: tuple = ()
    period_samples: int | None = None
    settle_periods: int | None = None
    excited_bins: tuple | None = None
    resolutions: dict = field(default_factory=dict)


def _recorded(lines, src) -> tuple[dict, list]:
    """The ``# KEY: VALUE`` comment lines before the header: whole numbers for
    :data:`PERIOD_KEY` and :data:`SETTLE_KEY`, ``FIRST:LAST`` bins for :data:`LINES_KEY` (other
    comments are left alone), and the lines after them."""
    found, k = {}, 0
    while k < len(lines) and (not lines[k].strip() or lines[k].lstrip().startswith("#")):
        key, sep, value = lines[k].lstrip().lstrip("#").partition(":")
        key = key.strip()
        if sep and key == LINES_KEY:
            first, colon, last = value.strip().partition(":")
            try:
                found[key] = (int(first), int(last))
            except ValueError:
                found[key] = None
            if not colon or found[key] is None or not 1 <= found[key][0] <= found[key][1]:
                raise SceneError(f"# {key}", f"must be FIRST:LAST, whole bins with 1 <= FIRST <= LAST (got "
                                 f"{value.strip()!r})", src)
        elif sep and key.startswith(RESOLUTION_PREFIX):
            try:
                step = float(value.strip())
            except ValueError:
                step = math.nan
            if not (math.isfinite(step) and step > 0):
                raise SceneError(f"# {key}", f"must be the positive step the column's values are rounded to, in its "
                                 f"unit (got {value.strip()!r})", src)
            found.setdefault("resolutions", {})[key[len(RESOLUTION_PREFIX):]] = step
        elif sep and key in (PERIOD_KEY, SETTLE_KEY):
            try:
                found[key] = int(value.strip())
            except ValueError:
                raise SceneError(f"# {key}", f"must be a whole number (got {value.strip()!r})", src) from None
            if found[key] < (MIN_SEGMENT if key == PERIOD_KEY else 0):
                raise SceneError(f"# {key}", f"must be at least {MIN_SEGMENT if key == PERIOD_KEY else 0} "
                                 f"(got {found[key]})", src)
        k += 1
    return found, lines[k:]


def _uneven(t) -> np.ndarray:
    """Indices of the steps of ``t`` that are not positive or depart from the mean step by
    more than :data:`SPACING_TOLERANCE` (times written with few digits)."""
    step = np.diff(t)
    dt = (t[-1] - t[0]) / (t.size - 1)
    return np.flatnonzero((step <= 0) | (np.abs(step - dt) > SPACING_TOLERANCE * dt))


def read_time_log(path) -> TimeLog:
    """Time and signals of a log CSV (header ``time_s,NAME,...``, or ``t_s,NAME,...`` as
    ``simulate -o`` writes its traces).

    A run stops at its final time, so its last step may be shorter than the others: that one
    last sample is left out, with a note; any other uneven step is refused. Comment lines
    before the header (``# period_samples: N``, ``# settle_periods: K``) record the period
    and the settling periods (:class:`TimeLog`).

    Raises
    ------
    SceneError
        Naming the file and the header or row: no time column (``time_s`` or ``t_s``), a
        value that is not a finite number, times not increasing equally spaced, fewer than
        2 * MIN_SEGMENT rows; a recorded period or settling count that is not a whole number,
        or that does not fit the log.
    """
    src = str(path)
    text = read_input_text(path, "(file)", MAX_DATA_BYTES, source=src, what="log")
    recorded, lines = _recorded(text.splitlines(), src)
    try:
        rows = [r for r in csv.reader(lines) if r and any(c.strip() for c in r)]
    except csv.Error as exc:
        raise SceneError("(file)", f"cannot read the log: not a CSV table ({exc})", src) from None
    if not rows:
        raise SceneError("header", "empty file; expected a header time_s,SIGNAL,...", src)
    header = [c.strip() for c in rows[0]]
    times = [c for c in TIME_COLUMNS if c in header]
    other_unit = next((c for c in header if c.lower().startswith(("time_", "t_")) and c not in TIME_COLUMNS), None)
    if not times and other_unit is not None:
        raise SceneError("header", f"column {header.index(other_unit) + 1} is {other_unit!r}: the time must be in s "
                         f"(time_s, or t_s as simulate -o writes)", src)
    if len(times) != 1 or len(header) < 3 or len(set(header)) != len(header):
        raise SceneError("header", "expected one time column (time_s, or t_s as simulate -o writes) and at least "
                         f"two distinct signal names, got {','.join(header)!r}", src)
    values = []
    for n, row in enumerate(rows[1:], start=2):
        if len(row) != len(header):
            raise SceneError(f"row {n}", f"expected {len(header)} values, got {len(row)}", src)
        try:
            v = [float(c) for c in row]
        except ValueError:
            raise SceneError(f"row {n}", f"values must be numbers (got {','.join(row)!r})", src) from None
        if not all(math.isfinite(x) for x in v):
            name = next(h for h, x in zip(header, v) if not math.isfinite(x))
            raise SceneError(f"row {n}", f"{name} must be a finite number (got {row[header.index(name)].strip()})", src)
        values.append(v)
    if len(values) < 2 * MIN_SEGMENT:
        raise SceneError("(data)", f"{len(values)} rows; a spectrum needs at least {2 * MIN_SEGMENT}", src)
    cols = np.array(values, float).T
    columns = dict(zip(header, cols))
    column = times[0]
    t = columns.pop(column)
    notes = []
    bad = _uneven(t)
    if bad.size and t.size > 2 * MIN_SEGMENT and not _uneven(t[:-1]).size:
        rest = (t[-2] - t[0]) / (t.size - 2)
        last = t[-1] - t[-2]
        if 0 < last < rest:  # every step but the last even, the last shorter: a run's final step
            notes.append(f"left out the last sample (t = {t[-1]:.6g} s): its step {last:.4g} s is shorter than the "
                         f"log's {rest:.4g} s (a run stopping at its final time)")
            t = t[:-1]
            columns = {k: v[:-1] for k, v in columns.items()}
            bad = bad[:0]
    if bad.size:
        step = np.diff(t)
        dt = (t[-1] - t[0]) / (t.size - 1)
        raise SceneError(f"row {bad[0] + 3}", f"{column} must increase equally spaced, every step within "
                         f"{SPACING_TOLERANCE:.0%} of the mean {dt:.4g} s (step {step[bad[0]]:.4g} s; only a last, "
                         "shorter step is left out)", src)
    period, settle, bins = recorded.get(PERIOD_KEY), recorded.get(SETTLE_KEY), recorded.get(LINES_KEY)
    if bins is not None and (period is None or bins[1] >= period / 2):
        raise SceneError(f"# {LINES_KEY}", f"needs # {PERIOD_KEY} and bins below half of it (got {bins[0]}:{bins[1]}"
                         + (f" for a period of {period})" if period is not None else ")"), src)
    if period is not None and period > t.size:
        raise SceneError(f"# {PERIOD_KEY}", f"{period} samples is longer than the log's {t.size} rows", src)
    if settle is not None and period is not None and settle >= t.size // period:
        raise SceneError(f"# {SETTLE_KEY}", f"must leave at least one of the log's {t.size // period} whole periods "
                         f"(got {settle})", src)
    return TimeLog(t, columns, column, tuple(notes), period, settle, bins, recorded.get("resolutions", {}))


def read_log(path) -> tuple[np.ndarray, dict]:
    """Time and signals of a log CSV: ``(time_s, columns)`` of :func:`read_time_log`."""
    log = read_time_log(path)
    return log.time_s, log.columns


def _varies(x) -> bool:
    """True when ``x`` changes by more than 1e-12 of its size (rounding of a constant does not)."""
    return bool(np.ptp(x) > 1e-12 * max(float(np.max(np.abs(x))), np.finfo(float).tiny))


def _check_resolved(fs: float, u, segment: int, source) -> None:
    """Refuse Hann segments of ``segment`` samples whose lowest line lies above most of the
    input's power (:data:`UNRESOLVED_SHARE`): their lines would hold only the window's
    leakage of it, at frequencies the input does not excite."""
    share, median = below_lowest_line(fs, u, segment)
    if share <= UNRESOLVED_SHARE:
        return
    need = max(MIN_SEGMENT, math.ceil(fs / median * (1 - 1e-9)))
    n = np.asarray(u).size
    fix = (f"give --segment {need} or more (at most {n // 2})" if need <= n // 2 else
           f"segments would need {need} samples, more than half the log's {n}: record a longer log, or give a "
           "periodic input's whole periods to --window periodic --period N")
    raise SceneError("--segment", f"{share:.0%} of the input's power lies below the lowest line of {segment}-sample "
                     f"Hann segments ({fs / segment:.4g} Hz; its median frequency {median:.4g} Hz): the segments "
                     f"cannot resolve it and their lines would hold only its leakage; {fix}", source)


def estimate_frf(time_s, u, y, *, window: str = "auto", segment: int | None = None, period: int | None = None,
                 settle: int | None = None, band=None, derivative: bool = False,
                 source: str | None = None, lines=None, resolution=None) -> FrequencyData:
    """H1 estimate of the response y / u, with its coherence.

    Parameters
    ----------
    time_s : array_like
        Equally spaced sample times (s).
    u, y : array_like
        Input (the excitation: a current, a voltage, a command) and output samples.
    window : {"auto", "periodic", "hann"}
        ``periodic``: whole periods of a periodic input, rectangular windows; ``hann``:
        Welch averaging; ``auto``: periodic when the input repeats, else hann.
    segment : int, optional
        Hann: samples per Welch segment (frequency resolution 1 / (segment dt)); default the
        largest power of two giving at least :data:`DEFAULT_AVERAGES` segments.
    period : int, optional
        Periodic: samples per period; default the period the input repeats with.
    settle : int, optional
        Periodic: periods left out at the start; default 1 when the log holds at least
        :data:`SETTLE_FROM`, else 0.
    band : (float, float), optional
        Keep frequencies in [lo, hi] Hz; default every excited frequency.
    derivative : bool
        Return the response of dy/dt (``j 2 pi f`` times that of y): an angle log gives the
        speed response.
    source : str, optional
        Where the log came from (kept with the data).
    lines : array_like of int, optional
        Periodic: the bins of the period's DFT to estimate at (the excitation's lines), in
        place of those whose input power is within
        :data:`~servo_toolkit.core.spectra.EXCITED_DB` of its peak.
    resolution : (float, float), optional
        The steps the input's and the output's values are rounded to (their units; 0: not
        rounded), e.g. from :func:`~.resolution.column_resolution`: the standard deviation
        of the error their rounding leaves goes with the estimate
        (:func:`~servo_toolkit.core.spectra.resolution_sd`, the same for the derivative's)
        when the input repeats (the rounding then repeats with it, unseen by the coherence;
        a Hann estimate of an input that does not repeat sees it in its coherence).

    Returns
    -------
    FrequencyData
        Frequencies, gain, phase and coherence of the excited bins, the number of spectra
        averaged and the window.

    Raises
    ------
    SceneError
        A segment shorter than :data:`~servo_toolkit.core.spectra.MIN_SEGMENT` or longer
        than half the log, or whose lowest line lies above more than
        :data:`UNRESOLVED_SHARE` of the input's power, ``periodic`` on an input that does not repeat (or a period that
        leaves no whole one), an option of the other window, a constant input (no
        excitation) or output (no response), a band that keeps no frequency.
    """
    t = np.asarray(time_s, float)
    u = np.asarray(u, float)
    y = np.asarray(y, float)
    for key, x, what in (("--input", u, "nothing excites the response"), ("--output", y, "nothing responds: its "
                         "gain would be zero (-inf dB) at every frequency")):
        if not _varies(x):
            raise SceneError(key, f"the signal is constant ({x[0]:g} throughout, to 1e-12 of its size): {what}",
                             source)
    n = t.size
    fs = (n - 1) / float(t[-1] - t[0])
    if window not in WINDOWS:
        raise SceneError("--window", f"must be one of {', '.join(WINDOWS)} (got {window!r})", source)
    if window == "auto":
        window = "hann" if segment is not None or (period is None and find_period(u) is None) else "periodic"
    try:
        if window == "periodic":
            if segment is not None:
                raise SceneError("--segment", "applies to the hann window; a periodic log is cut into its periods",
                                 source)
            if period is None:
                period = find_period(u)
                if period is None:
                    raise SceneError("--window", "periodic needs an input that repeats (none found: give --period "
                                     "or --window hann)", source)
            if not MIN_SEGMENT <= period <= n:
                raise SceneError("--period", f"must lie in [{MIN_SEGMENT}, {n}] samples for a log of {n} "
                                 f"(got {period})", source)
            whole = n // period
            settle = (1 if whole >= SETTLE_FROM else 0) if settle is None else settle
            if not 0 <= settle < whole:
                raise SceneError("--settle", f"must leave at least one of the log's {whole} whole periods "
                                 f"(got {settle})", source)
            spec = periodic_h1(fs, u, y, period, settle=settle, band=band, lines=lines)
        else:
            if period is not None or settle is not None:
                raise SceneError("--period" if period is not None else "--settle",
                                 "applies to the periodic window", source)
            if segment is None:
                segment = max(MIN_SEGMENT, 2 ** int(math.floor(math.log2(max(n // DEFAULT_AVERAGES, 1)))))
            if not MIN_SEGMENT <= segment <= n // 2:
                raise SceneError("--segment", f"must lie in [{MIN_SEGMENT}, {n // 2}] samples for a log of {n} "
                                 f"(got {segment})", source)
            _check_resolved(fs, u, segment, source)
            spec = welch_h1(fs, u, y, segment, band=band)
    except LookupError:
        raise SceneError("--band", "keeps no excited frequency of the log", source) from None
    except ValueError as exc:
        if isinstance(exc, SceneError):
            raise
        raise SceneError("--input", f"{exc}", source) from None
    fk, h = spec.frequency_hz, spec.response
    if derivative:
        h = h * 2j * math.pi * fk
    h = np.where(h == 0, 1e-300, h)
    # the rounding repeats when the log does; a Hann estimate of an input that does not repeat
    # sees it change from segment to segment, in its coherence
    repeats = spec.window == "periodic" or find_period(u) is not None
    res = None if resolution is None or not any(resolution) or not repeats else resolution_sd(spec, *resolution)
    return FrequencyData.from_complex(fk, h, coherence=spec.coherence, source=source, averages=spec.averages,
                                      window=spec.window, resolution=res)


#: the speed whose response ``--derivative`` gives, per angle or travel column
SPEEDS = {"motor_angle_rad": "motor_speed_rad_s", "output_angle_rad": "output_speed_rad_s",
          "output_travel_m": "output_speed_m_s"}


def response_signal(output: str, derivative: bool) -> str:
    """The signal a response to the log's column ``output`` is to: the column itself, or with
    ``derivative`` its speed (:data:`SPEEDS`; ``d(COLUMN)/dt`` for another column). ``frf -o``
    records it in a ``# signal: NAME`` line, which ``--plant-frf`` reads."""
    if not derivative:
        return output
    return SPEEDS.get(output, f"d({output})/dt")


def frf_csv(data: FrequencyData) -> str:
    """The CSV that ``fit`` reads: ``frequency_hz,gain_db,phase_deg,coherence,averages`` (the
    last column when the number of spectra averaged is known), then
    ``resolution_db,resolution_deg`` when the logged signals' resolution is known."""
    return response_csv(data.frequency_hz, data.gain_db, data.phase_deg, data.coherence, data.averages,
                        data.resolution_db, data.resolution_deg)
