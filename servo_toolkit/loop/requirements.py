"""Loop requirements: the scene's ``[requirements]``, documented defaults, overrides, checks."""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..errors import SceneError
from ..core.units import parse_quantity
from ..display.html import telling_digits  # noqa: F401 - the requirement tables' digits

#: name -> (Requirements attribute, sense, unit shown, SI -> shown factor, default in shown units)
#: sense ">=" means the achieved figure must be at least the requirement.
SPECS = {
    "bandwidth": ("bandwidth", ">=", "Hz", 1.0, 5.0),
    "phase_lag_at_bandwidth": ("max_phase_lag_at_bandwidth", "<=", "deg", 180 / math.pi, 90.0),
    "gain_margin": ("min_gain_margin", ">=", "dB", 1.0, 6.0),
    "phase_margin": ("min_phase_margin", ">=", "deg", 180 / math.pi, 45.0),
    "sensitivity_peak": ("max_sensitivity_peak", "<=", "dB", 1.0, 6.0),
}
_PINT_UNITS = {"bandwidth": "Hz", "phase_lag_at_bandwidth": "deg", "gain_margin": "dB",
               "phase_margin": "deg", "sensitivity_peak": "dB"}
_ALIASES = {"max_phase_lag_at_bandwidth": "phase_lag_at_bandwidth", "min_gain_margin": "gain_margin",
            "min_phase_margin": "phase_margin", "max_sensitivity_peak": "sensitivity_peak",
            "phase_lag": "phase_lag_at_bandwidth", "ms": "sensitivity_peak", "gm": "gain_margin",
            "pm": "phase_margin"}


@dataclass(frozen=True)
class Requirement:
    """One requirement in display units.

    Attributes
    ----------
    name : str
    sense : str
        ``">="`` (achieved at least ``value``) or ``"<="``.
    value : float
    unit : str
    source : str
        ``"scene"``, ``"default"`` (the scene sets none) or ``"override"`` (command line).
    """

    name: str
    sense: str
    value: float
    unit: str
    source: str


@dataclass(frozen=True)
class Check:
    """A requirement against the achieved figure.

    Attributes
    ----------
    name, unit, sense, source : str
    required, achieved : float
    passed : bool
    shortfall : float
        By how much the requirement is missed (0 when passed), in ``unit``; NaN when the
        figure does not exist (``reason``).
    reason : str
        Why the requirement fails without a figure ("" otherwise): the closed loop is unstable,
        so it has no margin, Ms or bandwidth (:func:`unstable_checks`); ``achieved`` is NaN.
    """

    name: str
    required: float
    achieved: float
    passed: bool
    unit: str
    sense: str
    source: str
    shortfall: float
    reason: str = ""

    @property
    def achieved_text(self) -> str:
        """The achieved figure with its unit, or ``"unstable"`` when the loop has none."""
        if self.reason:
            return "unstable"
        return f"{self.achieved:.4g} {self.unit}".rstrip()

    def to_dict(self) -> dict:
        """JSON-ready (a figure that does not exist is NaN here, null in the JSON text)."""
        return {"required": self.required, "achieved": self.achieved, "passed": self.passed,
                "unit": self.unit, "sense": self.sense, "source": self.source,
                "shortfall": self.shortfall, "reason": self.reason or None}


#: name -> (lower bound, lower bound included, upper bound or None) in display units: the
#: scene loader's ``[requirements]`` rules (positive; a gain margin may be 0 dB), and a phase
#: margin below 180 deg (python-control's phase margins lie in [-180, 180) deg).
RULES = {
    "bandwidth": (0.0, False, None),
    "phase_lag_at_bandwidth": (0.0, False, None),
    "gain_margin": (0.0, True, None),
    "phase_margin": (0.0, False, 180.0),
    "sensitivity_peak": (0.0, False, None),
}

#: the bandwidths a loop design can aim at (Hz): the design and its checks evaluate the loop
#: on a frequency grid from 0.01 Hz to 5 kHz (a 10 kHz controller's Nyquist limit)
BANDWIDTH_RANGE = (0.01, 5000.0)


def validate(name: str, value: float, key: str | None = None) -> float:
    """``value`` (display units) if it is a valid requirement ``name``, else SceneError.

    Parameters
    ----------
    name : str
        Requirement name (a key of :data:`SPECS`).
    value : float
        In the requirement's display unit (Hz, deg or dB).
    key : str, optional
        Key path for the error; default ``require.<name>``.

    Raises
    ------
    SceneError
        NaN, infinite, not positive (a gain margin: negative), a phase margin of 180 deg
        or more, or a bandwidth outside :data:`BANDWIDTH_RANGE`.
    """
    key = key or f"require.{name}"
    unit = SPECS[name][2]
    lo, closed, hi = RULES[name]
    if math.isnan(value):
        raise SceneError(key, "value is NaN")
    if math.isinf(value):
        raise SceneError(key, f"must be finite (got {value:g} {unit})")
    if closed and not value >= lo:
        raise SceneError(key, f"must not be negative (got {value:g} {unit})")
    if not closed and not value > lo:
        why = (": |1 / (1 + L)| tends to 1 (0 dB) where the loop gain falls off, so the peak "
               "exceeds 0 dB" if name == "sensitivity_peak" else "")
        raise SceneError(key, f"must be positive{why} (got {value:g} {unit})")
    if hi is not None and not value < hi:
        raise SceneError(key, f"must be below {hi:g} {unit}: a {name.replace('_', ' ')} lies in "
                              f"[-180, 180) {unit} (got {value:g} {unit})")
    if name == "bandwidth" and not BANDWIDTH_RANGE[0] <= value <= BANDWIDTH_RANGE[1]:
        raise SceneError(key, f"must lie in [{BANDWIDTH_RANGE[0]:g}, {BANDWIDTH_RANGE[1]:g}] Hz, the frequencies "
                              f"the loop design evaluates (got {value:g} {unit})")
    return float(value)


def override_value(name: str, value) -> float:
    """An override in display units: a number (already in the display unit) or a string with
    units (``"200 Hz"``, ``"0.5 rad"``), checked with :func:`validate`."""
    key = f"require.{name}"
    if isinstance(value, str):
        text = value.strip()
        try:
            number = float(text)
        except ValueError:
            number = parse_quantity(text, _PINT_UNITS[name], key)
    else:
        number = parse_quantity(value, _PINT_UNITS[name], key)
    return validate(name, number, key)


def canonical_name(name: str) -> str:
    """The requirement's name in :data:`SPECS` (aliases such as ``pm`` resolved), else
    SceneError naming ``require.<name>``."""
    name = _ALIASES.get(name, name)
    if name not in SPECS:
        raise SceneError(f"require.{name}", f"unknown requirement; known: {sorted(SPECS)}")
    return name


def requirements_of(scene, overrides=None) -> list[Requirement]:
    """Every requirement of the design: the scene's, defaults where it sets none (stated as
    such) and ``overrides`` (name -> value in display units, or a string with units; checked
    like the command line's ``--require``, :func:`override_value`)."""
    given = scene.requirements
    out = []
    overrides = {canonical_name(k): v for k, v in dict(overrides or {}).items()}
    for name, (attr, sense, unit, factor, default) in SPECS.items():
        value = getattr(given, attr)
        if name in overrides:
            out.append(Requirement(name, sense, override_value(name, overrides[name]), unit, "override"))
        elif value is not None:
            out.append(Requirement(name, sense, value * factor, unit, "scene"))
        else:
            out.append(Requirement(name, sense, default, unit, "default"))
    return out


def parse_override(text: str) -> tuple[str, float]:
    """``"bandwidth=200Hz"`` -> ``("bandwidth", 200.0)`` in the requirement's display unit.

    A bare number is in the display unit (Hz, deg, dB). The value obeys the scene's
    ``[requirements]`` rules (:func:`validate`): every requirement positive, a gain margin
    may be 0 dB, a phase margin below 180 deg. Raises SceneError naming the option as typed
    (``--require bandwith=8Hz``) and the rule.
    """
    option = f"--require {text}"
    if "=" not in text:
        raise SceneError(option, "expected NAME=VALUE, e.g. bandwidth=200Hz")
    name, value = (part.strip() for part in text.split("=", 1))
    try:
        name = canonical_name(name)
        if not value:
            raise SceneError(option, f"missing value, e.g. {name}=... {SPECS[name][2]}")
        return name, override_value(name, value)
    except SceneError as exc:
        raise SceneError(option, exc.rule) from None


def parse_overrides(texts) -> dict:
    """Every ``--require NAME=VALUE`` of a command line (:func:`parse_override`) as
    ``{name: value}``; a requirement given twice (under any of its names) is refused naming
    both, rather than the last one silently winning."""
    out, given = {}, {}
    for text in texts:
        name, value = parse_override(text)
        if name in given:
            raise SceneError(f"--require {text}", f"{name} is already required by --require {given[name]}; "
                                                  "give each requirement once")
        out[name], given[name] = value, text
    return out


def check(requirements, achieved: dict) -> list[Check]:
    """Compare each requirement with ``achieved[name]`` (display units).

    An infinite figure is a limit with a meaning (no phase crossover: an infinite gain
    margin) and is judged; NaN is no figure at all (an unstable loop's requirements fail with
    its reason instead, :func:`unstable_checks`).

    Raises
    ------
    SimulationError
        An achieved figure is NaN: no verdict is given on it.
    """
    checks = []
    for r in requirements:
        a = float(achieved[r.name])
        if math.isnan(a):
            from ..errors import SimulationError
            raise SimulationError(f"{r.name}: the achieved figure is NaN, no verdict can be given on it")
        ok = a >= r.value if r.sense == ">=" else a <= r.value
        ok = bool(ok and math.isfinite(a)) if r.sense == "<=" else bool(ok)
        short = 0.0 if ok else (r.value - a if r.sense == ">=" else a - r.value)
        checks.append(Check(r.name, r.value, a, ok, r.unit, r.sense, r.source,
                            float(short) if math.isfinite(short) else math.inf))
    return checks


def unstable_checks(requirements, reason: str, suffix: str = "") -> list[Check]:
    """Each requirement failing on an unstable closed loop: no figure (``achieved`` and
    ``shortfall`` NaN), ``passed`` False and ``reason`` saying why. A margin, Ms or a
    bandwidth measures a stable loop; an unstable one has none, so no placeholder figure
    (0 dB, -inf deg) stands in for it. ``suffix`` is appended to each name
    (``"_over_stroke"``)."""
    return [Check(r.name + suffix, r.value, math.nan, False, r.unit, r.sense, r.source, math.nan, reason)
            for r in requirements]


#: robust requirement name -> (Robustness attribute, sense, unit shown, SI -> shown factor,
#: nominal requirement it defaults to or None)
ROBUST_SPECS = {
    "stable_fraction": ("min_stable_fraction", ">=", "", 1.0, None),
    "gain_margin": ("min_gain_margin", ">=", "dB", 1.0, "gain_margin"),
    "phase_margin": ("min_phase_margin", ">=", "deg", 180 / math.pi, "phase_margin"),
    "sensitivity_peak": ("max_sensitivity_peak", "<=", "dB", 1.0, "sensitivity_peak"),
    "bandwidth": ("min_bandwidth", ">=", "Hz", 1.0, None),
}


def robust_requirements(spec, nominal) -> list[Requirement]:
    """What the variants must achieve: the ``[robustness]`` table's values, else the nominal
    requirement of the same name (sources ``"robustness"`` and ``"nominal"``): every variant is held to the margins
    the nominal loop must have. ``stable_fraction`` defaults to 1 (every variant stable); a
    worst-case bandwidth is only checked when the table sets ``min_bandwidth``.

    Parameters
    ----------
    spec : Robustness
    nominal : list of Requirement or Check
        The nominal requirements (values in display units).
    """
    by_name = {r.name: (r.value if hasattr(r, "value") else r.required) for r in nominal}
    out = []
    for name, (attr, sense, unit, factor, default) in ROBUST_SPECS.items():
        value = getattr(spec, attr)
        if name == "stable_fraction":
            out.append(Requirement(name, sense, float(value), unit, "robustness"))
        elif value is not None:
            out.append(Requirement(name, sense, value * factor, unit, "robustness"))
        elif default is not None and default in by_name:
            out.append(Requirement(name, sense, by_name[default], unit, "nominal"))
    return out


def time_requirements(scene, spec, table: str) -> list[Requirement]:
    """The time-run requirements of a ``[robustness]`` or ``[tolerances]`` table ``spec``
    (named ``table``): its worst tracking error (``max_tracking_error``, in deg, or mm for an
    output travel) and worst peak current (``max_peak_current``, A); empty when it sets
    neither.

    Raises
    ------
    SceneError
        ``TABLE.max_tracking_error`` given as an angle for an output travel, or as a length
        for an output angle.
    """
    out = []
    if spec.max_tracking_error is not None:
        linear = scene.drivetrain.output_is_linear
        dim = spec.tracking_error_dimension
        if dim is not None and dim != ("length" if linear else "angle"):
            raise SceneError(f"{table}.max_tracking_error",
                             f"the output is {'a travel: give a length' if linear else 'an angle: give an angle'}, "
                             f"got {'an angle' if dim == 'angle' else 'a length'}")
        value = spec.max_tracking_error * 1e3 if linear else math.degrees(spec.max_tracking_error)
        out.append(Requirement("tracking_error", "<=", value, "mm" if linear else "deg", table))
    if spec.max_peak_current is not None:
        out.append(Requirement("peak_current", "<=", spec.max_peak_current, "A", table))
    return out
