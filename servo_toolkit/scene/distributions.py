"""The distributions of a ``[tolerances]`` table: one scene key's spread as written
(a range, ``"+-X %"``, a normal ``{sigma}``), read into a :class:`Tolerance` and checked
against the key's physical range (:mod:`servo_toolkit.core.ranges`): its sign rule, the
range its model is conditioned for, a normal the physical range alone would cut by more
than :data:`IMPLICIT_CUT`, a spread the study cannot tell from none (:data:`MIN_SPREAD`). A
normal whose mean is its ``min`` (``max``) is a half-normal: cut at its mean by construction."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

from ..errors import SceneError
from ..core.fields import require
from ..core.ranges import conditioned_range, range_rule
from ..core.units import parse_quantity

#: distribution keys of a table value
DISTRIBUTION_KEYS = ("min", "max", "sigma", "mean")
#: a positive range wider than this ratio (hi / lo) is sampled uniformly in log(value)
LOG_RATIO = 10.0
#: the smallest spread (a sigma, a range's half width) relative to the key's value: below it the
#: variants differ by rounding only
MIN_SPREAD = 1e-9
#: the largest probability a normal may lose to the key's physical range without a ``min`` or
#: ``max`` given (beyond 3.09 sigma)
IMPLICIT_CUT = 1e-3
#: a half-normal's far truncation closer than this many sigma to its mean is shown in its description
CHECKED_FAR = 6.0
#: equal-probability midpoints a distribution's variance is computed on
VARIANCE_POINTS = 1 << 16
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

    def variance(self, log: bool = False) -> float:
        """The variance of the distribution's values (of their logarithm with ``log``): the
        population's, not a sample's; from the inverse CDF at :data:`VARIANCE_POINTS`
        equal-probability midpoints (a range's (hi - lo)^2 / 12 to 1e-9 relative; a
        normal's truncation included; an integer key's steps to about 1e-4)."""
        x = self.ppf((np.arange(VARIANCE_POINTS) + 0.5) / VARIANCE_POINTS)
        return float(np.var(np.log(np.abs(x)) if log else x))

    @property
    def ends(self) -> tuple:
        """The two extreme values a corner of the tolerance box takes: a range's ends, a
        normal's mean +- 3 sigma within its truncation."""
        if self.distribution == "normal":
            lo, hi = max(self.low, self.mean - 3 * self.sigma), min(self.high, self.mean + 3 * self.sigma)
            return (round(lo), round(hi)) if self.integer else (lo, hi)
        return self.low, self.high

    @property
    def half(self) -> str:
        """``"above"`` (``"below"``) for a half-normal, a normal whose mean is its lower
        (upper) truncation; ``""`` otherwise."""
        if self.distribution != "normal":
            return ""
        return "above" if self.mean == self.low else ("below" if self.mean == self.high else "")

    def describe(self, unit: str | None = None, factor: float = 1.0) -> str:
        """One phrase, e.g. ``uniform 0.475..0.525 ohm`` or ``normal, sigma 0.004 N*m/A``.

        Parameters
        ----------
        unit : str, optional
            The unit to show the values in (default: :attr:`unit`, SI).
        factor : float
            Shown units per SI unit.
        """
        unit = self.unit if unit is None else unit
        unit = "" if unit in ("dimensionless", "1", "") else f" {unit}"
        low, high, mean, sigma = (v * factor for v in (self.low, self.high, self.mean, self.sigma))
        if self.half:
            far = high if self.half == "above" else low
            return f"half-normal {self.half} {mean:.4g}, sigma {sigma:.4g}{unit}" + (
                f" (truncated to {low:.4g}..{high:.4g})" if abs(far - mean) < CHECKED_FAR * sigma else "")
        if self.distribution == "normal":
            cut = [f"{v:.4g}" for v in (low, high)]
            return f"normal, mean {mean:.4g}, sigma {sigma:.4g}{unit} (truncated to {cut[0]}..{cut[1]})"
        kind = "log-uniform" if self.distribution == "log_uniform" else "uniform"
        return f"{kind} {low:.4g}..{high:.4g}{unit}"

    def to_dict(self) -> dict:
        """JSON-ready."""
        d = {"key": self.key, "unit": self.unit, "nominal": self.nominal, "distribution": self.distribution,
             "low": self.low, "high": self.high, "written": self.written}
        if self.distribution == "normal":
            d.update(mean=self.mean, sigma=self.sigma)
        return d


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


def _toml_value(raw) -> str:
    """``raw`` (a value of a TOML table) as it reads in the scene: an inline table
    ``{ sigma = "2 %", min = "x0.95" }``, a quoted text or a number."""
    if isinstance(raw, dict):
        return "{ " + ", ".join(f"{k} = {_toml_value(v)}" for k, v in raw.items()) + " }"
    if isinstance(raw, str):
        return '"' + raw.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(raw, bool):
        return "true" if raw else "false"
    return repr(raw)


def _physical_range(kp) -> tuple:
    """(low, high) a value of ``kp`` may take: its sign rule and conditioned range."""
    if kp.integer:
        low = float(kp.rule.split()[-1]) if kp.rule and kp.rule.startswith("at least") else -math.inf
        return low, math.inf
    rng = conditioned_range(kp.unit, kp.bounds)
    if rng is None:
        return (0.0 if kp.rule in ("positive", "nonnegative") else -math.inf), math.inf
    low, high = rng
    if kp.rule == "finite":  # signed: bounded in magnitude only, as the loader checks it
        return -high, high
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
    written = raw if isinstance(raw, str) else _toml_value(raw)
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
            require(low <= mean <= high and low < high, where,
                    f"the mean {mean:g} must lie inside the truncation {low:g}..{high:g} (or at one end of it: "
                    f"a half-normal)")
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
    # a signed key's range is its magnitude's upper end alone (no component bounds one)
    bounds = None if kp.rule == "finite" else kp.bounds
    broken = range_rule(v, kp.rule if kp.rule is not None or v <= 0 else "positive", kp.unit, bounds)
    require(broken is None, where, f"an end of the distribution {broken}")


__all__ = ["DISTRIBUTION_KEYS", "IMPLICIT_CUT", "LOG_RATIO", "MIN_SPREAD", "Tolerance", "parse_distribution"]
