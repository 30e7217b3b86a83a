"""What the motor gives its output within a share of its current and voltage limits, over a
span of the stroke: the one rule behind the command's reach (:mod:`.reach`) and the largest
sine the actuator can follow (:func:`servo_toolkit.studies.actuator.spec.followable_amplitude`).

At the output (rad or m), the drivetrain's losses lumped as the model lumps them (the inertia
J_w before the losses, the rest J - J_w beyond them; eta driving, eta_b back-driven; the
motor's friction Fm at its shaft, the load's F and hinge moment M at the output, each the
larger of its static and Coulomb level, the stages' friction reflected to the motor shaft):

- driving (the motor accelerates the load against M and F): the current
  ``i = (J_d a + M + F + eta N Fm) / (eta N Kt)`` with ``J_d = eta J_w + J - J_w`` the
  driving-mode inertia of the linear plant;
- back-driven (the load, aided by M, decelerated by the motor while it drives the motor):
  ``i = (eta_b (J - J_w) a + eta_b (M - F) + J_w a) / (N Kt) - Fm / Kt``; it never asks more
  than the driving case while eta_b <= 1 / eta, so the driving case sets the acceleration;
- a sine's voltage ``R i + Ke N v`` of its peak current and peak speed added (a bound: its
  current and speed are in quadrature, the exact peak is at most this); a move's cruise speed
  the share of the voltage the drop of its acceleration's current leaves (:meth:`speed_at`);

with J, J_w, N taken at their worst over the span (largest inertia, smallest ratio for the
torque, largest for the back EMF). Left out: the viscous friction and damping (a current
that grows with the speed: the feedback's share covers it) and the inductance's drop.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: points along a span at which the drivetrain's inertia and ratio are taken (the worst wins)
SPAN_POINTS = 17


@dataclass(frozen=True)
class DriveBudget:
    """The motor's share of its limits, at the output over a span of the stroke (SI; N*m
    and rad, or N and m for an output travel).

    Attributes
    ----------
    fraction : float
        The share of the current and voltage limits.
    current, voltage : float
        ``fraction`` of the current limit (A) and of the voltage limit (V); inf without one.
    gain : float
        Driving torque per ampere at the output, eta N Kt (smallest over the span).
    inertia : float
        Driving-mode inertia J_d = J - (1 - eta) J_w (largest over the span).
    held : float
        Torque the current must give before accelerating: |M| + F + eta N Fm (largest).
    back_acceleration : float
        The largest deceleration the current allows back-driven (inf when no case binds).
    emf : float
        Back EMF per output speed, Ke N (largest over the span, V*s/rad or V*s/m).
    resistance : float
        Armature resistance (ohm).
    """

    fraction: float
    current: float
    voltage: float
    gain: float
    inertia: float
    held: float
    back_acceleration: float
    emf: float
    resistance: float

    @property
    def acceleration(self) -> float:
        """The largest acceleration within the current share, driving and back-driven; at
        most 0 when the current cannot hold the load's friction and moment."""
        driving = (self.gain * self.current - self.held) / self.inertia if self.inertia > 0 else math.inf
        return min(driving, self.back_acceleration)

    def current_for(self, acceleration: float) -> float:
        """The current (A) the driving case asks to accelerate at ``acceleration``."""
        return (self.inertia * acceleration + self.held) / self.gain

    def speed_at(self, acceleration: float) -> float:
        """A move's cruise speed after accelerating at ``acceleration``: the share of the
        voltage the resistive drop of the acceleration's current J_d a / G leaves,
        ``f (V_max - R J_d a / G) / (Ke N)`` (inf without a voltage limit)."""
        if not math.isfinite(self.voltage):
            return math.inf
        drop = self.fraction * self.resistance * self.inertia * acceleration / self.gain
        return max(self.voltage - drop, 0.0) / self.emf

    def allows(self, speed: float, acceleration: float, rel: float = 1e-12) -> bool:
        """Whether a sine of peak ``speed`` and peak ``acceleration`` stays within the
        shares (to ``rel`` relative): the current of its peak acceleration within the
        current share, the drop of that current and the back EMF of its peak speed added
        within the voltage share."""
        a, v = abs(acceleration), abs(speed)
        if a > self.acceleration * (1 + rel) + 1e-300:
            return False
        if not math.isfinite(self.voltage):
            return True
        return self.resistance * self.current_for(a) + self.emf * v <= self.voltage * (1 + rel)

    def sine_amplitude(self, frequency: float) -> float:
        """The largest amplitude of a sine at ``frequency`` (Hz) within the shares: the
        smaller of ``a_max / w^2`` and ``(V - R held / G) / (w (R J w / G + Ke N))``; 0 when the
        current cannot hold the load, inf without limits."""
        w = 2 * math.pi * frequency
        a = self.acceleration
        if not a > 0:
            return 0.0
        out = a / (w * w)
        if math.isfinite(self.voltage):
            g = self.gain
            out = min(out, max(self.voltage - self.resistance * self.held / g, 0.0)
                      / (w * (self.resistance * self.inertia * w / g + self.emf)))
        return out


def _friction(level, static) -> float:
    return max(abs(level), abs(static or 0.0))


def drive_budget(scene, lo: float, hi: float | None = None, fraction: float = 1.0, *,
                 loads: bool = True) -> DriveBudget:
    """The :class:`DriveBudget` of ``scene`` over the stroke from ``lo`` to ``hi`` (default
    the point ``lo``), with ``fraction`` of the motor's current and voltage limits.
    ``loads=False``: the hinge moment and the friction are left to another share of the limits
    (the followable sine's rule: half for the motion, half for the loop, which holds the loads),
    the drivetrain's efficiency and inertia still counted."""
    from ..drivetrain.stage_friction import lumped_friction
    drive, load = scene.drivetrain, scene.load
    hi = lo if hi is None else hi
    s_lo, s_hi = drive.stroke
    lo, hi = max(min(lo, hi), s_lo), min(max(lo, hi), s_hi)
    q = np.unique(np.append(np.linspace(lo, hi, SPAN_POINTS if hi > lo else 1), [lo, hi]))
    chain = drive.chain
    n = np.abs(np.asarray(drive.ratio(q)[0], float))
    j = chain.node_inertias(q).sum(axis=0)
    jw = chain.loss_inertia(q)
    eta, eta_b = drive.efficiency, drive.backdrive_efficiency
    motor, _ = lumped_friction(scene, float(0.5 * (lo + hi)), True, [])
    kt = motor.torque_constant
    fm = _friction(motor.coulomb_friction, motor.breakaway_torque)
    m, f = abs(load.hinge_moment), _friction(load.coulomb_friction, load.static_friction)
    if not loads:
        m = f = fm = 0.0
    held = m + f + eta * n * fm
    i_share = fraction * motor.current_limit
    back = np.full(q.shape, math.inf)
    if eta_b > 0 and math.isfinite(i_share):
        # |i| = (eta_b ((J - J_w) a + M - F) + J_w a) / (N Kt) - Fm / Kt  <=  i_share
        back = (n * (kt * i_share + fm) - eta_b * (m - f)) / (eta_b * (j - jw) + jw)
    return DriveBudget(fraction=fraction, current=i_share, voltage=fraction * motor.voltage_limit,
                       gain=float(np.min(eta * n * kt)), inertia=float(np.max(j - (1 - eta) * jw)),
                       held=float(np.max(held)), back_acceleration=float(np.min(back)),
                       emf=float(np.max(motor.back_emf_constant * n)), resistance=motor.resistance)


def followable_sine(scene, q0: float, frequency: float, fraction: float, *, loads: bool = False) -> float:
    """The largest amplitude (SI) of a sine about ``q0`` at ``frequency`` (Hz) whose peak
    speed and acceleration stay within ``fraction`` of the limits over the stroke the sine
    sweeps, q0 +- its amplitude (:meth:`DriveBudget.sine_amplitude` at q0, then bisected
    when the inertia or ratio along the sweep asks more). ``loads``: as :func:`drive_budget`
    (by default the loads are the other share's)."""
    w = 2 * math.pi * frequency
    top = drive_budget(scene, q0, fraction=fraction, loads=loads).sine_amplitude(frequency)
    if not (math.isfinite(top) and top > 0):
        return top

    def fits(a):
        return drive_budget(scene, q0 - a, q0 + a, fraction, loads=loads).allows(a * w, a * w * w)
    if fits(top):
        return top
    low = 0.0
    for _ in range(60):
        mid = 0.5 * (low + top)
        low, top = (mid, top) if fits(mid) else (low, mid)
        if top - low <= 1e-12 * top:
            break
    return low


__all__ = ["DriveBudget", "SPAN_POINTS", "drive_budget", "followable_sine"]
