"""The speed-loop gain the actuator allows: the play's limit cycle and the encoder's
quantization, each judged by the current ripple it costs against an allowance
(:mod:`.backlash_df` for the physics)."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from .backlash_df import LimitCycle, backlash_limit_cycle, quantization_ripple

#: default allowance of the current ripple (rms) from either effect, the rule of ``check``'s
#: ``current_ripple`` row (:mod:`servo_toolkit.studies.actuator.spec`): of the motor's
#: continuous current when it gives one, else of its current limit
RIPPLE_OF_CONTINUOUS, RIPPLE_OF_LIMIT = 0.10, 0.05
#: the cap leaves this margin below the gain that would just meet the allowance
CAP_MARGIN = 0.95


@dataclass(frozen=True)
class FilteredSpeed:
    """The motor encoder's speed through a constant-gain Kalman filter instead of the
    difference over one sample, at the same speed gain: what the filter buys and costs.

    Attributes
    ----------
    ripple : float
        rms current of the quantization through the filter's speed estimate (A).
    extra_lag_deg : float
        Phase the filter's estimate lags the difference's at ``crossover_hz`` (deg).
    crossover_hz : float
        The speed loop's crossover Kv Kt / J_m (Hz).
    jerk : float
        The filter's jerk level (motor rad/s^3, :func:`.encoder_estimators.default_jerk`).
    """

    ripple: float
    extra_lag_deg: float
    crossover_hz: float
    jerk: float

    def to_dict(self) -> dict:
        return {"ripple_A_rms": self.ripple, "extra_lag_deg": self.extra_lag_deg,
                "crossover_Hz": self.crossover_hz, "jerk_rad_s3": self.jerk}


def filtered_speed(scene, speed_gain: float, counts: int, sample_time: float, q0: float) -> FilteredSpeed | None:
    """:class:`FilteredSpeed` of a motor encoder with ``counts`` per revolution at the speed
    gain ``speed_gain`` (A per motor rad/s); None without an encoder or a gain."""
    if counts <= 0 or sample_time <= 0 or speed_gain == 0:
        return None
    import numpy as np

    from .encoder_estimators import default_jerk, speed_noise_rms, speed_response, steady_state_gain
    motor = scene.motor
    jm = float(scene.drivetrain.motor_inertia([q0])[0])
    lsb = 2 * math.pi / counts
    jerk = default_jerk(motor.torque_constant, motor.current_limit, jm, speed_gain, sample_time)
    try:
        F, _, K = steady_state_gain(sample_time, lsb, jerk)
    except (np.linalg.LinAlgError, ValueError):  # no stationary filter at this sample time
        return None
    fc = abs(speed_gain) * motor.torque_constant / jm / (2 * math.pi)
    z = np.exp(2j * math.pi * fc * sample_time)
    difference = (1 - 1 / z) / (sample_time * 2j * math.pi * fc)
    lag = math.degrees(float(np.angle(difference / speed_response(F, K, sample_time, fc)[0])))
    return FilteredSpeed(ripple=abs(speed_gain) * speed_noise_rms("kalman", lsb, sample_time, F, K),
                         extra_lag_deg=lag, crossover_hz=fc, jerk=jerk)


@dataclass(frozen=True)
class ActuatorBounds:
    """What the play and the motor encoder allow the speed loop, for one design.

    Attributes
    ----------
    allowance : float
        Current ripple allowed from either effect (A rms).
    allowance_source : str
        Where the allowance comes from (the default's rule, or "given").
    speed_gain : float
        The design's speed-path gain Kv (A per motor rad/s).
    counts : int
        Motor encoder counts per revolution (0: none, no quantization bound).
    sample_time : float
        s.
    quantization : float
        rms current of the encoder's quantization at ``speed_gain`` (A).
    half_play : float
        Half the lost motion at the output (rad, or m).
    play_deg : float or None
        The stages' backlash as the scene gives it, for the notes (None: none).
    limit_cycle : LimitCycle or None
        The describing-function limit cycle of the play in this loop (None: none predicted).
    capped_from : float or None
        The speed gain the unbounded search chose, when the bound lowered it.
    output_unit : {"rad", "m"}
    filtered : FilteredSpeed or None
        The encoder's speed through a Kalman filter at ``capped_from`` (the gain the
        quantization took away), or at ``speed_gain`` without a cap: what a filter buys
        (None: no encoder, or the scene's speed estimator is already the filter).
    """

    allowance: float
    allowance_source: str
    speed_gain: float
    counts: int
    sample_time: float
    quantization: float
    half_play: float
    limit_cycle: LimitCycle | None
    capped_from: float | None = None
    output_unit: str = "rad"
    filtered: FilteredSpeed | None = None

    @property
    def limit_cycle_current(self) -> float:
        """rms current of the predicted limit cycle (A; 0 without one)."""
        return 0.0 if self.limit_cycle is None else self.limit_cycle.current_rms

    @property
    def met(self) -> bool:
        """Both ripples within the allowance."""
        return self.quantization <= self.allowance and self.limit_cycle_current <= self.allowance

    @property
    def speed_gain_max(self) -> float:
        """The speed gain within the allowance, both ripples scaled with the gain (the
        quantization's exactly, the limit cycle's as a first estimate the redesign checks)."""
        worst = max(self.quantization, self.limit_cycle_current)
        return math.inf if worst <= 0 else self.speed_gain * self.allowance / worst

    def _show(self, x: float) -> str:
        return f"{x * 1e6:.3g} um" if self.output_unit == "m" else f"{math.degrees(x):.3g} deg"

    def notes(self) -> tuple:
        """Sentences an engineer reads: each bound, what it costs and what would relax it."""
        out = []
        kv = self.speed_gain
        if self.capped_from is not None:
            out.append(f"speed-loop gain lowered from {self.capped_from:.4g} to {kv:.4g} A*s/rad (per motor rad/s) "
                       f"to keep the current ripple within {self.allowance:.3g} A rms ({self.allowance_source})")
        if self.counts > 0 and self.sample_time > 0:
            lsb = 2 * math.pi / self.counts
            text = (f"motor encoder {self.counts} counts/rev at {self.sample_time * 1e3:.3g} ms: its quantization "
                    f"(LSB {lsb:.3g} rad, variance LSB^2/12, differenced over one sample) reaches the current "
                    f"through the speed gain {kv:.4g} A*s/rad (per motor rad/s) as {self.quantization:.3g} A rms")
            if self.quantization > self.allowance:
                need = math.ceil(self.counts * self.quantization / self.allowance)
                text += (f", over the {self.allowance:.3g} A allowance by {self.quantization - self.allowance:.3g} A: "
                         f"the encoder limits the speed-loop gain to {kv * self.allowance / self.quantization:.4g} "
                         f"A*s/rad (per motor rad/s); {need} counts/rev (or a filtered speed estimate) would allow {kv:.4g}")
            else:
                text += f", within the {self.allowance:.3g} A allowance"
            out.append(text)
        fs = self.filtered
        at = self.capped_from if self.capped_from is not None else kv
        if fs is not None and quantization_ripple(at, self.counts, self.sample_time) > self.allowance:
            out.append(f"a Kalman speed estimate ([sensors] speed_estimator = \"kalman\", jerk {fs.jerk:.3g} rad/s^3) "
                       f"at the speed gain {at:.4g} A*s/rad (per motor rad/s) would carry {fs.ripple:.3g} A rms of the quantization "
                       f"({'within' if fs.ripple <= self.allowance else 'over'} the {self.allowance:.3g} A allowance) "
                       f"at {abs(fs.extra_lag_deg):.3g} deg {'more' if fs.extra_lag_deg >= 0 else 'less'} phase lag than the "
                       f"difference at the speed loop's crossover ({fs.crossover_hz:.3g} Hz)")
        if self.half_play > 0:
            lc = self.limit_cycle
            head = f"play {self._show(2 * self.half_play)} at the output"
            if lc is None:
                out.append(f"{head}: the describing function of the play against the loop it sees (the motor side "
                           "under the controller, the load held by its friction or damping) predicts no limit "
                           "cycle")
            else:
                text = (f"{head}: the describing function predicts a limit cycle of the motor side, "
                        f"+-{self._show(lc.amplitude)} at {lc.frequency_hz:.3g} Hz (the load +-"
                        f"{self._show(lc.load_amplitude)}), costing {lc.current_rms:.3g} A rms")
                if lc.current_rms > self.allowance:
                    text += (f", over the {self.allowance:.3g} A allowance: the play limits the speed-loop gain to "
                             f"about {kv * self.allowance / lc.current_rms:.3g} A*s/rad (per motor rad/s); the current scales with the "
                             f"play (a play of {self._show(2 * self.half_play * self.allowance / lc.current_rms)} "
                             "would meet it), and a position measured on the motor side takes the play out of the "
                             f"loop (no limit cycle, a position error up to +-{self._show(self.half_play)})")
                out.append(text)
        return tuple(out)

    def table(self) -> str:
        """Text rows for :meth:`DesignResult.table`."""
        rows = [f"  actuator bounds on the speed loop (allowance {self.allowance:.3g} A rms, {self.allowance_source}):",
                f"    speed gain {self.speed_gain:.4g} A*s/rad per motor rad/s; encoder ripple {self.quantization:.3g} A rms; "
                + ("no play limit cycle" if self.limit_cycle is None else
                   f"play limit cycle {self.limit_cycle.frequency_hz:.3g} Hz, {self.limit_cycle_current:.3g} A rms")
                + f"; {'met' if self.met else 'NOT met'}"]
        return "\n".join(rows)

    def to_dict(self) -> dict:
        """SI: A, A*s/rad, s, output rad or m."""
        return {"allowance_A_rms": self.allowance, "allowance_source": self.allowance_source,
                "speed_gain_A_s_per_rad": self.speed_gain, "motor_encoder_counts": self.counts,
                "quantization_ripple_A_rms": self.quantization, "half_play": self.half_play,
                "limit_cycle": None if self.limit_cycle is None else self.limit_cycle.to_dict(),
                "limit_cycle_current_A_rms": self.limit_cycle_current, "met": self.met,
                "speed_gain_max_A_s_per_rad": self.speed_gain_max, "capped_from_A_s_per_rad": self.capped_from,
                "filtered_speed": None if self.filtered is None else self.filtered.to_dict()}


def ripple_allowance(scene, given: float | None = None) -> tuple:
    """``(A rms, where it comes from)``: ``given``, the scene's ``max_current_ripple`` or the
    default (:data:`RIPPLE_OF_CONTINUOUS`, :data:`RIPPLE_OF_LIMIT`)."""
    if given is not None:
        return given, "given"
    scene_value = scene.requirements.time.max_current_ripple
    if scene_value is not None:
        return scene_value, "the scene's max_current_ripple"
    motor = scene.motor
    if motor.continuous_torque is not None:
        i_cont = motor.continuous_torque / motor.torque_constant
        return (RIPPLE_OF_CONTINUOUS * i_cont,
                f"default: {100 * RIPPLE_OF_CONTINUOUS:g} % of the {i_cont:.3g} A continuous current")
    return (RIPPLE_OF_LIMIT * motor.current_limit,
            f"default: {100 * RIPPLE_OF_LIMIT:g} % of the {motor.current_limit:g} A current limit")


def actuator_bounds(scene, result, allowance: float | None = None, delay_response=None,
                    capped_from: float | None = None) -> ActuatorBounds | None:
    """The bounds of a cascade design (``result.motion``); None for another structure.

    Parameters
    ----------
    scene : Scene
    result : DesignResult
    allowance : float, optional
        Current ripple allowed (A rms); default the scene's ``[requirements]
        max_current_ripple``, else :data:`RIPPLE_OF_CONTINUOUS` of the continuous current
        (``continuous_torque`` / Kt), else :data:`RIPPLE_OF_LIMIT` of the current limit.
    delay_response : callable, optional
        s -> the sampling delay's response (default none).
    capped_from : float, optional
        The speed gain before a cap, for the notes.
    """
    motion = result.motion
    if motion is None or motion.structure != "cascade":
        return None
    p = result.parameters
    allowance, source = ripple_allowance(scene, allowance)
    kv = motion.gains["kv"] / p.N
    sensors = scene.sensors
    counts = sensors.motor_encoder_counts if sensors.speed_estimator in ("ideal", "difference") else 0
    ts = sensors.sample_time
    half = 0.5 * float(scene.drivetrain.backlash([p.q0])[0])
    gains = (result.controller.current_kp, result.controller.current_ki)
    lc = None
    if delay_response is None:  # no sampling delay given: the continuous loop
        def delay_response(s):
            return 1.0 + 0.0 * s
    if half > 0 and not p.rigid:
        lc = backlash_limit_cycle(p, motion, gains, delay_response, half)
    filtered = filtered_speed(scene, capped_from if capped_from is not None else kv, counts, ts, p.q0)
    return ActuatorBounds(allowance=allowance, allowance_source=source, speed_gain=kv, counts=counts,
                          sample_time=ts, quantization=quantization_ripple(kv, counts, ts), half_play=half,
                          limit_cycle=lc, capped_from=capped_from, output_unit=scene.drivetrain.output_unit,
                          filtered=filtered)


def bounded(scene, result, search, allowance, delay_response, rounds: int = 3):
    """``result`` with its :class:`ActuatorBounds` (``result.actuator``, the notes): where the
    speed gain costs more ripple than the allowance, ``search(kv_cap)`` (the nominal search
    with the speed gain capped, A per output rad/s) is redone at :data:`CAP_MARGIN` of the
    gain the bounds allow, up to ``rounds`` times while the capped design still misses."""
    b = actuator_bounds(scene, result, allowance, delay_response)
    if b is None:
        return result
    first = b.speed_gain
    for _ in range(rounds):
        if b.met or not math.isfinite(b.speed_gain_max):
            break
        capped = search(CAP_MARGIN * b.speed_gain_max * result.parameters.N)
        nb = actuator_bounds(scene, capped, allowance, delay_response, capped_from=first)
        if nb is None:
            break
        result, b = capped, nb
    return replace(result, actuator=b, notes=tuple(result.notes) + b.notes())


__all__ = ["ActuatorBounds", "CAP_MARGIN", "FilteredSpeed", "filtered_speed", "RIPPLE_OF_CONTINUOUS", "RIPPLE_OF_LIMIT", "actuator_bounds", "bounded",
           "ripple_allowance"]
