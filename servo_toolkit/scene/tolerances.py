"""``[tolerances]``: how every built actuator differs from the scene, as distributions of its
numeric keys, and what a fraction of them must achieve.

Any numeric key of the actuator (``motor.resistance``, ``drivetrain[2].stiffness``,
``load.hinge_moment``, ``sensors.output_encoder_bits``, ...) takes a distribution::

    [tolerances]
    samples = 1024                 # variants drawn
    method = "lhs"                 # "lhs" (Latin hypercube), "sobol" (scrambled) or "random"
    min_yield = 0.99               # fraction of the built actuators that must meet every requirement
    motor.resistance = "+-5 %"     # uniform about the scene's value (relative)
    motor.torque_constant = { sigma = "2 %" }          # normal about the scene's value
    "drivetrain[3].stiffness" = "1500 N*m/deg:1900 N*m/deg"   # uniform over a range
    load.inertia = [0.5, 4.0]      # uniform over [lo, hi] (SI, or strings with units)
    motor.coulomb_friction = "x0.5:x3"                 # factors of the scene's value

A range is ``"lo:hi"`` (each end a quantity, or ``xF`` a factor of the scene's value),
``[lo, hi]`` or ``{min, max}``; ``"+-X %"`` and ``"+-X unit"`` are ranges about the scene's
value. A positive range wider than a decade (``hi / lo > 10``) is sampled uniformly in its
logarithm, as the robustness study's ranges are. ``{sigma}`` (a quantity, or ``"X %"`` of
the mean) is a normal about ``mean`` (default the scene's value), truncated to the key's
physical range (its sign rule and the range its model is conditioned for,
:mod:`servo_toolkit.core.ranges`) and to ``min``/``max`` when given; the physical range alone
may cut at most :data:`IMPLICIT_CUT` of it (else the scene gives the end). Integer keys are
rounded. Every distribution is checked when the scene loads: an unknown key, a malformed
distribution, a sigma that is not positive or an end outside the key's conditioned range is
one line naming the key. Before a study draws variants it also builds the scene at each
end (a normal's mean +- 4 sigma within its truncation, :func:`check_ends`): an end at which
the scene itself does not load (the loader's own rules, e.g. Kt and Ke within 10 %) is one
line naming the key too.

``[robustness]`` ranges are tolerances too: ``load_inertia`` is ``load.inertia`` and the
stiffness factor is the virtual key ``drivetrain.stiffness_scale`` (a factor on the
drivetrain's series stiffness, nominal 1).
"""

from __future__ import annotations

import copy
import math
import re
from dataclasses import dataclass, field

import numpy as np

from ..errors import SceneError
from ..core.fields import Fields, require
from ..core.ranges import conditioned_range, range_rule
from ..core.units import parse_quantity

#: ``[tolerances]`` keys that are settings, not distributions
SETTINGS = ("samples", "method", "seed", "min_yield", "confidence", "max_tracking_error", "max_peak_current")
#: sampling methods (``scipy.stats.qmc``: Latin hypercube, scrambled Sobol; or independent draws)
METHODS = ("lhs", "sobol", "random")
#: distribution keys of a table value
DISTRIBUTION_KEYS = ("min", "max", "sigma", "mean")
DEFAULT_SAMPLES = 1024
#: a positive range wider than this ratio (hi / lo) is sampled uniformly in log(value)
LOG_RATIO = 10.0
#: a normal's mean +- this many sigma (within its truncation) must give a scene that loads
CHECKED_SIGMAS = 4.0
#: the smallest spread (a sigma, a range's half width) relative to the key's value: below it the
#: variants differ by rounding only
MIN_SPREAD = 1e-9
#: the largest probability a normal may lose to the key's physical range without a ``min`` or
#: ``max`` given (beyond 3.09 sigma)
IMPLICIT_CUT = 1e-3
#: virtual keys: not written in a scene, applied to the built drivetrain (unit, meaning)
STIFFNESS_SCALE = "drivetrain.stiffness_scale"
VIRTUAL = {STIFFNESS_SCALE: ("dimensionless", "factor on the drivetrain's series stiffness (nominal 1)")}
_PLUS_MINUS = re.compile(r"^\s*(\+-|\+/-|±)\s*(.+?)\s*$")
_PERCENT = re.compile(r"^\s*([0-9.eE+-]+)\s*%\s*$")
_FACTOR = re.compile(r"^\s*x\s*([0-9.eE+-]+)\s*$")


@dataclass(frozen=True)
class Tolerance:
    """The distribution of one scene key over the built actuators.

    Attributes
    ----------
    key : str
        Key path (``motor.resistance``) or a virtual key (``drivetrain.stiffness_scale``).
    unit : str
        SI unit of the values.
    nominal : float
        The scene's value (SI).
    distribution : {"uniform", "log_uniform", "normal"}
    low, high : float
        Uniform: the range; normal: its truncation.
    mean, sigma : float
        Normal only (NaN otherwise).
    integer : bool
        Values are rounded (an integer key).
    written : str
        The distribution as the scene gives it.
    """

    key: str
    unit: str
    nominal: float
    distribution: str
    low: float
    high: float
    mean: float = math.nan
    sigma: float = math.nan
    integer: bool = False
    written: str = ""

    def ppf(self, u) -> np.ndarray:
        """Values at probabilities ``u`` in (0, 1) (the inverse CDF)."""
        u = np.asarray(u, float)
        if self.distribution == "normal":
            from scipy.stats import truncnorm
            a, b = (self.low - self.mean) / self.sigma, (self.high - self.mean) / self.sigma
            x = truncnorm.ppf(u, a, b, loc=self.mean, scale=self.sigma)
        elif self.distribution == "log_uniform":
            x = np.exp(np.log(self.low) + u * (np.log(self.high) - np.log(self.low)))
        elif self.integer:
            x = np.floor(self.low + u * (self.high - self.low + 1.0))
        else:
            x = self.low + u * (self.high - self.low)
        x = np.clip(x, self.low, self.high)
        return np.round(x) if self.integer else x

    @property
    def ends(self) -> tuple:
        """The two extreme values a corner of the tolerance box takes: a range's ends, a
        normal's mean +- 3 sigma within its truncation."""
        if self.distribution == "normal":
            lo, hi = max(self.low, self.mean - 3 * self.sigma), min(self.high, self.mean + 3 * self.sigma)
            return (round(lo), round(hi)) if self.integer else (lo, hi)
        return self.low, self.high

    def describe(self) -> str:
        """One phrase, e.g. ``uniform 0.475..0.525 ohm`` or ``normal, sigma 0.004 N*m/A``."""
        unit = "" if self.unit in ("dimensionless", "1", "") else f" {self.unit}"
        if self.distribution == "normal":
            cut = [f"{v:.4g}" for v in (self.low, self.high)]
            return f"normal, mean {self.mean:.4g}, sigma {self.sigma:.4g}{unit} (truncated to {cut[0]}..{cut[1]})"
        kind = "log-uniform" if self.distribution == "log_uniform" else "uniform"
        return f"{kind} {self.low:.4g}..{self.high:.4g}{unit}"

    def to_dict(self) -> dict:
        """JSON-ready."""
        d = {"key": self.key, "unit": self.unit, "nominal": self.nominal, "distribution": self.distribution,
             "low": self.low, "high": self.high, "written": self.written}
        if self.distribution == "normal":
            d.update(mean=self.mean, sigma=self.sigma)
        return d


@dataclass(frozen=True)
class Tolerances:
    """The scene's tolerances and the yield they must give.

    Attributes
    ----------
    items : tuple of Tolerance
    samples : int
        Variants drawn.
    method : {"lhs", "sobol", "random"}
        Latin hypercube, scrambled Sobol (balanced for a power of 2) or independent draws.
    seed : int
        Seed of the draws.
    min_yield : float or None
        Fraction of the variants that must meet every requirement: ``check`` gates on the
        lower end of its Clopper-Pearson interval (None: no yield gate; the default of a
        ``[tolerances]`` table is 0.99, ``[robustness]`` sets none unless it gives one).
    confidence : float
        Two-sided confidence level of the yield interval.
    max_tracking_error, max_peak_current : float or None
        Requirements on the nonlinear time runs of the variants (rad or m; A), as in
        ``[robustness]``.
    tracking_error_dimension : str or None
    data : dict
        The scene's tables (without ``[tolerances]`` and ``[robustness]``): the variants
        are built from them.
    source : str or None
    build : callable
        The loader's ``scene_from_dict``, with which the variants are built.
    """

    items: tuple
    samples: int = DEFAULT_SAMPLES
    method: str = "lhs"
    seed: int = 0
    min_yield: float | None = 0.99
    confidence: float = 0.95
    max_tracking_error: float | None = None
    max_peak_current: float | None = None
    tracking_error_dimension: str | None = None
    data: dict = field(default_factory=dict, compare=False, repr=False)
    source: str | None = field(default=None, compare=False, repr=False)
    build: object = field(default=None, compare=False, repr=False)

    @property
    def keys(self) -> tuple:
        """Key paths, in order."""
        return tuple(t.key for t in self.items)

    def item(self, key: str) -> Tolerance:
        """The tolerance of ``key``."""
        return next(t for t in self.items if t.key == key)

    def scene_keys(self):
        """The scene's :class:`~.key_paths.SceneKeys` (variants are built from it)."""
        from .key_paths import SceneKeys
        return SceneKeys(self.data, self.source, self.build)


def _flatten(table: dict, prefix: str = ""):
    """(key path, distribution) pairs of the distribution part of ``[tolerances]``."""
    for k, v in table.items():
        key = f"{prefix}.{k}" if prefix else k
        if isinstance(v, dict) and v and not (set(v) & set(DISTRIBUTION_KEYS)):
            yield from _flatten(v, key)
        else:
            yield key, v


def _end(text, kp, where: str) -> float:
    """A range end: a quantity in the key's unit, or ``xF`` a factor of its value."""
    if isinstance(text, str):
        m = _FACTOR.match(text)
        if m:
            return float(m.group(1)) * kp.value
    if kp.integer and isinstance(text, (int, float)) and not isinstance(text, bool):
        return float(text)
    return parse_quantity(text, "dimensionless" if kp.unit == "1" else kp.unit, where)


def _spread(text: str, kp, where: str, center: float) -> float:
    """A half width or sigma: ``"X %"`` of ``|center|``, or a quantity."""
    m = _PERCENT.match(text) if isinstance(text, str) else None
    if m:
        return float(m.group(1)) / 100.0 * abs(center)
    return parse_quantity(text, "dimensionless" if kp.unit == "1" else kp.unit, where)


def _physical_range(kp) -> tuple:
    """(low, high) a value of ``kp`` may take: its sign rule and conditioned range."""
    if kp.integer:
        low = float(kp.rule.split()[-1]) if kp.rule and kp.rule.startswith("at least") else -math.inf
        return low, math.inf
    rng = conditioned_range(kp.unit, kp.bounds)
    if rng is None:
        return (0.0 if kp.rule in ("positive", "nonnegative") else -math.inf), math.inf
    low, high = rng
    if kp.rule == "positive" or kp.bounds is not None:
        return low, high
    if kp.rule == "nonnegative":
        return 0.0, high
    return -high, high


_EXPECTED = ("expected a range 'lo:hi' (ends with units, or xF a factor of the scene's value), [lo, hi], "
             "'+-X %', '+-X unit', {min, max} or a normal {sigma} (with optional mean, min, max)")


def parse_distribution(raw, kp, where: str) -> Tolerance:
    """The :class:`Tolerance` of key ``kp`` (a :class:`~.key_paths.KeyPath`) written ``raw``.

    Raises
    ------
    SceneError
        Naming ``where``: a malformed distribution, a sigma that is not positive, ends in
        the wrong order or outside the key's physical range.
    """
    nominal = kp.value
    written = raw if isinstance(raw, str) else repr(raw)
    mean, sigma, dist = math.nan, math.nan, "uniform"
    if isinstance(raw, str) and _PLUS_MINUS.match(raw):
        text = _PLUS_MINUS.match(raw).group(2)
        half = _spread(text, kp, where, nominal)
        require(not (nominal == 0 and _PERCENT.match(text)), where,
                f"{text} of the scene's value 0 is no spread: give the half width with a unit, or a range 'lo:hi'")
        require(half > 0 and math.isfinite(half), where, f"the half width must be positive and finite (got {half:g})")
        low, high = nominal - half, nominal + half
    elif isinstance(raw, str) and ":" in raw:
        a, _, b = raw.partition(":")
        low, high = _end(a.strip(), kp, where), _end(b.strip(), kp, where)
    elif isinstance(raw, list):
        require(len(raw) == 2, where, f"a range [lo, hi] has two values (got {len(raw)})")
        low, high = _end(raw[0], kp, where), _end(raw[1], kp, where)
    elif isinstance(raw, dict):
        unknown = sorted(set(raw) - set(DISTRIBUTION_KEYS))
        require(not unknown, where, f"unknown distribution key {unknown[0] if unknown else ''!r}; "
                                    f"known: {', '.join(DISTRIBUTION_KEYS)}")
        if "sigma" in raw:
            dist = "normal"
            mean = _end(raw["mean"], kp, where) if "mean" in raw else nominal
            require(not (mean == 0 and isinstance(raw["sigma"], str) and _PERCENT.match(raw["sigma"])), where,
                    f"a sigma of {raw['sigma']} of a mean of 0 is no spread: give sigma with a unit")
            sigma = _spread(raw["sigma"], kp, where, mean)
            require(sigma > 0 and math.isfinite(sigma), where, f"sigma must be positive and finite (got {sigma:g})")
            plo, phi = _physical_range(kp)
            low = _end(raw["min"], kp, where) if "min" in raw else plo
            high = _end(raw["max"], kp, where) if "max" in raw else phi
            require(low < mean < high, where, f"the mean {mean:g} must lie inside the truncation {low:g}..{high:g}")
            _implicit_cut(mean, sigma, low if "min" not in raw else -math.inf,
                          high if "max" not in raw else math.inf, kp, where)
        else:
            require("min" in raw and "max" in raw and "mean" not in raw, where,
                    "a table is a range {min, max} or a normal {sigma} (with optional mean, min, max)")
            low, high = _end(raw["min"], kp, where), _end(raw["max"], kp, where)
    else:
        raise SceneError(where, f"{_EXPECTED} (got {raw!r})")
    require(math.isfinite(low) and math.isfinite(high) or dist == "normal", where,
            f"the range must be finite (got {low:g}..{high:g})")
    require(low <= high, where, f"lo must not exceed hi (got {low:g} > {high:g})")
    if dist != "normal":
        require(high > low, where, f"the range is a single value ({low:g}): give a spread")
    spread = sigma if dist == "normal" else 0.5 * (high - low)
    scale = max(abs(v) for v in ((nominal, mean) if dist == "normal" else (nominal, low, high)) if math.isfinite(v))
    require(spread > MIN_SPREAD * scale, where,
            f"a spread of {spread:g} is below {MIN_SPREAD:g} of the value {scale:g}: the study cannot tell it "
            f"from none (give a real spread, or leave the key out)")
    for v in (low, high):
        _check_end(v, kp, where)
    if dist == "uniform" and low > 0 and high > LOG_RATIO * low and not kp.integer:
        dist = "log_uniform"
    unit = "dimensionless" if kp.unit in ("1", "") else kp.unit
    return Tolerance(kp.key, unit, nominal, dist, float(low), float(high), float(mean), float(sigma),
                     kp.integer, str(written))


def _implicit_cut(mean: float, sigma: float, low: float, high: float, kp, where: str) -> None:
    """A normal cut by the key's physical range (not by a ``min``/``max`` the scene gives)
    loses at most :data:`IMPLICIT_CUT` of its probability: a wider cut would change the
    distribution the scene states without saying so."""
    from scipy.stats import norm
    below, above = norm.cdf((low - mean) / sigma), norm.sf((high - mean) / sigma)
    for mass, end, side, key in ((below, low, "below", "min"), (above, high, "above", "max")):
        unit = "" if kp.unit in ("1", "", "dimensionless") else f" {kp.unit}"
        require(mass <= IMPLICIT_CUT, where,
                f"a normal of sigma {sigma:g}{unit} about {mean:g}{unit} puts {100 * mass:.3g} % of the variants "
                f"{side} the key's physical range ({end:g}{unit}): give {key} to truncate it where it is meant, "
                f"or a smaller sigma")


def _check_end(v: float, kp, where: str) -> None:
    """A value of the distribution's support obeys the key's sign rule and range."""
    if not math.isfinite(v):
        return
    if kp.integer:
        plo, _ = _physical_range(kp)
        require(v >= plo and float(v).is_integer(), where, f"an integer key: ends must be integers of at least "
                                                          f"{plo:g} (got {v:g})")
        return
    if kp.rule == "positive":
        require(v > 0, where, f"must be positive over the whole distribution (got an end at {v:g})")
    if kp.rule == "nonnegative":
        require(v >= 0, where, f"must not be negative over the whole distribution (got an end at {v:g})")
    broken = range_rule(v, kp.rule if kp.rule is not None or v <= 0 else "positive", kp.unit, kp.bounds)
    require(broken is None, where, f"an end of the distribution {broken}")


def _virtual(key: str, robust_value=None):
    from .key_paths import KeyPath
    unit, _ = VIRTUAL[key]
    return KeyPath(key, "drivetrain", key.split(".")[1], unit, 1.0, robust_value, "positive", None, False)


def _settings(table: dict, robust) -> dict:
    from .tables import UNPROVABLE_YIELD
    from .tracking import tracking_error as _tracking_error
    f = Fields({k: v for k, v in table.items() if k in SETTINGS}, "tolerances")
    samples = f.integer("samples", DEFAULT_SAMPLES, minimum=2)
    require(samples <= 1_000_000, f.key("samples"), f"at most 1000000 variants (got {samples})")
    out = dict(samples=samples, method=f.text("method", "lhs", choices=METHODS), seed=f.integer("seed", 0, minimum=0),
               min_yield=f.number("min_yield", 0.99, rule="positive", bounds=(1e-6, 1.0)),
               confidence=f.number("confidence", 0.95, rule="positive", bounds=(0.5, 0.999999)),
               max_peak_current=f.quantity("max_peak_current", "A", rule="positive") if f.has("max_peak_current")
               else (robust.max_peak_current if robust is not None else None),
               **(_tracking_error(f) or ({"max_tracking_error": robust.max_tracking_error,
                                          "tracking_error_dimension": robust.tracking_error_dimension}
                                         if robust is not None else {})))
    require(out["min_yield"] < 1.0, f.key("min_yield"), UNPROVABLE_YIELD)
    return out


def tolerances_of(data: dict, source, robust, scene, build):
    """The :class:`Tolerances` of ``scene`` (built from ``data``) from its ``[tolerances]``
    and the ranges of ``robust`` (its ``[robustness]``, a Robustness or None); None when it
    has neither; ``build`` is the loader's ``scene_from_dict``.

    Raises
    ------
    SceneError
        Naming ``tolerances.<key>`` (or ``robustness.<key>``) and the rule broken.
    """
    from .key_paths import KeyPath, SceneKeys
    table = data.get("tolerances")
    if table is None and robust is None:
        return None
    if table is not None and not isinstance(table, dict):
        raise SceneError("tolerances", f"expected a table, got {type(table).__name__}")
    keys = SceneKeys(data, source, build) if table else None
    items, where_of = [], {}
    for key, raw in _flatten({k: v for k, v in (table or {}).items() if k not in SETTINGS}):
        where = f"tolerances.{key}"
        require(key not in where_of, where, "given twice")
        kp = _virtual(key) if key in VIRTUAL else keys.resolve(key, where=where, what="a numeric key of this scene; "
                                                                                    "toleranced keys are:")
        items.append(parse_distribution(raw, kp, where))
        where_of[key] = where
    if robust is not None:
        unit = "kg" if scene.stages and scene.drivetrain.output_is_linear else "kg*m^2"
        for name, key in (("load_inertia", "load.inertia"), ("stiffness", STIFFNESS_SCALE)):
            rng = robust.ranges.get(name)
            if rng is None or not rng[1] > rng[0]:
                continue
            require(key not in where_of, f"robustness.{name}", f"also given as tolerances.{key}: give it once")
            kp = _virtual(key) if key in VIRTUAL else KeyPath(key, "load", "inertia", unit, scene.load.inertia,
                                                               None, "nonnegative", None, False)
            items.append(parse_distribution([float(rng[0]), float(rng[1])], kp, f"robustness.{name}"))
            where_of[key] = f"robustness.{name}"
    if table:
        settings = _settings(table, robust)
    else:
        settings = dict(samples=max(2, robust.samples), method="random", seed=robust.seed,
                        min_yield=robust.min_yield, max_tracking_error=robust.max_tracking_error,
                        max_peak_current=robust.max_peak_current,
                        tracking_error_dimension=robust.tracking_error_dimension)
    if not items:
        require(table is None, "tolerances", "no distribution given: name at least one key, e.g. "
                                             "motor.resistance = '+-5 %'")
        return None
    body = {k: copy.deepcopy(v) for k, v in data.items() if k not in ("tolerances", "robustness")}
    return Tolerances(tuple(items), data=body, source=source, build=build, **settings)


def check_ends(tolerances) -> None:
    """The scene loads at both ends of every tolerance (a normal: its mean +- 4 sigma
    within its truncation), the others at the scene's values: no variant breaks a rule of
    the loader (Kt and Ke within 10 %, a linkage that reaches, ...). Run before a study
    draws its variants (each end builds the scene once).

    Raises
    ------
    SceneError
        Naming ``tolerances.<key>``, the end and the loader's rule.
    """
    keys = tolerances.scene_keys()
    for t in tolerances.items:
        if t.key in VIRTUAL:
            continue
        lo, hi = t.ends if t.distribution != "normal" else (
            max(t.low, t.mean - CHECKED_SIGMAS * t.sigma), min(t.high, t.mean + CHECKED_SIGMAS * t.sigma))
        for v in (lo, hi):
            try:
                keys.scene({t.key: v})
            except SceneError as exc:
                raise SceneError(f"tolerances.{t.key}", f"the scene does not load at {v:.6g} {t.unit}: "
                                                        f"{exc.key}: {exc.rule}") from None


__all__ = ["CHECKED_SIGMAS", "DEFAULT_SAMPLES", "IMPLICIT_CUT", "MIN_SPREAD", "LOG_RATIO", "METHODS", "SETTINGS", "STIFFNESS_SCALE", "Tolerance",
           "Tolerances", "VIRTUAL", "check_ends", "parse_distribution", "tolerances_of"]
