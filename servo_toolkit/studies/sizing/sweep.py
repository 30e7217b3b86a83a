"""The ratio choice: the duty cycle's figures over a sweep of the first stage's ratio.

The sweep multiplies the first stage's ratio by factors s (a gear stage: its gear ratio; a
chain starting with a screw: its lead divided by s). Whatever turns with the motor shaft
(the rotor and the first stage's input member, e.g. the pinion or the screw) is then seen
s^2 heavier from the output, the rest of the chain is unchanged, and the power flows the
same way through every stage, so the inverse dynamics splits exactly:

    T(s) = T_rest / s + s T_shaft + b s N qd + Tc sign(qd)

with T_rest and T_shaft the two parts at s = 1: one inverse-dynamics run serves every ratio,
and the whole sweep is array arithmetic. The members keep their inertia as the ratio
changes (a different gear would change it too). A motor candidate's rotor replaces the
scene's in T_shaft and in the chain's motor node.

Per motor and ratio: RMS torque and current, peak torque and speed, peak voltage (hot
winding), the steady periodic winding temperature and the estimate of the achievable
position-loop bandwidth; per ratio the screw's lives when the lead is swept. Feasible: every
limit of the sizing holds (peak and RMS torque, peak voltage, winding temperature, the
required bandwidth, the required life, a roller screw's static load): the limits no factor
changes (the static load; the lives behind a gear) hold at every ratio or at none.

* **Bandwidth estimate**: min(f_r / 3, f_a / 2), f_r the chain's lowest resonance with the
  motor node's inertia of that motor and ratio (the chain's eigenproblem at the cycle's
  start position, one small eigenproblem per motor and ratio) and f_a its lowest
  antiresonance (the motor node held, which no ratio changes). It is an estimate to choose a
  ratio with, not a design: at the reference EMA's own ratio it lies 12 % under the -3 dB
  bandwidth of the scene's design, which meets every requirement (that design's search,
  asked 1.5 times the estimate, misses some); design the chosen ratio with
  ``servo-toolkit design``. A rigid chain has no estimate (nan).
* **Screw life with a swept lead**: the thrust on the nut is set by the chain after the screw,
  which the lead does not change, but the screw turns s times more revolutions per cycle: its
  lives in hours are those at s = 1 divided by s. A gear ratio in front of the screw leaves
  the screw's speed and lives as they are.
* **Output stiffness**: the chain's series stiffness at the output (seed 001, eq 8). Every
  spring of a stage (a gear's mesh, a screw's axial, a rod's, the housing's) is given at
  that stage's output, after the first stage's ratio, so the factor leaves the output
  stiffness unchanged: it is shown as the one value of the chain. (The loop's stiffness
  against a load depends on the design and is no closed form of the ratio; see the report's
  dynamic stiffness.)

Without friction the RMS torque is smallest at s* = (mean(T_rest^2) / mean(T_shaft^2))^(1/4):
for a pure inertia J_L behind a ratio N and a rotor J_m, the inertia-matching ratio
N s* = sqrt(J_L / J_m).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from scipy import linalg

from ...components.ball_screw import BallScrew
from ...components.roller_screw.stages import RollerScrew
from .envelope import Envelope
from .thermal import ThermalNetwork, interval_i2, periodic_peak

#: most elements of one (factors x samples) array of the sweep: the factors are taken a few
#: at a time, so a fine sample time and many ratios bound the memory (about 16 MB an array)
CHUNK_ELEMENTS = 2_000_000


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
        Shape (motors, factors): the achievable bandwidth estimate (Hz; nan for a rigid
        chain; module docstring).
    stiffness : float
        Series stiffness at the output (N*m/rad, or N/m for an output travel), the same at
        every factor.
    feasible : numpy.ndarray of bool
        Shape (motors, factors): every limit holds.
    limited_by : tuple of (str or None, str or None)
        Per motor, the limits that end its feasible ratios: those that fail at the swept ratio
        just below the lowest feasible one and just above the highest (e.g. ``"RMS
        current"``, ``"peak voltage"``); None where the feasible ratios reach the sweep's end
        or none is feasible.
    rms_optimal_ratio : tuple of float
        Per motor, the overall ratio of smallest RMS torque without friction.
    required_bandwidth : float or None
        The scene's ``[requirements] bandwidth`` (Hz).
    lives : tuple of (str, numpy.ndarray)
        With a swept lead: each rated part's L10 (h) per factor; empty otherwise.
    required_life : float or None
        The duty cycle's ``required_life`` (h) the lives are held to.
    limits : tuple of dict
        Per motor: ``continuous_current`` (A, or None), ``peak_torque`` (N*m), ``no_load_speed``
        (rad/s), ``voltage`` (V), ``winding_temperature`` (K, or None without a network).
    swept : str
        What the factor multiplies, e.g. ``"ratio of spur gear train"`` or ``"1 / lead of
        ball screw"``.
    output_unit : str
        ``"rad"`` or ``"m"``.
    stiffness_unit : str
        The unit the stiffness is shown in (the scene's ``[display]``).
    stiffness_factor : float
        Shown units per SI unit of the stiffness.
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
    lives: tuple = ()
    required_life: float | None = None
    limits: tuple = ()
    swept: str = ""
    output_unit: str = "rad"
    stiffness_unit: str = "N*m/rad"
    stiffness_factor: float = 1.0
    limited_by: tuple = ()

    @property
    def ratio_unit(self) -> str:
        """The overall ratio's unit: motor rad per unit of the output."""
        return "rad/m" if self.output_unit == "m" else "rad/rad"

    @property
    def scene_ratio(self) -> float:
        """The scene's own overall ratio (factor 1)."""
        return float(self.ratio[0] / self.factors[0])

    def feasible_range(self, motor: int = 0) -> tuple | None:
        """(lowest, highest) feasible overall ratio of a motor, None when none is."""
        ok = self.feasible[motor]
        return (float(self.ratio[ok].min()), float(self.ratio[ok].max())) if ok.any() else None

    def limits_text(self, motor: int = 0) -> str:
        """What ends a motor's feasible ratios, e.g. ``"limited by the RMS current below, the
        peak voltage above"`` (an end at the sweep's range says so)."""
        low, high = self.limited_by[motor] if self.limited_by else (None, None)
        return f"limited by the {low or 'sweep range'} below, the {high or 'sweep range'} above"

    def to_dict(self) -> dict:
        """JSON-ready dictionary."""
        def arr(a):
            return [[None if not math.isfinite(v) else float(v) for v in row] for row in np.atleast_2d(a)]
        return {"factors": self.factors.tolist(), "ratio": self.ratio.tolist(), "motors": list(self.motors),
                "rms_current_A": arr(self.rms_current), "rms_torque_Nm": arr(self.rms_torque),
                "peak_torque_Nm": arr(self.peak_torque), "peak_speed_rad_s": arr(self.peak_speed),
                "peak_voltage_V": arr(self.peak_voltage), "winding_temperature_degC": arr(self.winding_temperature - 273.15),
                "bandwidth_estimate_Hz": arr(self.bandwidth), "swept": self.swept,
                "stiffness": self.stiffness if math.isfinite(self.stiffness) else None,
                "lives_h": {part: arr(hours)[0] for part, hours in self.lives}, "required_life_h": self.required_life,
                "feasible": self.feasible.tolist(),
                "feasible_ratio_range": [self.feasible_range(i) for i in range(len(self.motors))],
                "feasible_range_limited_by": [list(ends) for ends in self.limited_by], "ratio_unit": self.ratio_unit,
                "rms_optimal_ratio": list(self.rms_optimal_ratio), "required_bandwidth_Hz": self.required_bandwidth}

    def plot(self, axes=None):
        """The ratio choice on one figure (:func:`.sweep_plot.plot_sweep`); returns the axes."""
        from .sweep_plot import plot_sweep
        return plot_sweep(self, axes)


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


def bandwidth_estimate(chain, q0: float, node_inertia, factors) -> np.ndarray:
    """min(f_r / 3, f_a / 2) (Hz) of ``chain`` at ``q0`` with the motor node's inertia scaled:
    ``node_inertia(s)`` is that node's inertia (reflected to q) at each factor; nan for a
    rigid chain (module docstring)."""
    factors = np.asarray(factors, dtype=float)
    if chain.rigid:
        return np.full(factors.size, np.nan)
    M, K, keep = chain.condensed(q0)
    fa = float(chain.antiresonances(q0)[0]) / (2 * math.pi)
    m = np.diag(M).copy()
    fr = np.empty(factors.size)
    for i, j0 in enumerate(np.broadcast_to(node_inertia(factors), factors.shape)):
        m[0] = max(float(j0), 1e-12 * m.sum())
        w2 = np.sort(linalg.eigh(K, np.diag(m), eigvals_only=True))[1]
        fr[i] = math.sqrt(max(w2, 0.0)) / (2 * math.pi)
    return np.minimum(fr / 3, fa / 2)


def _swept(drivetrain) -> str:
    first = drivetrain.stages[0]
    return f"1 / lead of {first.name}" if isinstance(first, (BallScrew, RollerScrew)) else f"ratio of {first.name}"


def ratio_sweep(drivetrain, motion, loads, motors, factors, *, required_bandwidth=None, lives=None,
                required_life=None, display=None, thermal_steps: int = 200,
                fixed_limits_hold: bool = True) -> RatioSweep:
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
    lives : sequence of Life, optional
        The screw's lives at s = 1 when the first stage is the screw (its lead is swept).
    required_life : float, optional
        s; ratios where a life of ``lives`` falls short of it are not feasible.
    display : DisplayUnits, optional
        The scene's ``[display]``: the unit the stiffness is shown in.
    thermal_steps : int
        Intervals per cycle of the thermal integration.
    fixed_limits_hold : bool
        Whether the limits no factor changes hold (a roller screw's static load; the screw's
        lives behind a gear, which leaves the screw's speed as it is): when one fails, no
        ratio is feasible.
    """
    from ...display.units import DisplayUnits
    display = display or DisplayUnits()
    s = np.asarray(factors, dtype=float)[:, None]
    rest, shaft, j_shaft = split_torque(drivetrain, motion, loads)
    n = loads.ratio
    dn = _dn(drivetrain, motion)
    rotor0 = drivetrain.motor.rotor_inertia
    q0 = float(motion.q[0])
    node0 = float(np.diag(drivetrain.chain.condensed(q0)[0])[0]) if not drivetrain.chain.rigid else 0.0
    w1 = n * motion.qd
    rows = {k: [] for k in ("rms_current", "rms_torque", "peak_torque", "peak_speed", "peak_voltage",
                            "winding_temperature", "bandwidth", "feasible")}
    optimal, limits, ends = [], [], []
    life_rows = tuple((life.part, life.hours / s[:, 0]) for life in (lives or ()))
    life_ok = np.full(s.size, bool(fixed_limits_hold))
    if required_life is not None:
        for _, hours in life_rows:
            life_ok &= hours >= required_life / 3600
    for _, motor in motors:
        # the candidate's rotor replaces the scene's in the shaft's torque and on the motor node
        extra = motor.rotor_inertia - rotor0
        t_shaft = shaft + extra * (n * motion.qdd + dn * motion.qd**2)
        env = Envelope.of(motor)
        net = ThermalNetwork.from_motor(motor)
        # a few factors at a time: (factors x samples) arrays stay within CHUNK_ELEMENTS
        step = max(1, CHUNK_ELEMENTS // max(1, w1.size))
        rms_t, peak_t, peak_w, peak_u, temp = (np.concatenate(c) for c in zip(*(
            _figures(motor, env, net, s[a:a + step], rest, t_shaft, w1, motion, thermal_steps)
            for a in range(0, s.shape[0], step))))
        j_shaft_m = float(j_shaft[0]) + extra * float(n[0]) ** 2
        bw = bandwidth_estimate(drivetrain.chain, q0, lambda f: node0 + (f**2 - 1) * j_shaft_m
                                + extra * float(n[0]) ** 2, s[:, 0])
        # where each limit fails (nan passes only the bandwidth: a rigid chain has no estimate)
        fails = {"peak torque": ~(peak_t <= env.peak_torque), "peak voltage": ~(peak_u <= motor.voltage_limit),
                 "required life": ~life_ok}
        if env.continuous_torque is not None:
            fails["RMS current"] = ~(rms_t <= env.continuous_torque)
        if net is not None:
            fails["winding temperature"] = ~(temp <= motor.max_winding_temperature)
        if required_bandwidth is not None:
            fails["required bandwidth"] = bw < required_bandwidth
        ok = ~np.any(list(fails.values()), axis=0)
        ends.append(_limited_by(s[:, 0], ok, fails))
        for key, value in zip(rows, (rms_t / motor.torque_constant, rms_t, peak_t, peak_w, peak_u, temp, bw, ok)):
            rows[key].append(value)
        a2, b2 = motion.mean(rest**2), motion.mean(t_shaft**2)
        optimal.append(float(n[0] * (a2 / b2) ** 0.25) if b2 > 0 else math.inf)
        limits.append({"continuous_current": None if env.continuous_torque is None
                       else env.continuous_torque / motor.torque_constant,
                       "peak_torque": env.peak_torque, "no_load_speed": env.no_load_speed,
                       "voltage": motor.voltage_limit,
                       "winding_temperature": motor.max_winding_temperature if net is not None else None})
    arrays = {k: np.array(v) for k, v in rows.items()}
    stiff = float(drivetrain.stiffness([q0]).total[0])
    linear = drivetrain.output_unit == "m"
    return RatioSweep(factors=s[:, 0], ratio=s[:, 0] * float(n[0]), motors=tuple(m for m, _ in motors),
                      stiffness=stiff, rms_optimal_ratio=tuple(optimal), required_bandwidth=required_bandwidth,
                      lives=life_rows, required_life=None if required_life is None else required_life / 3600,
                      limits=tuple(limits), swept=_swept(drivetrain), output_unit=drivetrain.output_unit,
                      stiffness_unit=display.stiffness_unit(linear),
                      stiffness_factor=display.factor("stiffness", linear), limited_by=tuple(ends), **arrays)


def _limited_by(factors, ok, fails: dict) -> tuple:
    """(lower, upper): the names of the limits in ``fails`` (name -> where it fails) at the
    factor next below the lowest feasible one and next above the highest, None at the
    sweep's end or when no factor is feasible."""
    order = np.argsort(factors, kind="stable")
    inside = np.flatnonzero(ok[order])
    if not inside.size:
        return None, None

    def at(k):
        if k < 0 or k >= order.size:
            return None
        return " and ".join(name for name, where in fails.items() if where[order[k]]) or None
    return at(inside[0] - 1), at(inside[-1] + 1)


def _figures(motor, env, net, s, rest, t_shaft, w1, motion, thermal_steps: int) -> tuple:
    """(RMS torque, peak torque, peak speed, peak voltage, winding temperature) of ``motor`` at
    the factors ``s`` (a column), each an array over the factors."""
    torque = rest / s + s * t_shaft + motor.viscous_friction * s * w1 + motor.coulomb_friction * np.sign(w1)
    speed = s * w1
    current = torque / motor.torque_constant
    rms_t = np.sqrt(np.sum(torque**2 * motion.weight, axis=1) / motion.duration)
    peak_t = np.abs(torque).max(axis=1)
    peak_w = np.abs(speed).max(axis=1)
    peak_u = np.abs(env.hot_resistance * current + motor.back_emf_constant * speed).max(axis=1)
    if net is None:
        temp = np.full(s.shape[0], np.nan)
    else:
        i2, h = interval_i2(current, motion.weight, thermal_steps)
        temp = periodic_peak(net, i2, h)
    return rms_t, peak_t, peak_w, peak_u, temp


def _dn(drivetrain, motion) -> np.ndarray:
    return drivetrain.ratio(motion.q)[1]


__all__ = ["RatioSweep", "ratio_sweep", "split_torque", "bandwidth_estimate"]
