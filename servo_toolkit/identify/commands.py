"""The position command of a closed-loop log as a command the compiled simulation follows.

The simulation evaluates its command inside the kernel (:class:`servo_toolkit.sim.Reference`).
A logged command is first recognised as one of its analytic kinds: a constant, one jump, a
constant followed by a constant rate, or ``offset + A sin(2 pi f (t - t0))``, each accepted
when it reproduces every logged sample within :data:`TOLERANCE` of the command's span (the
digits a log writes); these are exact between the samples too (a jump stays a jump). Any
other command (a logged trajectory, a chirp, a sequence of moves) is followed as it was
logged: a sampled command (:meth:`~servo_toolkit.sim.Reference.table`, the cubic spline
through the samples), which the controller reads exactly at its sample instants when the log
is written at the controller's sample rate.

Times are counted from the log's first sample, where the simulation starts in equilibrium at
the command's first value.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import optimize

from ..errors import SceneError
from ..sim.reference import Reference

#: largest deviation of a logged command from the recognised one, relative to its span
TOLERANCE = 1e-4


def _close(model, command, tol) -> bool:
    return bool(np.max(np.abs(model - command)) <= tol)


def _step(t, c, tol):
    moved = np.flatnonzero(np.abs(c - c[0]) > tol)
    k = int(moved[0])
    if not _close(c[k:], c[-1], tol):
        return None
    at = 0.5 * (t[k - 1] + t[k])  # the jump lies between the two samples
    return Reference.step(float(c[-1] - c[0]), at=float(at), offset=float(c[0]))


def _ramp(t, c, tol):
    moved = np.flatnonzero(np.abs(c - c[0]) > tol)
    k = max(int(moved[0]) - 1, 0)
    if t.size - k < 3:
        return None
    rate, icpt = np.polyfit(t[k + 1:], c[k + 1:], 1)
    if rate == 0:
        return None
    at = max((c[0] - icpt) / rate, 0.0)
    ref = Reference.ramp(float(rate), at=float(at), offset=float(c[0]))
    model = c[0] + rate * np.maximum(t - at, 0.0)
    return ref if _close(model, c, tol) else None


def _sine(t, c, tol):
    n = t.size
    dt = (t[-1] - t[0]) / (n - 1)
    spec = np.abs(np.fft.rfft((c - c.mean()) * np.hanning(n)))
    k = int(np.argmax(spec[1:])) + 1
    if 1 <= k < spec.size - 1:  # between bins: the parabola through the peak's log-magnitudes
        a, b, g = np.log(spec[k - 1:k + 2] + 1e-300)
        k = k + 0.5 * (a - g) / (a - 2 * b + g)
    f0 = k / (n * dt)
    basis = np.column_stack([np.ones(n), np.sin(2 * math.pi * f0 * t), np.cos(2 * math.pi * f0 * t)])
    off, s, co = np.linalg.lstsq(basis, c, rcond=None)[0]

    def residual(p):
        return p[0] + p[1] * np.sin(2 * math.pi * p[2] * t + p[3]) - c
    sol = optimize.least_squares(residual, [off, math.hypot(s, co), f0, math.atan2(co, s)], method="lm",
                                 xtol=1e-14, ftol=1e-14)
    off, amp, f, phase = sol.x
    if not (f > 0 and amp != 0):
        return None
    if amp < 0:
        amp, phase = -amp, phase + math.pi
    t0 = -phase / (2 * math.pi * f)
    ref = Reference("sine", float(amp), float(f), float(off), float(t0))
    model = off + amp * np.sin(2 * math.pi * f * (t - t0))
    return ref if _close(model, c, tol) else None


def command_reference(time_s, command, source: str | None = None) -> Reference:
    """The simulation's command that reproduces a logged position command.

    Parameters
    ----------
    time_s : array_like
        Equally spaced times (s); the command is read relative to the first.
    command : array_like
        Logged position command (rad, or m for an output travel).
    source : str, optional
        The log's file (named in an error).

    Returns
    -------
    Reference
        Hold, step, ramp or sine, or else the sampled command (kind ``"table"``), with times
        from the first sample.
    """
    t = np.asarray(time_s, float) - float(time_s[0])
    c = np.asarray(command, float)
    span = float(np.ptp(c))
    tol = TOLERANCE * span + 1e-12 * max(1.0, float(np.max(np.abs(c))))
    if span <= tol:
        return Reference("hold", offset=float(c[0]))
    for recognise in (_step, _ramp, _sine):
        ref = recognise(t, c, tol)
        if ref is not None:
            return ref
    try:  # the log's times are equally spaced (checked when read): its mean step, free of their digits
        return Reference.table(np.arange(t.size) * (t[-1] / (t.size - 1)), c - c[0], offset=float(c[0]))
    except SceneError as exc:
        raise SceneError("command", exc.rule, source) from None
