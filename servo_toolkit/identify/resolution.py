"""The resolution of a logged signal: the step its values are rounded to (an encoder's count,
an ADC's least significant bit), as the log records it or as its values show it.

A log may record it in a comment line before its header, per column, in the column's unit
(``# resolution_motor_angle_rad: 0.00153398078789``, what ``excite`` writes for the scene's
encoders). The recorded step is taken when the column's values lie on its grid (each within
:data:`ON_GRID` of a step from the first value, whatever offset the grid has), unless their
own smallest step is a larger one (a coarser sensor than recorded); values that do not lie on
it (a model's run, a filtered signal) are not rounded to it, and their own grid is looked for
instead. Without a recorded step, the step is the smallest difference between the
column's distinct values (refined over their span), taken when every value lies on its grid:
a signal that is not rounded has no such grid and no resolution.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

#: a value lies on a grid when within this share of a step of one of its points (the digits
#: a log writes its values with)
ON_GRID = 0.05
#: the rounding's model (an error uniform over a step, white: Widrow's) holds for a signal
#: whose RMS about its trend is at least this many steps; below it the error depends on the
#: signal's few levels (on periodic logs of the EMA rounded to half a step of RMS the margins'
#: intervals still held the truth in 45-50 of 50, at a quarter step in 26-38)
MIN_RMS_STEPS = 0.5
#: distinct values closer than this share of the column's span are one value written twice
#: with other digits (a finer step costs less than a millionth of the span's power)
SAME_VALUE = 1e-6


@dataclass(frozen=True)
class Resolution:
    """The step a column's values are rounded to.

    Attributes
    ----------
    column : str
        The log's column.
    step : float
        The step in the column's unit (0: not rounded, or not known).
    basis : str
        Where it comes from, as text (or why there is none).
    """

    column: str
    step: float
    basis: str
    rms_steps: float | None = None

    @property
    def coarse(self) -> bool:
        """The signal moves less than :data:`MIN_RMS_STEPS` steps RMS about its trend: the
        rounding's model, and the figures resting on it, do not describe it."""
        return self.rms_steps is not None and self.rms_steps < MIN_RMS_STEPS

    @property
    def unit(self) -> str:
        """The column's unit, the last part of its name (``motor_angle_rad`` -> ``rad``)."""
        return self.column.rsplit("_", 1)[-1] if "_" in self.column else ""

    def text(self) -> str:
        """One line: the column, its step with its unit and the basis."""
        if not self.step:
            return f"resolution of {self.column}: none ({self.basis})"
        line = f"resolution of {self.column}: {self.step:.6g} {self.unit}, {self.basis}"
        if self.coarse:
            line += (f"; its values move {self.rms_steps:.2g} steps RMS about their trend, under the "
                     f"{MIN_RMS_STEPS:g} the rounding's model (an error uniform over a step) needs: the error "
                     "figures resting on it may understate the rounding (a larger excitation moves the signal "
                     "over more steps)")
        return line

    def to_dict(self) -> dict:
        """The column, the step (``step`` in ``unit``; 0: none) and the basis."""
        return {"column": self.column, "step": self.step, "unit": self.unit, "basis": self.basis,
                "rms_steps": self.rms_steps, "coarse": self.coarse}


def on_grid(values, step: float) -> bool:
    """True when every value lies within :data:`ON_GRID` steps of a grid of ``step`` through
    the first value."""
    v = np.asarray(values, float)
    if not step > 0:
        return False
    r = (v - v[0]) / step
    return bool(np.all(np.abs(r - np.round(r)) <= ON_GRID))


def values_step(values) -> float:
    """The step of the grid ``values`` lie on: the smallest difference between their distinct
    values, refined over their span (0: they lie on none)."""
    v = np.unique(np.asarray(values, float))
    span = float(v[-1] - v[0]) if v.size else 0.0
    if not span > 0:
        return 0.0
    d = np.diff(v)
    d = d[d > SAME_VALUE * span]
    if not d.size:
        return 0.0
    step = span / round(span / float(d.min()))
    return step if on_grid(values, step) else 0.0


def rms_steps(values, step: float) -> float | None:
    """The RMS of ``values`` about their straight-line trend, in steps of ``step`` (None
    without a step)."""
    if not step > 0:
        return None
    v = np.asarray(values, float)
    x = np.arange(v.size, dtype=float)
    if v.size > 1:
        v = v - np.polyval(np.polyfit(x, v, 1), x)
    return float(np.sqrt(np.mean(v * v)) / step)


def column_resolution(values, column: str, recorded: float | None = None) -> Resolution:
    """The resolution of a log's column: the ``recorded`` step when the values lie on its
    grid, else the grid the values show, else none; with the values' RMS in steps."""
    found = _column_step(values, column, recorded)
    return replace(found, rms_steps=rms_steps(values, found.step))


def _column_step(values, column: str, recorded: float | None) -> Resolution:
    """:func:`column_resolution` without the RMS."""
    found = values_step(values)
    if recorded is not None and on_grid(values, recorded):
        if found > 1.5 * recorded:  # every value a whole number of steps apart: the sensor is coarser
            return Resolution(column, found, f"from its values' smallest step, {found / recorded:.3g} times the "
                              f"{recorded:.6g} the log records")
        return Resolution(column, float(recorded), "as the log records it")
    if recorded is not None:
        why = f"the log records steps of {recorded:.6g}, but its values do not lie on them"
        if found:
            return Resolution(column, found, f"from its values' smallest step ({why})")
        return Resolution(column, 0.0, f"{why} (a model's run, or a filtered signal), nor on any other grid")
    if found:
        return Resolution(column, found, "from its values' smallest step (the log records none)")
    return Resolution(column, 0.0, "the log records none and its values lie on no grid")


def log_resolution(log, column: str) -> Resolution:
    """The resolution of a column of a :class:`~.frf.TimeLog`: the step its comment lines
    record, checked against its values, else the one its values show
    (:func:`column_resolution`)."""
    return column_resolution(log.columns[column], column, log.resolutions.get(column))


__all__ = ["MIN_RMS_STEPS", "ON_GRID", "Resolution", "column_resolution", "log_resolution", "on_grid", "rms_steps",
           "values_step"]
