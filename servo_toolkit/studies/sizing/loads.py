"""Motor torque, speed, current, voltage and power along a duty cycle, from the Kv inverse
dynamics (:func:`servo_toolkit.studies.mechanisms.inverse_dynamics.inverse_dynamics`: efficiency by
direction of power flow, variable ratio and inertia along the stroke, the motor's, each
stage's and the load's friction at their Coulomb levels).

Each segment's external load replaces the scene's ``[load] hinge_moment`` over that
segment (the load's inertia, stiffness and damping stay). The motor's electrical side is
the steady DC motor: current i = T / Kt, voltage u = R i + Ke w (the inductance's L di/dt is
left out: at the cycle's time scales it is a small fraction of R i), electrical power u i
(negative: the motor regenerates), mechanical power T w.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ...components.ball_screw import BallScrew
from ...components.roller_screw.stages import RollerScrew
from ..mechanisms.inverse_dynamics import friction_notes, inverse_dynamics, subchain


@dataclass(frozen=True)
class CycleLoads:
    """What the motor and the screw see along one cycle (arrays over the samples).

    Attributes
    ----------
    motor_torque, motor_speed : numpy.ndarray
        N*m and rad/s at the motor shaft.
    ratio : numpy.ndarray
        N(q), motor rad per unit of q.
    friction_torque : numpy.ndarray
        The motor's own friction inside ``motor_torque`` (N*m).
    screw_thrust : numpy.ndarray or None
        Axial force on the first ball screw's nut, or on a roller screw's last nut (N); None
        without a screw.
    screw_speed : numpy.ndarray or None
        That screw's angular speed (rad/s).
    """

    motor_torque: np.ndarray
    motor_speed: np.ndarray
    ratio: np.ndarray
    friction_torque: np.ndarray
    screw_thrust: np.ndarray | None
    screw_speed: np.ndarray | None


def cycle_loads(drivetrain, motion, losses: str = "directional", stage_friction=()) -> CycleLoads:
    """Inverse dynamics of ``drivetrain`` along a :class:`~.cycle.CycleMotion`, one call per
    distinct segment load; ``stage_friction`` (``scene.stage_friction``) each stage's friction.

    Raises
    ------
    SimulationError
        The ratio vanishes or a load is not finite along the motion.
    """
    n = motion.t.size
    torque, speed, ratio, fric = (np.empty(n) for _ in range(4))
    thrust = None
    for value in np.unique(motion.load):
        idx = np.flatnonzero(motion.load == value)
        arrays = motion.q[idx], motion.qd[idx], motion.qdd[idx]
        train = replace(drivetrain, load=replace(drivetrain.load, hinge_moment=float(value)))
        res = inverse_dynamics(train, lambda t, a=arrays: a, motion.t[idx], losses=losses,
                               stage_friction=stage_friction)
        torque[idx], speed[idx], ratio[idx], fric[idx] = (res.motor_torque, res.motor_speed, res.ratio,
                                                          res.friction_torque)
        if res.screw_thrust is not None:
            thrust = np.empty(n) if thrust is None else thrust
            thrust[idx] = res.screw_thrust
    screw_speed = None
    if thrust is not None:
        k = screw_index(drivetrain)
        screw_speed = subchain(drivetrain, k).ratio(motion.q)[0] * motion.qd
    return CycleLoads(torque, speed, ratio, fric, thrust, screw_speed)


def screw_index(drivetrain) -> int | None:
    """Index of the first ball or roller screw of the chain (the one the thrust is taken on),
    or None."""
    return next((i for i, s in enumerate(drivetrain.stages) if isinstance(s, (BallScrew, RollerScrew))), None)


def electrical(motor, torque, speed, winding_temperature: float | None = None) -> dict:
    """Current (A), voltage (V), electrical and mechanical power (W) of ``motor`` at the
    torques and speeds given; the resistance at ``winding_temperature`` (K; default the
    temperature the resistance is given at)."""
    r = resistance_at(motor, motor.resistance_temperature if winding_temperature is None else winding_temperature)
    current = np.asarray(torque) / motor.torque_constant
    voltage = r * current + motor.back_emf_constant * np.asarray(speed)
    return {"current": current, "voltage": voltage, "electrical_power": voltage * current,
            "mechanical_power": np.asarray(torque) * np.asarray(speed)}


def resistance_at(motor, temperature: float) -> float:
    """Winding resistance at ``temperature`` (K): R (1 + alpha (T - T_ref))."""
    return motor.resistance * (1 + motor.copper_temperature_coefficient * (temperature - motor.resistance_temperature))


__all__ = ["CycleLoads", "cycle_loads", "electrical", "resistance_at", "screw_index"]
