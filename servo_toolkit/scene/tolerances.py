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
may cut at most :data:`~.distributions.IMPLICIT_CUT` of it (else the scene gives the end);
a mean at ``min`` or ``max`` is a half-normal (``{ sigma = "0.01 N*m", min = "x1" }``: a
friction that can only grow).
Integer keys are rounded. Every distribution is checked when the scene loads: an unknown key, a malformed
distribution, a sigma that is not positive or an end outside the key's conditioned range is
one line naming the key. Before a study draws variants it also builds the scene at each
end (a normal's mean +- 4 sigma within its truncation, :func:`check_ends`): an end at which
the scene itself does not load (the loader's own rules, e.g. Kt and Ke within 10 %) is one
line naming the key too. The controller's sample time (``sensors.sample_time``) is the
design's, not a tolerance (:data:`FIXED`): it is refused naming the key.

``[robustness]`` ranges are tolerances too: ``load_inertia`` is ``load.inertia`` and the
stiffness factor is the virtual key ``drivetrain.stiffness_scale`` (a factor on the
drivetrain's series stiffness, nominal 1).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field

from ..errors import SceneError
from ..core.fields import Fields, require
from .distributions import (DISTRIBUTION_KEYS, IMPLICIT_CUT, LOG_RATIO, MIN_SPREAD, Tolerance,
                            parse_distribution)

#: ``[tolerances]`` keys that are settings, not distributions
SETTINGS = ("samples", "method", "seed", "min_yield", "confidence", "max_tracking_error", "max_peak_current")
#: sampling methods (``scipy.stats.qmc``: Latin hypercube, scrambled Sobol; or independent draws)
METHODS = ("lhs", "sobol", "random")
DEFAULT_SAMPLES = 1024
#: a normal's mean +- this many sigma (within its truncation) must give a scene that loads
CHECKED_SIGMAS = 4.0
#: virtual keys: not written in a scene, applied to the built drivetrain (unit, meaning)
STIFFNESS_SCALE = "drivetrain.stiffness_scale"
VIRTUAL = {STIFFNESS_SCALE: ("dimensionless", "factor on the drivetrain's series stiffness (nominal 1)")}
#: numeric keys that are the design's, not a tolerance of the built actuators: key -> why, and
#: what to do instead (the one line the loader gives)
FIXED = {"sensors.sample_time": (
    "the controller's sample time is the design's, not a tolerance: the designed controller is discretized "
    "at it and the time runs sample it at a whole number of integration steps, while a drive clock's drift "
    "(tens of ppm) moves the sampling delay's phase by as little; leave it out, and compare sample times by "
    "designing and checking a scene for each")}


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
        kp = _virtual(key) if key in VIRTUAL else keys.resolve(
            key, where=where, what="a numeric key of this scene that can take a tolerance", excluded=FIXED)
        require(kp.key not in FIXED, where, FIXED.get(kp.key, ""))
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


__all__ = ["CHECKED_SIGMAS", "DEFAULT_SAMPLES", "IMPLICIT_CUT", "LOG_RATIO", "METHODS", "MIN_SPREAD", "SETTINGS",
           "STIFFNESS_SCALE", "FIXED", "Tolerance", "Tolerances", "VIRTUAL", "check_ends", "parse_distribution",
           "tolerances_of"]
