"""A sampled position command packed for the kernel: checked samples, the slopes of the cubic
spline through them and a fingerprint (:func:`pack_table`; the kernel side is
``servo_toolkit/_physics/command.h``, the slots ``REF_TAB_*`` of
:mod:`servo_toolkit.sim.layout`).

The interpolant is the cubic spline through the samples (not-a-knot ends; periodic for a
periodic table), written as a cubic Hermite interpolant with the spline's slopes at the
samples: its value, slope and curvature are continuous, and the kernel evaluates r, r' and
r'' exactly (what the model-based feedforward needs).
"""

from __future__ import annotations

import hashlib

import numpy as np
from scipy.interpolate import CubicSpline

from ..errors import SceneError

#: fewest samples of a table (a cubic needs four)
MIN_SAMPLES = 4
#: most samples of a table (they are copied into every run's parameters)
MAX_SAMPLES = 10_000_000
#: largest deviation of a time step from the first step (relative)
SPACING_TOLERANCE = 1e-6


def check_samples(time_s, values, *, periodic: bool = False) -> tuple[float, float, np.ndarray]:
    """The start (s), the spacing (s) and the values of a table, checked.

    Parameters
    ----------
    time_s : array_like
        Sample times (s): strictly increasing, equally spaced.
    values : array_like
        The command at those times (rad, or m for an output travel), finite.
    periodic : bool
        The samples are one period; the command repeats after ``len(values)`` spacings.

    Raises
    ------
    SceneError
        Naming ``time_s`` or ``values`` (and the sample) and the rule: fewer than
        :data:`MIN_SAMPLES` samples, lengths that differ, a value that is not finite, times
        that do not increase equally spaced.
    """
    t = np.asarray(time_s, float).reshape(-1)
    v = np.asarray(values, float).reshape(-1)
    if t.size != v.size:
        raise SceneError("values", f"{v.size} values for {t.size} times: one value per time")
    if not MIN_SAMPLES <= t.size <= MAX_SAMPLES:
        raise SceneError("time_s", f"a command table needs {MIN_SAMPLES} to {MAX_SAMPLES} samples (got {t.size})")
    for name, arr in (("time_s", t), ("values", v)):
        bad = np.flatnonzero(~np.isfinite(arr))
        if bad.size:
            raise SceneError(name, f"sample {bad[0]} is not a finite number ({arr[bad[0]]})")
    step = np.diff(t)
    bad = np.flatnonzero(step <= 0)
    if bad.size:
        k = int(bad[0]) + 1
        raise SceneError("time_s", f"times must increase strictly (sample {k}: {t[k]:.9g} s after {t[k - 1]:.9g} s)")
    dt = float(step[0])
    bad = np.flatnonzero(np.abs(step - dt) > SPACING_TOLERANCE * dt)
    if bad.size:
        k = int(bad[0]) + 1
        raise SceneError("time_s", f"times must be equally spaced (step {step[bad[0]]:.9g} s before sample {k}, "
                         f"{dt:.9g} s before sample 1)")
    return float(t[0]), float((t[-1] - t[0]) / (t.size - 1)), v


def pack_table(time_s, values, *, periodic: bool = False) -> tuple[float, float, np.ndarray, float]:
    """Start, spacing, packed data and fingerprint of a table.

    Returns
    -------
    t0, step : float
        Time of the first sample and the spacing (s).
    data : numpy.ndarray
        The values, then the spline's slopes at them (per second); a periodic table gets its
        first sample repeated at the end (length 2 (n + 1)).
    fingerprint : float
        A 48-bit hash of the data, start, spacing and periodicity (an integer exact in a
        float): equal fingerprints mean equal commands.
    """
    t0, step, v = check_samples(time_s, values, periodic=periodic)
    knots = t0 + step * np.arange(v.size + (1 if periodic else 0))
    y = np.append(v, v[0]) if periodic else v
    spline = CubicSpline(knots, y, bc_type="periodic" if periodic else "not-a-knot")
    data = np.concatenate([y, spline(knots, 1)])
    digest = hashlib.blake2b(data.tobytes() + np.array([t0, step, float(periodic)]).tobytes(), digest_size=6)
    return t0, step, data, float(int.from_bytes(digest.digest(), "big"))


def table_span(data: np.ndarray) -> tuple[float, float]:
    """Smallest and largest sample of packed ``data``."""
    y = data[: data.size // 2]
    return float(np.min(y)), float(np.max(y))


def duration_of(n: int, step: float, periodic: bool) -> float:
    """Time a table covers (s): its period, or from its first sample to its last."""
    return step * (n if periodic else n - 1)


__all__ = ["MIN_SAMPLES", "check_samples", "duration_of", "pack_table", "table_span"]
