"""Inverse dynamics of a one-DOF drivetrain along a prescribed motion (seed 000, eq 10).

With the equivalent-element data of :meth:`Drivetrain.jacobians` (masses M, T = du/dq,
T2 = d2u/dq2) the generalized inertial force of a set of elements is

    I(q, qd, qdd) = (T'MT) qdd + (T'M T2) qd^2 = J(q) qdd + (1/2) J'(q) qd^2,

and the motor torque follows by walking the chain from the load back to the motor.

Loads and losses (the documented model)
---------------------------------------
* External moments at the output coordinate y (y = q for a rocker actuator): the load's
  hinge moment M_h (a constant moment opposing positive motion, so the drive must supply
  +M_h), hinge stiffness k*y and damping c*y'. Their generalized force is
  (M_h + k y + c y') dy/dq. The load inertia is one of the elements.
* Stage losses, stage by stage from the load back to the motor, each element at its place in
  the drivetrain's chain (:mod:`servo_toolkit.drivetrain.chain`). Let G be the generalized
  force (at q) the stages beyond stage k require; raw = G plus the inertial force of stage
  k's output members (the gear wheel, the nut: beyond its loss). With P = raw * qd the power
  flowing through stage k:
  motoring (P >= 0, power flows motor -> load): G_k = raw / eta_k;
  back-driving (P < 0, the load drives the motor): G_k = raw * eta_b,k, with the stage's
  back-drive efficiency (``Stage.backdrive_efficiency``: eta_k for gears and linkages,
  2 - 1/eta_k for screws), the same pair of efficiencies the nonlinear simulation uses. A
  self-locking screw (eta_b <= 0) makes the motor pull the load along even when it back-drives.
  Stage k's input members (the pinion, the screw) are before its loss: their inertial force is
  added to G_k as it is.
  ``losses="none"`` sets every eta_k = 1.
* The motor rotor is before every loss: T_m = (G_0 + I_rotor) / N + b w_m + Tc sign(w_m)
  with the motor's viscous and Coulomb friction, w_m = N qd.
* Friction at a stage's output (``[[drivetrain]]`` ``coulomb_friction``, ``viscous_friction``,
  :class:`~servo_toolkit.components.stage_friction.StageFriction`) acts on the stage's output
  members, beyond its loss: F_k = Tc_k sign(u_k') + B_k u_k' at the stage's output coordinate
  u_k, generalized F_k du_k/dq, added to raw at stage k (so the losses of stage k and of every
  stage before it carry it). The load's Coulomb friction Tc_L sign(y') joins its moments. Both
  slide at their Coulomb level: the breakaway excess Ts - Tc of a start from rest is not in
  (:func:`breakaway_note` says how large it is). On a constant-speed segment (qdd = 0, constant
  ratios) the motor torque is therefore b w_m + Tc_m + (F_0 u_0' + (F_1 u_1' + ... + (c y' +
  Tc_L + M_h) y'_q / eta_n ...) / eta_1) / eta_0 / N while motoring.

Forces in the chain
-------------------
* Nut pin force F_pin = G_beyond / (dx_A/dq): what the chain beyond the ball screw needs,
  divided by the screw-to-output ratio (positive pushes the nut towards +x_A, i.e. towards
  positive q; with the nut pin behind the arm that compresses the link rod).
* Screw thrust = F_pin + m_nut * x_A'': the axial force the screw thread puts on the nut
  (what the screw and its bearings carry).
* Link-rod force = F_pin / cos(psi), psi the rod angle against the screw axis: the pin force
  taken along the rod (the rod's own transverse inertial load is neglected here).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ...components.ball_screw import BallScrew
from ...components.linkage import RockerLinkage
from ...components.roller_screw.stages import RollerScrew
from ...drivetrain.reflected import Drivetrain
from ...errors import SimulationError

LOSS_MODELS = ("directional", "none")


@dataclass(frozen=True)
class InverseDynamicsResult:
    """Loads along a prescribed motion.

    Attributes
    ----------
    t, q, qd, qdd : numpy.ndarray
        Time (s) and the prescribed motion of q (rad, rad/s, rad/s^2).
    ratio : numpy.ndarray
        N(q), motor rad per rad of q.
    motor_speed : numpy.ndarray
        rad/s.
    motor_torque : numpy.ndarray
        N*m at the motor shaft (what the motor's electromagnetic torque must be).
    inertial_torque, external_torque, loss_torque, friction_torque : numpy.ndarray
        Parts of ``motor_torque`` (N*m): all inertial forces over N, external moments and the
        stages' and the load's friction over N, stage losses, motor friction. They add up to
        ``motor_torque``.
    screw_thrust, rod_force : numpy.ndarray or None
        N; None when the chain has no ball or roller screw / no rocker linkage after it (a
        roller screw's thrust is that on its last nut).
    losses : str
        Loss model used.
    """

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    ratio: np.ndarray
    motor_speed: np.ndarray
    motor_torque: np.ndarray
    inertial_torque: np.ndarray
    external_torque: np.ndarray
    loss_torque: np.ndarray
    friction_torque: np.ndarray
    screw_thrust: np.ndarray | None
    rod_force: np.ndarray | None
    losses: str

    @property
    def peak_motor_torque(self) -> float:
        """max |motor torque| (N*m)."""
        return float(np.max(np.abs(self.motor_torque)))

    @property
    def peak_screw_thrust(self) -> float | None:
        """max |screw thrust| (N), or None."""
        return None if self.screw_thrust is None else float(np.max(np.abs(self.screw_thrust)))

    @property
    def peak_rod_force(self) -> float | None:
        """max |link-rod force| (N), or None."""
        return None if self.rod_force is None else float(np.max(np.abs(self.rod_force)))

    def to_dict(self) -> dict:
        """JSON-ready dictionary (time series as lists)."""
        def opt(a):
            return None if a is None else a.tolist()
        return {
            "losses": self.losses,
            "t_s": self.t.tolist(), "q_deg": np.degrees(self.q).tolist(),
            "qd_deg_s": np.degrees(self.qd).tolist(), "qdd_deg_s2": np.degrees(self.qdd).tolist(),
            "ratio": self.ratio.tolist(), "motor_speed_rad_s": self.motor_speed.tolist(),
            "motor_torque_Nm": self.motor_torque.tolist(),
            "inertial_torque_Nm": self.inertial_torque.tolist(),
            "external_torque_Nm": self.external_torque.tolist(),
            "loss_torque_Nm": self.loss_torque.tolist(),
            "friction_torque_Nm": self.friction_torque.tolist(),
            "screw_thrust_N": opt(self.screw_thrust), "rod_force_N": opt(self.rod_force),
            "peak_motor_torque_Nm": self.peak_motor_torque,
            "peak_screw_thrust_N": self.peak_screw_thrust, "peak_rod_force_N": self.peak_rod_force,
        }

    def plot(self, axes=None, label: str | None = None):
        """Motion, motor torque and screw thrust over time; returns the axes (3 rows)."""
        import matplotlib.pyplot as plt
        if axes is None:
            _, axes = plt.subplots(3, 1, figsize=(7, 6.5), sharex=True)
        axes[0].plot(self.t, np.degrees(self.q), label=label)
        axes[0].set_ylabel("q [deg]")
        axes[1].plot(self.t, self.motor_torque, label=label)
        axes[1].set_ylabel("motor torque [N*m]")
        if self.screw_thrust is not None:
            axes[2].plot(self.t, self.screw_thrust / 1e3, label=label)
        axes[2].set_ylabel("screw thrust [kN]")
        axes[2].set_xlabel("t [s]")
        for ax in axes:
            ax.grid(True, alpha=0.3)
        if label:
            axes[1].legend(fontsize="small")
        return axes


def subchain(drivetrain: Drivetrain, start: int) -> Drivetrain:
    """The stages from index ``start`` to the load, without the motor rotor.

    Its ``ratio(q)`` is d(input coordinate of stage ``start``)/dq and its ``inertia(q)`` the
    reflected inertia of those stages' elements and the load.
    """
    motor = replace(drivetrain.motor, rotor_inertia=0.0)
    return Drivetrain(motor, tuple(drivetrain.stages[start:]), drivetrain.load)


def inertial_force(drivetrain: Drivetrain, q, qd, qdd) -> np.ndarray:
    """J(q) qdd + (1/2) J'(q) qd^2 of every element of ``drivetrain`` (generalized, at q)."""
    j, dj = drivetrain.inertia(q)
    return j * qdd + 0.5 * dj * np.asarray(qd) ** 2


def external_force(drivetrain: Drivetrain, q, qd) -> np.ndarray:
    """Generalized force (at q) the drive must supply against the load's moments."""
    load = drivetrain.load
    y = drivetrain.kinematics(q).output
    moment = load.hinge_moment + load.hinge_stiffness * y.value + load.damping * y.d1 * qd
    return moment * y.d1


def stage_friction_forces(drivetrain: Drivetrain, stage_friction, q, qd) -> list:
    """Each stage's friction at its output, generalized at q (N*m per rad of q, or N): Tc_k
    sign(u_k') du_k/dq + B_k u_k' du_k/dq with u_k' = du_k/dq qd; zeros for a stage without."""
    zero = np.zeros_like(q)
    if not stage_friction or all(f is None for f in stage_friction):
        return [zero] * len(drivetrain.stages)
    sides, _ = drivetrain.output_sides(q)
    out = []
    for k in range(len(drivetrain.stages)):
        fr = stage_friction[k] if k < len(stage_friction) else None
        if fr is None:
            out.append(zero)
            continue
        slope = sides[k].d1
        speed = slope * qd
        out.append((fr.coulomb_friction * np.sign(speed) + fr.viscous_friction * speed) * slope)
    return out


def load_friction_force(drivetrain: Drivetrain, q, qd) -> np.ndarray:
    """The load's Coulomb friction, Tc_L sign(y') dy/dq, generalized at q."""
    y = drivetrain.kinematics(q).output
    return drivetrain.load.coulomb_friction * np.sign(y.d1 * qd) * y.d1


def breakaway_note(motor, load, stage_friction, unit: str = "N*m") -> str | None:
    """What the inverse dynamics leaves out of the scene's friction: the breakaway excess
    Ts - Tc a start from rest needs at each node that gives one (None when none does)."""
    parts = []
    if motor.breakaway_torque > motor.coulomb_friction:
        parts.append(f"motor {motor.breakaway_torque - motor.coulomb_friction:.4g} N*m")
    for k, fr in enumerate(stage_friction or ()):
        if fr is not None and fr.breakaway > fr.coulomb_friction:
            parts.append(f"drivetrain[{k}] {fr.breakaway - fr.coulomb_friction:.4g} at its output")
    if load.breakaway > load.coulomb_friction:
        parts.append(f"load {load.breakaway - load.coulomb_friction:.4g} {unit}")
    if not parts:
        return None
    return ("friction slides at its Coulomb level: a start from rest needs the breakaway excess Ts - Tc "
            "on top (" + ", ".join(parts) + "), not in these figures")


def friction_notes(scene) -> list:
    """What the inverse dynamics takes of the scene's friction (every node's Coulomb and
    viscous levels) and what it leaves out (the breakaway excess of a start from rest)."""
    motor, load = scene.motor, scene.load
    frictions = scene.stage_friction or ()
    taken = [f"motor {motor.coulomb_friction:.4g} N*m"] if motor.coulomb_friction > 0 else []
    taken += [f"drivetrain[{k}] {fr.coulomb_friction:.4g} at its output" for k, fr in enumerate(frictions)
              if fr is not None and fr.coulomb_friction > 0]
    unit = "N" if scene.drivetrain.output_unit == "m" else "N*m"
    if load.coulomb_friction > 0:
        taken.append(f"load {load.coulomb_friction:.4g} {unit}")
    notes = [f"Coulomb friction in the loads, through the stages' losses: {', '.join(taken)}"] if taken else []
    left = breakaway_note(motor, load, frictions, unit)
    return notes + ([left] if left else [])


def inverse_dynamics(drivetrain: Drivetrain, motion, t, *, losses: str = "directional",
                     friction: bool = True, stage_friction=()) -> InverseDynamicsResult:
    """Motor torque, screw thrust and link-rod force along a prescribed motion.

    Parameters
    ----------
    drivetrain : Drivetrain
        E.g. ``scene.drivetrain`` (the load's inertia is part of it).
    motion : callable
        ``motion(t) -> (q, qd, qdd)``, e.g. :class:`~servo_toolkit.studies.trajectories.SineMotion`.
    t : array_like
        Sample times (s).
    losses : {"directional", "none"}
        Stage-efficiency model (module docstring).
    friction : bool
        Include the motor's viscous and Coulomb friction, the load's Coulomb friction and
        the stages' (``stage_friction``).
    stage_friction : sequence of StageFriction or None
        Each stage's friction at its output (``scene.stage_friction``; empty: none).

    Returns
    -------
    InverseDynamicsResult

    Raises
    ------
    SimulationError
        The ratio vanishes or a load is not finite along the motion.
    """
    if losses not in LOSS_MODELS:
        raise ValueError(f"losses must be one of {LOSS_MODELS}, got {losses!r}")
    t = np.atleast_1d(np.asarray(t, dtype=float))
    q, qd, qdd = (np.broadcast_to(np.asarray(a, dtype=float), t.shape).copy() for a in motion(t))
    stages = drivetrain.stages
    n = len(stages)
    chains = [subchain(drivetrain, k) for k in range(n + 1)]
    inertial = [inertial_force(c, q, qd, qdd) for c in chains]   # inertial[n] = load only
    external = external_force(drivetrain, q, qd)
    zero = np.zeros_like(q)
    if friction:
        external = external + load_friction_force(drivetrain, q, qd)
        at_stage = stage_friction_forces(drivetrain, stage_friction, q, qd)
    else:
        at_stage = [zero] * n
    # each element's inertial force, and its place in the chain (drivetrain.chain): before its
    # stage's loss (a stage's input members) or beyond it (its output members)
    per = drivetrain.reflected_inertias(q)
    force = per.output * qdd + 0.5 * per.output_dq * qd**2
    chain = drivetrain.chain
    before = ~np.array([e.past_loss for e in chain.elements])
    owner = np.array([e.stage for e in chain.elements])
    required = [None] * (n + 1)
    required[n] = inertial[n] + external
    for k in reversed(range(n)):
        mine = owner == k
        raw = required[k + 1] + force[mine & ~before].sum(axis=0) + at_stage[k]
        if losses == "none":
            eta = eta_b = 1.0
        else:
            eta, eta_b = float(getattr(stages[k], "efficiency", 1.0)), stages[k].backdrive_efficiency
        required[k] = np.where(raw * qd >= 0, raw / eta, raw * eta_b) + force[mine & before].sum(axis=0)
    ratio, _ = drivetrain.ratio(q)
    if not np.all(np.isfinite(ratio)) or np.any(ratio == 0):
        raise SimulationError("the drivetrain ratio is zero or not finite along the motion")
    total_inertial = inertial_force(drivetrain, q, qd, qdd)
    rotor = total_inertial - inertial[0]
    motor_speed = ratio * qd
    motor = drivetrain.motor
    fric = (motor.viscous_friction * motor_speed + motor.coulomb_friction * np.sign(motor_speed)
            if friction else np.zeros_like(q))
    torque = (required[0] + rotor) / ratio + fric
    lossless = (total_inertial + external + sum(at_stage)) / ratio
    screw, rod = _chain_forces(drivetrain, chains, required, q, qd, qdd, at_stage)
    if not np.all(np.isfinite(torque)):
        raise SimulationError("inverse dynamics produced a non-finite motor torque")
    return InverseDynamicsResult(
        t=t, q=q, qd=qd, qdd=qdd, ratio=ratio, motor_speed=motor_speed, motor_torque=torque,
        inertial_torque=total_inertial / ratio, external_torque=(external + sum(at_stage)) / ratio,
        loss_torque=(required[0] + rotor) / ratio - lossless, friction_torque=fric,
        screw_thrust=screw, rod_force=rod, losses=losses)


def _chain_forces(drivetrain, chains, required, q, qd, qdd, at_stage):
    """Screw thrust and link-rod force from the first ball or roller screw of the chain (a
    roller screw's thrust is that on its last nut); the thrust carries the nut's own friction
    (the screw stage's, ``at_stage``)."""
    stages = drivetrain.stages
    k = next((i for i, s in enumerate(stages) if isinstance(s, (BallScrew, RollerScrew))), None)
    if k is None:
        return None, None
    beyond = chains[k + 1]
    kin = beyond.kinematics(q).motor            # nut travel x_A as a jet in q
    rate, curvature = kin.d1, kin.d2
    pin = required[k + 1] / rate
    thrust = pin + stages[k].nut_mass * (rate * qdd + curvature * qd**2) + at_stage[k] / rate
    rod = None
    if k + 1 < len(stages) and isinstance(stages[k + 1], RockerLinkage):
        phi = chains[k + 2].kinematics(q).motor.value   # the linkage's own output angle
        psi = stages[k + 1].rod_angle(phi).value
        rod = pin / np.cos(psi)
    return thrust, rod


def motor_torque_at(drivetrain: Drivetrain, motion, t: float, **options) -> float:
    """Motor torque at one instant (convenience for forward checks)."""
    return float(inverse_dynamics(drivetrain, motion, [t], **options).motor_torque[0])


__all__ = ["InverseDynamicsResult", "inverse_dynamics", "inertial_force", "external_force", "breakaway_note", "friction_notes",
           "load_friction_force", "stage_friction_forces",
           "subchain", "motor_torque_at", "LOSS_MODELS"]
