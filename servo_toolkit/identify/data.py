"""Measured data for identification: a frequency response or time traces, read from CSV.

Two kinds of CSV are read, told apart by their header:

``frequency_hz,gain_db,phase_deg[,coherence[,averages[,resolution_db,resolution_deg]]]``
    A measured frequency response; frequencies positive and strictly increasing, coherence
    (optional) in [0, 1], and the number of spectra averaged behind it (optional, a whole
    number >= 1, the same on every row: what ``frf`` writes), then the standard deviations
    of the gain and the phase that the logged signals' resolution leaves (optional, >= 0:
    what ``frf`` writes from a log with a resolution, an encoder's counts). Comment lines
    before the header may record that number instead (``# averages: N``, or ``# periods: N``
    for the periods of a multisine averaged); other comment lines are left alone.
``time_s,voltage_V,current_A,motor_angle_rad,output_angle_rad``
    Time traces of a rig driven by a voltage; times equally spaced and increasing.
``time_s,command_m,output_m,current_A`` (``_rad`` for an output angle)
    Time traces of the rig in closed loop: the position command of its loop, the measured
    output position (an encoder's) and the motor current; times equally spaced.

Every error names the file and the row (or the header) and the rule.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass

import numpy as np

from ..errors import SceneError
from ..core.inputs import read_input_text
from ..core.spectra import measured_phase
from ..display.cards import RichDisplay
from . import frequency_view
from .headers import FREQUENCY_HEADER, FREQUENCY_HEADERS, LOOP_HEADERS, TIME_HEADER, header_rule

#: nepers (and radians) to dB
DB_PER_NEPER = 20 / math.log(10)
#: largest data file read (bytes)
MAX_DATA_BYTES = 64 * 1024 * 1024


@dataclass(frozen=True, repr=False)
class FrequencyData(RichDisplay):
    """A measured frequency response; ``repr`` is one line, a notebook shows a card, and
    :meth:`to_dict` and :meth:`plot` give its JSON form and its Bode plot
    (:mod:`.frequency_view`).

    Attributes
    ----------
    frequency_hz, gain_db, phase_deg, coherence : numpy.ndarray
        One value per point; coherence is 1 where the file gives none.
    source : str or None
        The file it was read from.
    averages : int or None
        Spectra averaged behind the coherence (Welch segments or periods); None: unknown
        (the coherence then weighs nothing in the noise floor).
    window : str or None
        The estimator's window (``"periodic"`` or ``"hann"``), when known.
    resolution_db, resolution_deg : numpy.ndarray or None
        Standard deviations of the gain (dB) and the phase (deg) at each point that the
        logged signals' resolution leaves (an encoder's counts): an error that repeats in
        every spectrum averaged, which the coherence does not see; None: none known.
    signal : str or None
        The signal the response is to (its input the motor current), as a ``# signal: NAME``
        line before the header records it (``frf -o`` writes it: the output column, or its
        speed with ``--derivative``); None: not recorded.
    """

    frequency_hz: np.ndarray
    gain_db: np.ndarray
    phase_deg: np.ndarray
    coherence: np.ndarray
    source: str | None = None
    averages: int | None = None
    window: str | None = None
    resolution_db: np.ndarray | None = None
    resolution_deg: np.ndarray | None = None
    signal: str | None = None

    kind = "frequency"

    @property
    def points(self) -> int:
        """Number of frequencies."""
        return len(self.frequency_hz)

    @property
    def resolution_sd(self) -> np.ndarray | None:
        """The resolution's standard deviation of ``ln H`` at each point, nepers of magnitude
        and rad of phase alike (``resolution_db`` over :data:`DB_PER_NEPER`); None: none known."""
        if self.resolution_db is None:
            return None
        return np.asarray(self.resolution_db, float) / DB_PER_NEPER

    @property
    def complex(self) -> np.ndarray:
        """The response as complex numbers."""
        return 10 ** (self.gain_db / 20) * np.exp(1j * np.radians(self.phase_deg))

    def to_dict(self) -> dict:
        """JSON-ready (strict JSON), units in the key names: ``frequency_hz``, ``gain_db``,
        ``phase_deg``, ``coherence``, ``averages``, ``window``, ``signal``,
        ``resolution_db``, ``resolution_deg`` (None: not known), ``source``."""
        return frequency_view.to_dict(self)

    def plot(self, axes=None):
        """Bode plot (gain dB, phase deg against log frequency) and the coherence below, the
        lines of coherence under 0.8 marked; returns the three axes."""
        return frequency_view.plot(self, axes)

    def _repr_line(self) -> str:
        return frequency_view.repr_line(self)

    def _repr_card(self) -> str:
        return frequency_view.card_html(self)

    @classmethod
    def from_complex(cls, frequency_hz, response, coherence=None, source=None, averages=None,
                     window=None, resolution=None) -> "FrequencyData":
        """From complex values (e.g. a model's response); ``resolution``: the standard
        deviation (nepers, and radians alike) the logged signals' resolution leaves at each
        point. The phase is unwrapped along the frequencies; with a coherence, along the
        well-measured ones, the others on the branch nearest them
        (:func:`~servo_toolkit.core.spectra.measured_phase`)."""
        f = np.asarray(frequency_hz, float)
        h = np.asarray(response, complex)
        coh = np.ones_like(f) if coherence is None else np.asarray(coherence, float)
        res = None if resolution is None else np.asarray(resolution, float) * np.ones_like(f)
        phase = np.unwrap(np.angle(h)) if coherence is None else measured_phase(h, coh, averages)
        data = cls(f, 20 * np.log10(np.abs(h)), np.degrees(phase), coh, source,
                   None if averages is None else int(averages), window,
                   None if res is None else DB_PER_NEPER * res, None if res is None else np.degrees(res))
        check_frequency(data)
        return data


@dataclass(frozen=True)
class TimeData:
    """Measured time traces of a voltage-driven rig (angles relative to the start).

    Attributes
    ----------
    time_s, voltage_V, current_A, motor_angle_rad, output_angle_rad : numpy.ndarray
    source : str or None
    """

    time_s: np.ndarray
    voltage_V: np.ndarray
    current_A: np.ndarray
    motor_angle_rad: np.ndarray
    output_angle_rad: np.ndarray
    source: str | None = None

    kind = "time"

    @property
    def points(self) -> int:
        """Number of samples."""
        return len(self.time_s)


@dataclass(frozen=True)
class LoopData:
    """Measured time traces of a rig in closed loop.

    Attributes
    ----------
    time_s, command, output, current_A : numpy.ndarray
        Times (s), the loop's position command and the measured output position (m for an
        output travel, rad for an output angle), the motor current (A).
    unit : {"m", "rad"}
        Unit of the command and the output.
    source : str or None
    """

    time_s: np.ndarray
    command: np.ndarray
    output: np.ndarray
    current_A: np.ndarray
    unit: str = "m"
    source: str | None = None

    kind = "loop"

    @property
    def points(self) -> int:
        """Number of samples."""
        return len(self.time_s)


#: largest |gain| a measured response may have (dB): 1e15 either way, beyond any actuator's
#: response in any unit; a larger one is a slip (a column of another quantity), and its
#: linear gain 10**(g/20) would overflow the fit's residuals
MAX_GAIN_DB = 300.0


def check_frequency(data: FrequencyData) -> None:
    """Raise SceneError (row numbers count the header as row 1) unless the frequencies are
    positive and strictly increasing, the values finite, the gains within
    +-:data:`MAX_GAIN_DB` and the coherence in [0, 1]."""
    src = data.source
    for name in ("frequency_hz", "gain_db", "phase_deg", "coherence"):
        values = getattr(data, name)
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            raise SceneError(f"row {bad[0] + 2}", f"{name} must be a finite number", src)
    bad = np.flatnonzero(np.abs(data.gain_db) > MAX_GAIN_DB)
    if bad.size:
        raise SceneError(f"row {bad[0] + 2}", f"gain_db must lie within +-{MAX_GAIN_DB:g} dB, a gain of 1e15 "
                         f"either way (got {data.gain_db[bad[0]]:g} dB): no measured response has it", src)
    f = data.frequency_hz
    bad = np.flatnonzero(f <= 0)
    if bad.size:
        raise SceneError(f"row {bad[0] + 2}", f"frequency_hz must be positive (got {f[bad[0]]:g})", src)
    bad = np.flatnonzero(np.diff(f) <= 0)
    if bad.size:
        raise SceneError(f"row {bad[0] + 3}", f"frequency_hz must increase strictly from row to row "
                         f"({f[bad[0] + 1]:g} after {f[bad[0]]:g})", src)
    for name in ("resolution_db", "resolution_deg"):
        values = getattr(data, name)
        bad = np.flatnonzero(~(values >= 0) | ~np.isfinite(values)) if values is not None else []
        if len(bad):
            raise SceneError(f"row {bad[0] + 2}", f"{name} must be a finite standard deviation >= 0 "
                             f"(got {values[bad[0]]:g})", src)
    c = data.coherence
    bad = np.flatnonzero((c < 0) | (c > 1))
    if bad.size:
        raise SceneError(f"row {bad[0] + 2}", f"coherence must lie in [0, 1] (got {c[bad[0]]:g})", src)
    if data.averages is not None and not data.averages >= 1:
        raise SceneError("averages", f"must be a whole number >= 1 (got {data.averages})", src)


def check_time(data) -> None:
    """Raise SceneError unless the values are finite and the times increase equally spaced
    (time traces of either kind)."""
    src = data.source
    names = TIME_HEADER if isinstance(data, TimeData) else ("time_s", "command", "output", "current_A")
    for name in names:
        values = getattr(data, name)
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            raise SceneError(f"row {bad[0] + 2}", f"{name} must be a finite number", src)
    t = data.time_s
    if len(t) < 2:
        raise SceneError("time_s", "needs at least two samples", src)
    step = np.diff(t)
    bad = np.flatnonzero(step <= 0)
    if bad.size:
        raise SceneError(f"row {bad[0] + 3}", f"time_s must increase strictly from row to row ({t[bad[0] + 1]:.9g} "
                         f"after {t[bad[0]]:.9g}{': a duplicate' if t[bad[0] + 1] == t[bad[0]] else ''})", src)
    dt = step[0]
    bad = np.flatnonzero(np.abs(step - dt) > 1e-6 * dt + 1e-12)
    if bad.size:
        raise SceneError(f"row {bad[0] + 3}", f"time_s must be equally spaced (step {step[bad[0]]:g} s here, "
                         f"{dt:g} s from row 2 to row 3)", src)


def _averages(column, src) -> int:
    """The one whole number >= 1 of an ``averages`` column."""
    bad = np.flatnonzero(~np.isfinite(column) | (column < 1) | (column != np.round(column)))
    if bad.size:
        raise SceneError(f"row {bad[0] + 2}", f"averages must be a whole number >= 1 (got {column[bad[0]]:g})", src)
    bad = np.flatnonzero(column != column[0])
    if bad.size:
        raise SceneError(f"row {bad[0] + 2}", f"averages must be the same on every row ({column[bad[0]]:g} here, "
                         f"{column[0]:g} on row 2)", src)
    return int(column[0])


#: comment lines of a frequency response that record the number of spectra averaged
AVERAGES_KEYS = ("averages", "periods")


#: the comment line of a frequency response that names the signal it is the response to
SIGNAL_KEY = "signal"


def _comments(lines, src) -> tuple[int | None, str | None, list]:
    """What the comment lines before the header record: the number of spectra averaged
    (``# averages: N`` or ``# periods: N``; None: none), the signal the response is to
    (``# signal: NAME``; None: none), and the lines after them."""
    found, signal, k = None, None, 0
    while k < len(lines) and (not lines[k].strip() or lines[k].lstrip().startswith("#")):
        key, sep, value = lines[k].lstrip().lstrip("#").partition(":")
        key = key.strip().lower()
        if sep and key == SIGNAL_KEY:
            name = value.strip()
            if not name or (signal is not None and name != signal):
                raise SceneError(f"# {key}", f"must name one signal (got {name!r}"
                                 + (f" after {signal!r})" if signal is not None else ")"), src)
            signal = name
        if sep and key in AVERAGES_KEYS:
            try:
                n = int(value.strip())
            except ValueError:
                n = 0
            if n < 1:
                raise SceneError(f"# {key}", f"must be a whole number >= 1 (got {value.strip()!r})", src)
            if found is not None and n != found:
                raise SceneError(f"# {key}", f"{n} disagrees with the {found} recorded above", src)
            found = n
        k += 1
    return found, signal, lines[k:]


def read_data(path) -> FrequencyData | TimeData | LoopData:
    """Read a measured frequency response or time traces from CSV (kind from the header).

    Parameters
    ----------
    path : str or path-like

    Returns
    -------
    FrequencyData, TimeData or LoopData

    Raises
    ------
    SceneError
        Naming the file and the header or row, and the rule.
    """
    src = str(path)
    text = read_input_text(path, "(file)", MAX_DATA_BYTES, source=src, what="data")
    recorded, signal, lines = _comments(text.splitlines(), src)
    try:
        rows = [r for r in csv.reader(lines) if r and any(c.strip() for c in r)]
    except csv.Error as exc:  # e.g. a field larger than the csv module's field limit
        raise SceneError("(file)", f"cannot read data: not a CSV table ({exc})", src) from None
    expected = (f"{','.join(FREQUENCY_HEADER)}[,coherence[,averages[,resolution_db,resolution_deg]]], "
                f"{','.join(TIME_HEADER)} or "
                f"{','.join(LOOP_HEADERS['m'])} (_rad for an output angle)")
    if not rows:
        raise SceneError("header", f"empty file; expected the header {expected}", src)
    header = tuple(c.strip() for c in rows[0])
    loop_unit = next((u for u, h in LOOP_HEADERS.items() if h == header), None)
    if header in FREQUENCY_HEADERS:
        kind = "frequency"
    elif header == TIME_HEADER:
        kind = "time"
    elif loop_unit is not None:
        kind = "loop"
    else:
        raise SceneError("header", header_rule(header, expected), src)
    values = []
    for n, row in enumerate(rows[1:], start=2):
        if len(row) != len(header):
            raise SceneError(f"row {n}", f"expected {len(header)} values, got {len(row)}", src)
        try:
            values.append([float(c) for c in row])
        except ValueError:
            raise SceneError(f"row {n}", f"values must be numbers (got {','.join(row)!r})", src) from None
    if not values:
        raise SceneError("row 2", "no data rows after the header", src)
    cols = np.array(values, float).T
    if kind == "frequency":
        coh = cols[3] if len(header) >= 4 else np.ones(cols.shape[1])
        averages = _averages(cols[4], src) if len(header) >= 5 else recorded
        if recorded is not None and averages != recorded:
            raise SceneError("averages", f"the column's {averages} disagrees with the {recorded} the comment lines "
                             "record", src)
        res = (cols[5], cols[6]) if len(header) == 7 else (None, None)
        data = FrequencyData(cols[0], cols[1], cols[2], coh, src, averages, None, *res, signal=signal)
        check_frequency(data)
    elif kind == "time":
        data = TimeData(*cols, source=src)
        check_time(data)
    else:
        data = LoopData(*cols, unit=loop_unit, source=src)
        check_time(data)
    return data
