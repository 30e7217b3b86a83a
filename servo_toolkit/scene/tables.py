"""The scene's tables that are no component: ``[sensors]``, ``[requirements]``,
``[robustness]`` and each ``[studies.NAME]``, read and validated into frozen descriptions
(:mod:`servo_toolkit.scene.loader` assembles the scene from them)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from types import MappingProxyType

from ..core.fields import Fields, require, unknown_key_rule
from ..core.ranges import VARIED
from ..core.units import is_bare_number, read_as
from ..errors import SceneError
from .time_requirements import TimeRequirements
from .tracking import tracking_error as _tracking_error

#: the values a bare number (rad) for a phase key is plausible in: 0.5 deg .. 360 deg
PHASE_TYPICAL = (math.radians(0.5), 2 * math.pi)


def check_phase_margin(f: Fields, name: str, value: float | None) -> None:
    """A phase margin must lie below 180 deg; a refused one says how it was read (a bare
    number is in rad: ``45`` is 45 rad = 2578 deg)."""
    if value is None or value < math.pi:
        return
    raw = f.table.get(name)
    got = read_as(raw, value, "rad") if is_bare_number(raw) else f"got {math.degrees(value):.4g} deg"
    raise SceneError(f.key(name), f"must be below 180 deg: a phase margin lies in [-180, 180) deg ({got})")


#: the rule of a required yield of 1
UNPROVABLE_YIELD = ("a yield of 1 cannot be shown by any number of variants (the lower end of its interval, on "
                    "which the gate judges, stays below 1): give less than 1, e.g. 0.999")

#: the rule of an output sensor for the output's dimension (an angle's encoder, a travel's scale)
OUTPUT_SENSOR_RULE = {
    "output_encoder_bits": "an output encoder counts 2**bits per revolution of an output angle, and this "
                           "scene's output is a travel (m): read it with output_scale_resolution, a length "
                           "per count (e.g. \"1 um\"), or give 0",
    "output_scale_resolution": "a linear scale's length per count reads an output travel, and this scene's "
                               "output is an angle (rad): read it with output_encoder_bits (2**bits counts "
                               "per revolution), or give 0",
}

#: speed signals the speed loop can use (``[sensors] speed_estimator``)
SPEED_ESTIMATORS = ("ideal", "difference", "kalman")
#: ``[robustness] method`` values
ROBUSTNESS_METHODS = ("monte_carlo", "grid")


@dataclass(frozen=True)
class Sensors:
    """Position sensing and sampling.

    Parameters
    ----------
    output_encoder_bits : int
        Output encoder of an output angle, counts per revolution = 2**bits (0 = ideal); an
        output travel is read by ``output_scale_resolution`` instead.
    output_scale_resolution : float
        Linear scale reading an output travel: its length per count (m; 0 = ideal); an
        output angle is read by ``output_encoder_bits`` instead.
    motor_encoder_counts : int
        Motor encoder counts per revolution (0 = ideal).
    sample_time : float
        Controller sample time (s); 0 = continuous.
    speed_estimator : str
        Motor speed fed to the speed loop: ``"ideal"`` (the true speed, a tachometer-grade
        signal), ``"difference"`` (backward difference of the motor encoder counts over one
        sample) or ``"kalman"`` (a Kalman filter on the motor encoder counts, see
        :mod:`servo_toolkit.loop.encoder_estimators`). The last two need a motor encoder and a sample time.
    """

    output_encoder_bits: int = 0
    output_scale_resolution: float = 0.0
    motor_encoder_counts: int = 0
    sample_time: float = 0.0
    speed_estimator: str = "ideal"

    def output_count(self, linear: bool, path: str = "sensors") -> float:
        """The output sensor's count in the output's unit (rad for an angle, m for a travel;
        0: the output read ideally): ``2 pi / 2**output_encoder_bits`` of an angle,
        ``output_scale_resolution`` of a travel.

        Raises
        ------
        SceneError
            The sensor of the other dimension is given (an encoder's bits on a travel, a
            scale's resolution on an angle), naming its key and the rule.
        """
        wrong = "output_encoder_bits" if linear else "output_scale_resolution"
        require(not getattr(self, wrong), f"{path}.{wrong}", OUTPUT_SENSOR_RULE[wrong])
        if linear:
            return self.output_scale_resolution
        return 2 * math.pi / 2**self.output_encoder_bits if self.output_encoder_bits else 0.0

    @classmethod
    def from_table(cls, f: Fields, linear: bool = False) -> "Sensors":
        """Build from a ``[sensors]`` table; ``linear``: the output is a travel (its sensor is
        a linear scale, :meth:`output_count`)."""
        s = cls(output_encoder_bits=f.integer("output_encoder_bits", 0, minimum=0),
                output_scale_resolution=f.quantity("output_scale_resolution", "m", 0.0, rule="nonnegative",
                                                   bounds=(1e-12, 0.01), typical=(1e-9, 1e-3)),
                motor_encoder_counts=f.integer("motor_encoder_counts", 0, minimum=0),
                sample_time=f.quantity("sample_time", "s", 0.0, rule="nonnegative", typical=(1e-6, 0.02)),
                speed_estimator=f.text("speed_estimator", "ideal", choices=SPEED_ESTIMATORS))
        f.check_unknown()
        require(s.output_encoder_bits <= 64, f.key("output_encoder_bits"),
                f"must be at most 64 (got {s.output_encoder_bits}): counts per turn are 2**bits")
        s.output_count(linear, f.path)
        require(s.motor_encoder_counts <= 2**40, f.key("motor_encoder_counts"),
                f"must be at most 2**40 (got {s.motor_encoder_counts})")
        require(s.sample_time <= 1.0, f.key("sample_time"), f"must be at most 1 s (got {s.sample_time:g} s)")
        if s.speed_estimator != "ideal" and (s.motor_encoder_counts == 0 or s.sample_time == 0):
            raise SceneError(f.key("speed_estimator"), f"{s.speed_estimator!r} estimates the speed "
                             "from motor encoder counts: it needs motor_encoder_counts > 0 and "
                             "sample_time > 0")
        return s


@dataclass(frozen=True)
class Requirements:
    """Loop requirements; ``None`` where the scene sets none.

    Bandwidth in Hz, angles in rad, levels in dB; ``time`` holds what the nonlinear closed
    loop must do in time (:class:`~.time_requirements.TimeRequirements`).

    Attributes
    ----------
    bandwidth : float or None
        Closed-loop -3 dB bandwidth the loop must reach (Hz; default 5 Hz); also the
        frequency of the requirement sine the nonlinear rows run.
    max_phase_lag_at_bandwidth : float or None
        Largest closed-loop phase lag at that bandwidth (rad in, deg shown; default 90 deg).
    min_gain_margin : float or None
        Smallest gain margin at every phase crossing and over the stroke (dB, 0 or more;
        default 6 dB).
    min_phase_margin : float or None
        Smallest phase margin at every gain crossing and over the stroke (rad in, deg shown,
        below 180 deg; default 45 deg).
    max_sensitivity_peak : float or None
        Largest sensitivity peak Ms = max |1 / (1 + L)| (dB, positive; default 6 dB).
    step_amplitude : float or None
        The nonlinear rows' step (an angle, or a length for an output travel; default 1 deg
        or 0.5 mm).
    sine_amplitude : float or None
        The requirement sine's amplitude (an angle or a length; default the sweep study's,
        else 2 deg or 1 mm cut to what the actuator follows at the bandwidth).
    max_overshoot : float or None
        Largest overshoot of the nonlinear step, a fraction of it (e.g. "20 %"; default 20 %).
    max_settling_time : float or None
        Longest time (s) for the nonlinear step to stay within its band (2 % of the step, or
        the error allowed at rest when larger; default 4 periods of the bandwidth).
    max_position_error_at_rest : float or None
        Largest |command - output| at rest after the step (an angle or a length; default 2 %
        of the step).
    max_limit_cycle : float or None
        Largest amplitude of an oscillation or a hunting after the step (an angle or a
        length; default 2 % of the step).
    max_tracking_error : float or None
        Largest |command - output| over the requirement sine's last 3 of 8 periods (an angle
        or a length; default 1.25 x the linear closed loop's).
    max_current_ripple : float or None
        Largest rms of the motor current above 10 x the sine's frequency, at rest after the
        step or in the sine (A; default 10 % of the continuous current, else 5 % of the
        current limit).
    max_rms_current : float or None
        Largest rms motor current over the sine's judged periods (A; default the motor's
        continuous current, checked only when the motor gives one).
    max_time_at_current_limit : float or None
        Longest time the current spends within 1 % of its limit in the sine after its first
        2 periods (s; default 0).
    max_time_at_voltage_limit : float or None
        The same for the armature voltage (s; default 0).
    """

    bandwidth: float | None = None
    max_phase_lag_at_bandwidth: float | None = None
    min_gain_margin: float | None = None
    min_phase_margin: float | None = None
    max_sensitivity_peak: float | None = None
    time: TimeRequirements = TimeRequirements()

    @classmethod
    def from_table(cls, f: Fields) -> "Requirements":
        """Build from a ``[requirements]`` table."""
        def opt(name, unit, rule="positive", typical=None):
            return f.quantity(name, unit, rule=rule, typical=typical) if f.has(name) else None
        r = cls(bandwidth=opt("bandwidth", "Hz"),
                max_phase_lag_at_bandwidth=opt("max_phase_lag_at_bandwidth", "rad", typical=PHASE_TYPICAL),
                min_gain_margin=opt("min_gain_margin", "dB", "nonnegative"),
                min_phase_margin=opt("min_phase_margin", "rad", typical=PHASE_TYPICAL),
                max_sensitivity_peak=opt("max_sensitivity_peak", "dB"),
                time=TimeRequirements.from_fields(f))
        f.check_unknown()
        check_phase_margin(f, "min_phase_margin", r.min_phase_margin)
        return r


@dataclass(frozen=True)
class Robustness:
    """Parameter variations the loop must tolerate, and what it must achieve over them.

    Variations are at the design operating point: ``load_inertia`` replaces the load's
    inertia (kg*m^2 at the output), ``stiffness`` multiplies the drivetrain's series
    stiffness. A margin left ``None`` defaults to the nominal ``[requirements]`` one (see
    :func:`servo_toolkit.loop.requirements.robust_requirements`).

    Parameters
    ----------
    load_inertia : tuple of float or None
        (lo, hi) in kg*m^2, 0 <= lo <= hi.
    stiffness : tuple of float or None
        (lo, hi) factors, 0 < lo <= hi.
    samples : int
        Variants in total (Monte Carlo draws, or grid points spread over the axes: the same
        number on each, the nearest whole root of ``samples``, so 200 over two ranges is a
        14 x 14 grid of 196; the notes and rows give the count run).
    method : str
        ``"monte_carlo"`` (uniform, seeded) or ``"grid"`` (corners included).
    seed : int
    min_stable_fraction : float
        Fraction of the variants whose closed loop must be stable, 0..1.
    min_gain_margin, max_sensitivity_peak : float or None
        Worst case over the stable variants (dB).
    min_phase_margin : float or None
        Worst case (rad).
    min_bandwidth : float or None
        Worst-case closed-loop bandwidth (Hz); not checked when ``None``.
    max_tracking_error : float or None
        Worst |output - command| over the nonlinear time runs of the variants
        (``servo-toolkit montecarlo``; rad, or m for an output travel); not checked when
        ``None``.
    tracking_error_dimension : str or None
        ``"angle"`` or ``"length"`` as the scene gave it (None for a bare SI number).
    max_peak_current : float or None
        Worst peak motor current over those runs (A); not checked when ``None``.
    min_yield : float or None
        Fraction of the built actuators (the ranges drawn as tolerances,
        :mod:`servo_toolkit.scene.tolerances`) that must meet every requirement; ``check``
        gates on the lower end of its confidence interval. Not checked when ``None``.
    """

    load_inertia: tuple | None = (0.0, 4.0)
    stiffness: tuple | None = (0.7, 1.3)
    samples: int = 1000
    method: str = "monte_carlo"
    seed: int = 0
    min_stable_fraction: float = 1.0
    min_gain_margin: float | None = None
    min_phase_margin: float | None = None
    max_sensitivity_peak: float | None = None
    min_bandwidth: float | None = None
    max_tracking_error: float | None = None
    tracking_error_dimension: str | None = None
    max_peak_current: float | None = None
    min_yield: float | None = None

    @property
    def ranges(self) -> dict:
        """name -> (lo, hi) of the parameters that vary."""
        return {k: v for k, v in (("load_inertia", self.load_inertia), ("stiffness", self.stiffness))
                if v is not None}

    @classmethod
    def from_table(cls, f: Fields) -> "Robustness":
        """Build from a ``[robustness]`` table."""
        known = {"load_inertia", "stiffness", "samples", "method", "seed", "min_stable_fraction",
                 "min_gain_margin", "min_phase_margin", "max_sensitivity_peak", "min_bandwidth",
                 "max_tracking_error", "max_peak_current", "min_yield"}
        unknown = sorted(set(f.table) - known)
        require(not unknown, f.key(unknown[0]) if unknown else "", unknown_key_rule(unknown[0] if unknown else "", known))

        def span(name, unit, positive):
            if not f.has(name):
                return None
            lo_hi = f.quantity_list(name, unit, rule="positive" if positive else "nonnegative", bounds=VARIED[name])
            require(len(lo_hi) == 2, f.key(name), f"expected [lo, hi], got {len(lo_hi)} values")
            require(lo_hi[0] <= lo_hi[1], f.key(name), f"lo must not exceed hi (got {lo_hi[0]:g} > {lo_hi[1]:g})")
            return lo_hi

        def opt(name, unit, rule="positive"):
            return f.quantity(name, unit, rule=rule) if f.has(name) else None

        load, stiff = span("load_inertia", "kg*m^2", False), span("stiffness", "dimensionless", True)
        require(load is not None or stiff is not None, f.key("load_inertia"),
                "missing key: give load_inertia and/or stiffness, the ranges to vary")
        samples = f.integer("samples", 1000, minimum=1)
        require(samples <= 1_000_000, f.key("samples"), f"at most 1000000 variants (got {samples})")
        r = cls(load_inertia=load, stiffness=stiff, samples=samples,
                method=f.text("method", "monte_carlo", choices=ROBUSTNESS_METHODS),
                seed=f.integer("seed", 0, minimum=0),
                min_stable_fraction=f.number("min_stable_fraction", 1.0, rule="nonnegative"),
                min_gain_margin=opt("min_gain_margin", "dB", "nonnegative"),
                min_phase_margin=f.quantity("min_phase_margin", "rad", rule="positive", typical=PHASE_TYPICAL)
                if f.has("min_phase_margin") else None,
                max_sensitivity_peak=opt("max_sensitivity_peak", "dB"),
                min_bandwidth=opt("min_bandwidth", "Hz"), max_peak_current=opt("max_peak_current", "A"),
                min_yield=f.number("min_yield", rule="positive", bounds=(1e-6, 1.0)) if f.has("min_yield") else None,
                **_tracking_error(f))
        require(r.min_yield is None or r.min_yield < 1.0, f.key("min_yield"), UNPROVABLE_YIELD)
        require(r.min_stable_fraction <= 1.0, f.key("min_stable_fraction"),
                f"a fraction of the variants, 0..1 (got {r.min_stable_fraction:g})")
        check_phase_margin(f, "min_phase_margin", r.min_phase_margin)
        return r


@dataclass(frozen=True)
class Study:
    """A named study of the scene: its kind and parameters in SI (angles rad, Hz for frequency)."""

    name: str
    kind: str
    params: MappingProxyType

    def get(self, key: str, default=None):
        """A parameter or ``default``."""
        return self.params.get(key, default)

    def key(self, name: str) -> str:
        """Key path of a parameter, for error messages."""
        return f"studies.{self.name}.{name}"


__all__ = ["ROBUSTNESS_METHODS", "SPEED_ESTIMATORS", "Requirements", "Robustness", "Sensors", "Study"]
