"""The ratio choice: the duty cycle's figures over a sweep of the first stage's ratio.

The sweep multiplies the first stage's ratio by factors s (a gear stage: its gear ratio; a
chain starting with a screw: its lead divided by s). Whatever turns with the motor shaft
(the rotor and the first stage's input member, e.g. the pinion or the screw) is then seen
s^2 heavier from the output, the rest of the chain is unchanged, and the power flows the
same way through every stage, so the inverse dynamics splits exactly:

    T(s) = T_rest / s + s T_shaft + b s N qd + Tc sign(qd)

with T_rest and T_shaft the two parts at s = 1: one inverse-dynamics run serves every ratio,
and the whole sweep is array arithmetic. The members keep their inertia as the ratio
changes (a different gear would change it too).

Per ratio: RMS torque and current, peak torque and speed, peak voltage (hot winding), the
steady periodic winding temperature, the output stiffness (the series stiffness of the
chain, which a first-stage ratio leaves unchanged) and an estimate of the achievable
position-loop bandwidth from the two-mass model: min(f_r / 3, f_a / 2), f_r the resonance
(its motor-side inertia scaled by s^2) and f_a the antiresonance; an estimate to choose a
ratio with, the design of the chosen one is ``servo-toolkit design``.

Without friction the RMS torque is smallest at s* = (mean(T_rest^2) / mean(T_shaft^2))^(1/4):
for a pure inertia J_L behind a ratio N and a rotor J_m, the inertia-matching ratio
N s* = sqrt(J_L / J_m).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .envelope import Envelope
from .thermal import ThermalNetwork, interval_i2, periodic_peak


@dataclass(frozen=True)
class RatioSweep:
    """Figures of the duty cycle over a sweep of the first stage's ratio, per motor.

    Attributes
    ----------
    factors : numpy.ndarray
        s, the factor on the first stage's ratio.
    ratio : numpy.ndarray
        The overall ratio N at the cycle's start position for each factor (motor rad per
        unit of q).
    motors : tuple of str
        Motor names (the scene's motor first, then ``[[duty_cycle.motors]]``).
    rms_current, rms_torque, peak_torque, peak_speed, peak_voltage, winding_temperature : numpy.ndarray
        Shape (motors, factors); A, N*m, N*m, rad/s, V, K (nan without a thermal
        network, inf for thermal runaway).
    bandwidth : numpy.ndarray
        Bandwidth estimate (Hz) per factor (nan for a rigid chain).
    stiffness : float
        Series stiffness at the output (N*m/rad, or N/m for an output travel).
    feasible : numpy.ndarray of bool
        Shape (motors, factors): every limit holds.
    rms_optimal_ratio : tuple of float
        Per motor, the overall ratio of smallest RMS torque without friction.
    required_bandwidth : float or None
        The scene's ``[requirements] bandwidth`` (Hz).
    """

    factors: np.ndarray
    ratio: np.ndarray
    motors: tuple
    rms_current: np.ndarray
    rms_torque: np.ndarray
    peak_torque: np.ndarray
    peak_speed: np.ndarray
    peak_voltage: np.ndarray
    winding_temperature: np.ndarray
    bandwidth: np.ndarray
    stiffness: float
    feasible: np.ndarray
    rms_optimal_ratio: tuple
    required_bandwidth: float | None = None

    def feasible_range(self, motor: int = 0) -> tuple | None:
        """(lowest, highest) feasible overall ratio of a motor, None when none is."""
        ok = self.feasible[motor]
        return (float(self.ratio[ok].min()), float(self.ratio[ok].max())) if ok.any() else None

    def to_dict(self) -> dict:
        """JSON-ready dictionary."""
        def arr(a):
            return [[None if not math.isfinite(v) else float(v) for v in row] for row in np.atleast_2d(a)]
        return {"factors": self.factors.tolist(), "ratio": self.ratio.tolist(), "motors": list(self.motors),
                "rms_current_A": arr(self.rms_current), "rms_torque_Nm": arr(self.rms_torque),
                "peak_torque_Nm": arr(self.peak_torque), "peak_speed_rad_s": arr(self.peak_speed),
                "peak_voltage_V": arr(self.peak_voltage), "winding_temperature_degC": arr(self.winding_temperature - 273.15),
                "bandwidth_estimate_Hz": arr(self.bandwidth)[0],
                "stiffness": self.stiffness if math.isfinite(self.stiffness) else None,
                "feasible": self.feasible.tolist(),
                "feasible_ratio_range": [self.feasible_range(i) for i in range(len(self.motors))],
                "rms_optimal_ratio": list(self.rms_optimal_ratio), "required_bandwidth_Hz": self.required_bandwidth}


def split_torque(drivetrain, motion, loads):
    """(T_rest, T_shaft, w_shaft) at s = 1: the motor torque without what turns with the
    motor shaft and without the motor's friction, the torque of the shaft's members, and
    their inertia reflected to q at the samples (kg*m^2, or kg)."""
    q, qd, qdd = motion.q, motion.qd, motion.qdd
    per = drivetrain.reflected_inertias(q)
    member = np.array([e.member == "input" for e in drivetrain.kinematics(q[:1]).elements])
    owner = np.asarray(per.stage)
    if member.size != owner.size:  # the rotor is listed apart from the stages' elements
        member = np.concatenate([member, np.zeros(owner.size - member.size, bool)])
    shaft = (owner == -1) | ((owner == 0) & member)
    n, dn = drivetrain.ratio(q)
    force = (per.output[shaft] * qdd + 0.5 * per.output_dq[shaft] * qd**2).sum(axis=0)
    has_rotor = np.any(owner == -1)
    if not has_rotor:
        force = force + drivetrain.motor.rotor_inertia * (n**2 * qdd + n * dn * qd**2)
    j_shaft = per.output[shaft].sum(axis=0) + (0.0 if has_rotor else drivetrain.motor.rotor_inertia * n**2)
    t_shaft = force / n
    return loads.motor_torque - loads.friction_torque - t_shaft, t_shaft, j_shaft


def _bandwidth(drivetrain, q0: float, j_shaft: float, factors) -> np.ndarray:
    chain = drivetrain.chain
    if chain.rigid:
        return np.full(factors.size, np.nan)
    j1, j2, k = chain.modal_two_mass(q0)
    j1s = np.maximum(j1 + (factors**2 - 1) * j_shaft, 1e-12 * j1)
    fr = np.sqrt(k * (1 / j1s + 1 / j2)) / (2 * math.pi)
    fa = math.sqrt(k / j2) / (2 * math.pi)
    return np.minimum(fr / 3, fa / 2)


def ratio_sweep(drivetrain, motion, loads, motors, factors, *, required_bandwidth=None,
                thermal_steps: int = 200) -> RatioSweep:
    """The :class:`RatioSweep` of a sized duty cycle (module docstring).

    Parameters
    ----------
    drivetrain : Drivetrain
    motion : CycleMotion
    loads : CycleLoads
        Of ``drivetrain`` along ``motion`` (s = 1).
    motors : sequence of (str, DCMotor)
        The motors compared; the first is the drivetrain's.
    factors : array_like
        Factors s on the first stage's ratio.
    required_bandwidth : float, optional
        Hz; ratios whose bandwidth estimate is below it are not feasible.
    thermal_steps : int
        Intervals per cycle of the thermal integration.
    """
    s = np.asarray(factors, dtype=float)[:, None]
    rest, shaft, j_shaft = split_torque(drivetrain, motion, loads)
    n = loads.ratio
    rotor0 = drivetrain.motor.rotor_inertia
    w1 = n * motion.qd
    rows = {k: [] for k in ("rms_current", "rms_torque", "peak_torque", "peak_speed", "peak_voltage",
                            "winding_temperature", "feasible")}
    optimal = []
    bw = _bandwidth(drivetrain, float(motion.q[0]), float(j_shaft[0]), s[:, 0])
    for _, motor in motors:
        # the candidate's rotor replaces the scene's in the shaft's torque
        t_shaft = shaft + (motor.rotor_inertia - rotor0) * (n * motion.qdd + _dn(drivetrain, motion) * motion.qd**2)
        torque = rest / s + s * t_shaft + motor.viscous_friction * s * w1 + motor.coulomb_friction * np.sign(w1)
        speed = s * w1
        env = Envelope.of(motor)
        current = torque / motor.torque_constant
        rms_t = np.sqrt(np.sum(torque**2 * motion.weight, axis=1) / motion.duration)
        peak_t = np.abs(torque).max(axis=1)
        peak_w = np.abs(speed).max(axis=1)
        peak_u = np.abs(env.hot_resistance * current + motor.back_emf_constant * speed).max(axis=1)
        net = ThermalNetwork.from_motor(motor)
        if net is None:
            temp = np.full(s.size, np.nan)
        else:
            i2, h = interval_i2(current, motion.weight, thermal_steps)
            temp = periodic_peak(net, i2, h)
        ok = (peak_t <= env.peak_torque) & (peak_u <= motor.voltage_limit)
        if env.continuous_torque is not None:
            ok &= rms_t <= env.continuous_torque
        if net is not None:
            ok &= temp <= motor.max_winding_temperature
        if required_bandwidth is not None:
            ok &= ~(bw < required_bandwidth)
        for key, value in zip(rows, (rms_t / motor.torque_constant, rms_t, peak_t, peak_w, peak_u, temp, ok)):
            rows[key].append(value)
        a2, b2 = motion.mean(rest**2), motion.mean(t_shaft**2)
        optimal.append(float(n[0] * (a2 / b2) ** 0.25) if b2 > 0 else math.inf)
    arrays = {k: np.array(v) for k, v in rows.items()}
    stiff = float(drivetrain.stiffness([float(motion.q[0])]).total[0])
    return RatioSweep(factors=s[:, 0], ratio=s[:, 0] * float(n[0]), motors=tuple(m for m, _ in motors),
                      bandwidth=bw, stiffness=stiff, rms_optimal_ratio=tuple(optimal),
                      required_bandwidth=required_bandwidth, **arrays)


def _dn(drivetrain, motion) -> np.ndarray:
    return drivetrain.ratio(motion.q)[1]


__all__ = ["RatioSweep", "ratio_sweep", "split_torque"]
