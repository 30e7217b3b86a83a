"""A duty cycle as samples of the prescribed motion q(t), its speed and acceleration.

Each segment is cut at its kinks (:func:`kink_times`: its ends and, for a ramp or a step,
where the acceleration jumps) and each piece is sampled at the midpoints of equal
sub-intervals, so every sample stands for a share of its piece's time (its ``weight``, s):
a mean over the cycle is ``sum(x * weight) / duration``, exact for the piecewise-constant
acceleration of a ramp or a step however short its move is against the cycle's sample time.

A sine takes at least 32 samples a period and a points spline 2 between its points
(:func:`~servo_toolkit.scene.duty_cycle.resolving_samples`), whatever the cycle's length:
a few samples over many periods would land on the same phases (all at the zero crossings of
the acceleration, say) and miss its torque.

Midpoints never land where the speed peaks at the end of an acceleration (a triangular
move's top speed, a ramp's last instant of acceleration at full speed), nor on a segment's
ends (a sine starts at its top speed): by up to half a sample of acceleration, which for a
short move in a long cycle is several percent of the peak speed, power and voltage. So each
kink also carries two samples of zero weight, one on each side of the acceleration's jump:
they count in every peak and in none of the means.

Motions (position q0 at the segment's start, local time t from 0 to the duration T):

* dwell: q = q0.
* ramp: a trapezoidal speed profile from q0 to ``to``: constant acceleration over
  ``accel_time`` ta, constant speed v = D / (T - ta), constant deceleration over ta.
* step: the same move as a triangular speed profile over ``rise_time`` (ta = rise / 2),
  then hold: a position step the drive can follow (an ideal step asks infinite torque).
* sine: q = q0 + A sin(2 pi f t).
* points: a cubic spline through the file's points (not-a-knot ends).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: samples of one cycle when the duty cycle gives no sample time
DEFAULT_SAMPLES = 4000
#: fewest samples of one segment
MIN_SEGMENT_SAMPLES = 16


@dataclass(frozen=True)
class CycleMotion:
    """The prescribed motion of one cycle, sampled.

    Attributes
    ----------
    t : numpy.ndarray
        Sample times from the cycle's start (s).
    weight : numpy.ndarray
        Time each sample stands for (s); they sum to the cycle's duration. Zero for the
        samples at a segment's kinks (module docstring), which count in the peaks only.
    q, qd, qdd : numpy.ndarray
        Position (rad or m), speed, acceleration.
    load : numpy.ndarray
        External moment or force the drive supplies at each sample (N*m or N).
    segment : numpy.ndarray
        Index of each sample's segment.
    """

    t: np.ndarray
    weight: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    load: np.ndarray
    segment: np.ndarray

    @property
    def duration(self) -> float:
        """One cycle (s)."""
        return float(self.weight.sum())

    def mean(self, x) -> float:
        """Time mean of ``x`` over the cycle."""
        return float(np.sum(np.asarray(x) * self.weight) / self.duration)

    def rms(self, x) -> float:
        """Root mean square of ``x`` over the cycle."""
        return math.sqrt(self.mean(np.asarray(x) ** 2))


def trapezoid(distance: float, duration: float, accel_time: float, t) -> tuple:
    """(q, qd, qdd) of a trapezoidal-speed move of ``distance`` in ``duration`` (from 0),
    accelerating and decelerating over ``accel_time`` each, at local times ``t``."""
    t = np.asarray(t, dtype=float)
    v = distance / (duration - accel_time)
    a = v / accel_time
    ta, tb = accel_time, duration - accel_time
    q = np.where(t < ta, 0.5 * a * t**2,
                 np.where(t <= tb, 0.5 * a * ta**2 + v * (t - ta), distance - 0.5 * a * (duration - t) ** 2))
    qd = np.where(t < ta, a * t, np.where(t <= tb, v, a * (duration - t)))
    qdd = np.where(t < ta, a, np.where(t <= tb, 0.0, -a))
    return q, qd, qdd


def segment_motion(seg, q0: float, t) -> tuple:
    """(q, qd, qdd) of segment ``seg`` starting at ``q0`` at local times ``t`` (s from the
    segment's start; module docstring)."""
    zero = np.zeros_like(t)
    if seg.kind == "ramp":
        q, qd, qdd = trapezoid(seg.to - q0, seg.duration, seg.accel_time, t)
        return q0 + q, qd, qdd
    if seg.kind == "step":
        move = t < seg.rise_time
        q, qd, qdd = trapezoid(seg.to - q0, seg.rise_time, seg.rise_time / 2, np.minimum(t, seg.rise_time))
        return q0 + q, np.where(move, qd, 0.0), np.where(move, qdd, 0.0)
    if seg.kind == "sine":
        w = 2 * math.pi * seg.frequency
        return q0 + seg.amplitude * np.sin(w * t), seg.amplitude * w * np.cos(w * t), -seg.amplitude * w**2 * np.sin(w * t)
    if seg.kind == "points":
        from scipy.interpolate import CubicSpline
        spline = CubicSpline(np.asarray(seg.times), np.asarray(seg.positions))
        return spline(t), spline(t, 1), spline(t, 2)
    return q0 + zero, zero, zero.copy()


def kink_times(seg) -> np.ndarray:
    """Local times of ``seg`` where its acceleration jumps or its speed or acceleration peaks
    between the midpoint samples: the segment's ends; for a ramp and a step, the ends of the
    acceleration and deceleration; for a sine, every quarter period."""
    if seg.kind == "ramp":
        inner = (seg.accel_time, seg.duration - seg.accel_time)
    elif seg.kind == "step":
        inner = (seg.rise_time / 2, seg.rise_time)
    elif seg.kind == "sine":
        inner = np.arange(1, math.floor(4 * seg.cycles) + 1) / (4 * seg.frequency)
    else:
        inner = ()
    return np.unique(np.clip(np.concatenate(([0.0], inner, [seg.duration])), 0.0, seg.duration))


def _samples(seg, q0: float, dt: float) -> tuple:
    """(local times, weights, q, qd, qdd) of a segment: the midpoints of each piece between
    its kinks (at most ``dt`` apart, at least :data:`MIN_SEGMENT_SAMPLES` over the segment and
    those that resolve a sine or a points spline) and the zero-weight samples on each side of
    every kink, in time order."""
    from ...scene.duty_cycle import resolving_samples
    cuts = kink_times(seg)
    dt = min(dt, seg.duration / max(MIN_SEGMENT_SAMPLES, resolving_samples(seg)))
    start, length = cuts[:-1], np.diff(cuts)
    keep = length > 1e-12 * seg.duration
    start, length = start[keep], length[keep]
    n = np.maximum(1, np.ceil(length / dt - 1e-9).astype(int))
    piece = np.repeat(np.arange(n.size), n)
    within = np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)
    h = length / n
    eps = 1e-9 * seg.duration
    kinks = np.clip(np.concatenate([cuts - eps, cuts + eps]), 0.0, seg.duration)
    times = np.concatenate([start[piece] + (within + 0.5) * h[piece], kinks])
    weight = np.concatenate([h[piece], np.zeros(kinks.size)])
    order = np.argsort(times, kind="stable")
    q, qd, qdd = segment_motion(seg, q0, times[order])
    return times[order], weight[order], q, qd, qdd


def sample_cycle(duty, start: float, default_load: float, sample_time: float | None = None) -> CycleMotion:
    """The motion of one cycle of ``duty`` (a :class:`~servo_toolkit.scene.duty_cycle.DutyCycle`).

    Parameters
    ----------
    duty : DutyCycle
    start : float
        Position at the cycle's start when the duty cycle gives none (rad or m).
    default_load : float
        Load of the segments that give none (the scene's hinge moment).
    sample_time : float, optional
        Sample spacing (s); default the duty cycle's, else :data:`DEFAULT_SAMPLES` per cycle.

    Returns
    -------
    CycleMotion
    """
    from ...scene.duty_cycle import segment_end
    dt = sample_time or duty.sample_time or duty.duration / DEFAULT_SAMPLES
    q0 = start if duty.start is None else duty.start
    parts, t0 = [], 0.0
    for i, seg in enumerate(duty.segments):
        local, weight, q, qd, qdd = _samples(seg, q0, dt)
        load = default_load if seg.load is None else seg.load
        parts.append((t0 + local, weight, q, qd, qdd, np.full(local.size, load), np.full(local.size, i)))
        t0 += seg.duration
        q0 = segment_end(seg, q0)
    cols = [np.concatenate(c) for c in zip(*parts)]
    return CycleMotion(*cols[:6], segment=cols[6].astype(int))


__all__ = ["CycleMotion", "sample_cycle", "segment_motion", "trapezoid", "kink_times", "DEFAULT_SAMPLES"]
