"""Sine-dwell estimation: amplitude and phase of a signal at the drive frequency.

As MATLAB's sinestream: at each frequency the system is driven for a settling time
(discarded) and then ``estimation_cycles``; the fundamental is estimated by correlation
with exp(-j w t) over a whole number of cycles. On a uniform grid of ``n`` points per
window the correlation is a DFT bin: it rejects the mean and every harmonic below ``n``
exactly (they are orthogonal to the fundamental over whole cycles).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: correlation grid points per cycle (uniform resampling of the recorded trace)
GRID_PER_CYCLE = 200
#: fewest recorded samples per cycle accepted by :func:`fundamental`
MIN_RECORDS_PER_CYCLE = 16


@dataclass(frozen=True)
class DwellPlan:
    """How long to drive at one frequency.

    Parameters
    ----------
    settling_cycles : int
        Fewest cycles discarded while transients decay.
    estimation_cycles : int
        Cycles used for the correlation (at least 2: the two halves are compared).
    min_settling_time : float
        Settling time floor (s), so that slow closed-loop modes die out at high frequencies.
    settling_time_constants : float
        With a known slowest decay rate sigma (1/s) of the closed loop, the settling time is
        at least this many time constants 1/sigma (5: transients below 0.7 %).
    """

    settling_cycles: int = 4
    estimation_cycles: int = 4
    min_settling_time: float = 0.3
    settling_time_constants: float = 5.0

    def __post_init__(self):
        if self.settling_cycles < 0 or self.estimation_cycles < 2:
            raise ValueError("settling_cycles must be >= 0 and estimation_cycles >= 2")
        if self.min_settling_time < 0 or self.settling_time_constants < 0:
            raise ValueError("min_settling_time and settling_time_constants must be >= 0")

    def settling_time(self, decay_rate: float | None = None) -> float:
        """Settling time floor (s) given the slowest decay rate (1/s) of the loop, if known."""
        floor = self.min_settling_time
        if decay_rate is not None and decay_rate > 0:
            floor = max(floor, self.settling_time_constants / decay_rate)
        return floor

    def cycles(self, frequency_hz: float, decay_rate: float | None = None) -> tuple[int, int]:
        """(settling, estimation) whole cycles at a frequency."""
        if not frequency_hz > 0:
            raise ValueError(f"frequency must be positive, got {frequency_hz!r}")
        settle = max(self.settling_cycles, math.ceil(self.settling_time(decay_rate) * frequency_hz))
        return settle, self.estimation_cycles

    def duration(self, frequency_hz: float, decay_rate: float | None = None) -> float:
        """Total run time (s) at a frequency."""
        settle, est = self.cycles(frequency_hz, decay_rate)
        return (settle + est) / frequency_hz

    def to_dict(self) -> dict:
        """JSON-ready description."""
        return {"settling_cycles": self.settling_cycles, "estimation_cycles": self.estimation_cycles,
                "min_settling_time_s": self.min_settling_time,
                "settling_time_constants": self.settling_time_constants}


def fundamental(t, y, frequency_hz: float, t_start: float, cycles: int) -> complex:
    """Complex amplitude of ``y`` at ``frequency_hz`` over ``cycles`` whole cycles from ``t_start``.

    The recorded signal is resampled (linear interpolation) on a uniform grid of
    ``GRID_PER_CYCLE`` points per cycle, so that uneven solver steps do not bias the estimate.

    Parameters
    ----------
    t, y : array_like
        Record times (s, increasing) and values.
    frequency_hz : float
    t_start : float
        Start of the estimation window (s).
    cycles : int
        Whole cycles in the window.

    Returns
    -------
    complex
        The phasor ``Y`` of the fundamental written as a sine:
        ``y ~ mean + |Y| sin(w t + angle(Y)) + harmonics``.

    Raises
    ------
    ValueError
        Window outside the record, or fewer than ``MIN_RECORDS_PER_CYCLE`` records per cycle
        (linear interpolation would bias the amplitude).
    """
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    cycles = int(cycles)
    if not frequency_hz > 0 or cycles < 1:
        raise ValueError("frequency must be positive and cycles >= 1")
    period = 1.0 / frequency_hz
    t_end = t_start + cycles * period
    span = max(abs(t_end), 1.0) * 1e-9
    if t.size < 2 or t_start < t[0] - span or t_end > t[-1] + span:
        raise ValueError(f"estimation window [{t_start:.6g}, {t_end:.6g}] s is outside the record "
                         f"[{t[0] if t.size else math.nan:.6g}, {t[-1] if t.size else math.nan:.6g}] s")
    inside = np.count_nonzero((t >= t_start - span) & (t <= t_end + span))
    if inside < MIN_RECORDS_PER_CYCLE * cycles:
        raise ValueError(f"{inside} records over {cycles} cycles at {frequency_hz:.4g} Hz: need at least "
                         f"{MIN_RECORDS_PER_CYCLE} per cycle (record more densely)")
    n = cycles * GRID_PER_CYCLE
    grid = t_start + np.arange(n) * (cycles * period / n)
    yy = np.interp(grid, t, y)
    w = 2 * np.pi * frequency_hz
    c = 2.0 / n * np.sum(yy * np.exp(-1j * w * grid))
    # for y = A sin(w t + p) the correlation is A exp(j(p - pi/2)): rotate by +pi/2
    return complex(c * 1j)


def dwell_estimate(t, y, frequency_hz: float, settle_cycles: int, estimation_cycles: int):
    """Fundamental over the estimation cycles and how much it changed between their halves.

    Returns
    -------
    phasor : complex
        :func:`fundamental` over all estimation cycles after ``settle_cycles``.
    change : float
        ``|Y_first_half - Y_second_half| / |Y|`` (0 for a settled, periodic response; a
        large value flags unfinished transients or a non-periodic, e.g. chaotic, response).
    """
    t0 = settle_cycles / frequency_hz
    whole = fundamental(t, y, frequency_hz, t0, estimation_cycles)
    half = estimation_cycles // 2
    first = fundamental(t, y, frequency_hz, t0, half)
    second = fundamental(t, y, frequency_hz, t0 + (estimation_cycles - half) / frequency_hz, half)
    change = abs(first - second) / abs(whole) if abs(whole) > 0 else math.inf
    return whole, float(change)
