"""What every drivetrain stage provides: a kinematic map, inertial elements, springs, lash.

Sign and coordinate conventions
-------------------------------
A *backward* stage (gears, screws, linkages) maps its output coordinate ``z`` to its input
coordinate ``x(z)``; the chain is walked from the load back to the motor. A *forward* stage
(a cam) maps its input ``z`` to its output ``y(z)``; it ends a chain, and the generalized
coordinate is then its input. Every element, spring and lash of a stage is located by a
coordinate ``u(z)`` with derivatives; the drivetrain composes them with the chain rule.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..core.fields import field_value, require
from ..errors import SceneError

#: efficiencies the loss models are conditioned for: below 1 % a stage's loss torque dwarfs
#: what it transmits and the lumped chain becomes singular
EFFICIENCY_RANGE = (0.01, 1.0)
#: damping ratios a compliance's damper is conditioned for (0 is allowed: an undamped spring)
DAMPING_RATIO_RANGE = (1e-4, 1.0)


def read_damping_ratio(f, stiffness: float, stiffness_key: str):
    """The stage's ``damping_ratio`` key (None when absent): the damping ratio of its
    compliance, refused on a stage without one (``stiffness_key`` not given or infinite)."""
    ratio = f.number("damping_ratio", None, rule="nonnegative", bounds=DAMPING_RATIO_RANGE)
    require(ratio is None or math.isfinite(stiffness), f.key("damping_ratio"),
            f"damps the stage's compliance: give {stiffness_key} too (the stage is rigid)")
    return ratio


def read_stroke(f, unit: str, what: str):
    """The stage's ``stroke`` key: ``[lowest, highest]`` of its output in ``unit`` (``"m"``
    for a nut's travel, ``"rad"`` for a shaft's angle), None when absent. ``what`` names the
    output in the rule (``"nut travel"``)."""
    if f.raw("stroke", None) is None:
        return None
    stroke = tuple(f.quantity_list("stroke", unit, rule="finite"))
    require(len(stroke) == 2 and stroke[0] < stroke[1], f.key("stroke"),
            f"must be [lowest, highest] {what} with lowest < highest")
    return stroke


def check_fields(component, rules: dict, prefix: str) -> None:
    """Check and convert, in place, the fields of a frozen ``component`` that ``rules`` names
    (``{field: (unit, rule)}``), however it was made (the scene file, ``dataclasses.replace``,
    a constructor call): each value a real number in SI or a pint Quantity (converted, a tuple
    of units: the first its dimension fits), a tuple field element by element; ``rule`` as
    :func:`~servo_toolkit.core.fields.check_rule`, or ``"efficiency"`` (within
    :data:`EFFICIENCY_RANGE`) or ``"stroke"`` (two finite ends, lowest < highest). A field
    that is None (not given) is left as it is. SceneError naming ``prefix.field``."""
    for name, (unit, rule) in rules.items():
        value = getattr(component, name)
        if value is None:
            continue
        key = f"{prefix}.{name}"
        if isinstance(value, (tuple, list)):
            each = "finite" if rule == "stroke" else rule
            value = tuple(field_value(v, unit, each, f"{key}[{i}]") for i, v in enumerate(value))
            require(rule != "stroke" or len(value) == 2 and value[0] < value[1], key,
                    f"must be (lowest, highest) with lowest < highest (got {value})")
        elif rule == "efficiency":
            value = field_value(value, unit, "positive", key)
            low, high = EFFICIENCY_RANGE
            require(low <= value <= high, key, f"must be within [{low:g}, {high:g}] (got {value:g})")
        else:
            value = field_value(value, unit, rule, key)
        object.__setattr__(component, name, value)


def made(cls, f, **fields):
    """``cls(**fields)`` for a scene table read by ``f``: a rule the component's
    ``__post_init__`` finds broken (named ``ClassName.field``) is named by the table's key
    (``drivetrain[0].efficiency``; ``stroke_range`` is the key ``stroke``, ``inertias`` the
    key ``inertia``)."""
    try:
        return cls(**fields)
    except SceneError as exc:
        prefix, _, field = exc.key.partition(".")
        if prefix != cls.__name__:
            raise
        name, bracket, index = field.partition("[")
        key = f.key({"stroke_range": "stroke", "inertias": "inertia"}.get(name, name))
        raise SceneError(key + bracket + index, exc.rule) from None


def require_friction_values(f, values: dict, finite: tuple, unit: str = "") -> None:
    """The scene table's friction values (read by ``f`` into ``values``) checked before the
    component is made: each key of ``finite`` finite, and the breakaway level (the
    ``static_friction``, or the ``coulomb_friction`` where none is given) finite and at least
    the Coulomb level; ``unit`` shown after the figures. SceneError naming the table's key."""
    for key in finite:
        require(math.isfinite(values[key]), f.key(key), "must be finite")
    coulomb = values["coulomb_friction"]
    breakaway = coulomb if values["static_friction"] is None else values["static_friction"]
    shown = f" {unit}" if unit else ""
    require(math.isfinite(breakaway) and breakaway >= coulomb, f.key("static_friction"),
            f"must be finite and at least the coulomb_friction {coulomb:g}{shown} (got {breakaway:g}{shown})")


def check_breakaway(friction, key: str) -> None:
    """SceneError naming ``key`` unless ``friction``'s breakaway level (its
    ``static_friction``, or its ``coulomb_friction`` where none is given) is at least its
    Coulomb level."""
    require(friction.breakaway >= friction.coulomb_friction, key,
            f"must be at least the coulomb_friction {friction.coulomb_friction:g} (got {friction.breakaway:g})")


@dataclass(frozen=True)
class Jet:
    """A coordinate and its first two derivatives with respect to a parameter."""

    value: np.ndarray
    d1: np.ndarray
    d2: np.ndarray

    @classmethod
    def linear(cls, z, gain: float, offset: float = 0.0) -> "Jet":
        """``u = gain * z + offset``."""
        z = np.asarray(z, dtype=float)
        return cls(gain * z + offset, np.full_like(z, gain), np.zeros_like(z))

    def compose(self, inner: "Jet") -> "Jet":
        """This jet (a function of z) evaluated along ``inner`` = z(q), as a jet in q."""
        return Jet(self.value, self.d1 * inner.d1, self.d2 * inner.d1**2 + self.d1 * inner.d2)


@dataclass(frozen=True)
class Element:
    """An inertial element: mass (kg) or inertia (kg*m^2) moving with coordinate ``u``.

    ``member`` places it in the lumped chain (:mod:`servo_toolkit.drivetrain.chain`):
    ``"input"`` for a stage's input member (a pinion, a screw: on the motor side of the
    stage's compliance and before its loss), ``"output"`` for its output member (beyond both).
    """

    label: str
    inertia: float
    u: Jet
    member: str = "output"


@dataclass(frozen=True)
class Spring:
    """A compliance of stiffness ``k`` (N/m or N*m/rad) acting on coordinate ``u``, with the
    damping ratio its stage gives it (None: the model's default structural damping; see
    :mod:`servo_toolkit.drivetrain.chain_damping`)."""

    label: str
    stiffness: float
    u: Jet
    damping_ratio: float | None = None


@dataclass(frozen=True)
class Lash:
    """Total free play ``lash`` (m or rad) on coordinate ``u``."""

    label: str
    lash: float
    u: Jet


def screw_backdrive_efficiency(eta: float) -> float:
    """Back-drive efficiency of a screw of forward efficiency ``eta``: ``2 - 1/eta``, the screw
    catalogues' relation for the same thread friction driven the other way (with lead angle l
    and friction angle r, eta = tan(l)/tan(l + r) and the back-drive tan(l - r)/tan(l), which
    it matches to second order in r); zero or less means self-locking."""
    return 2.0 - 1.0 / eta


class Stage:
    """Mixin with defaults; concrete stages are frozen dataclasses.

    A stage carries its own facts as class attributes, read by the scene loader, the
    drivetrain and the report, so that a new stage is one module here plus its tests:

    ``KIND``
        The scene's ``kind`` of the stage (``[[drivetrain]] kind = "..."``).
    ``IO``
        What it takes and gives, ``"rotary"`` or ``"travel"`` (None: as it finds it).
    ``UNITS``
        SI units of its input and output coordinates and of its spring's coordinate
        (``"rad"`` or ``"m"``; None: the coordinate it finds).
    ``RATIO_KEYS``
        The scene keys that set its ratio, for messages (None: it sets none).
    ``DISPLAY_UNITS``
        The report's units of its fields where they differ from the scene table's:
        ``((field, unit, factor from SI), ...)``.
    """

    direction = "backward"
    KIND = ""
    IO = (None, None)
    UNITS = ("rad", "rad", "rad")
    RATIO_KEYS = None
    DISPLAY_UNITS = ()

    @property
    def backdrive_efficiency(self) -> float:
        """Efficiency when the load drives the motor through this stage: the forward
        efficiency for a stage whose losses are mesh or joint friction proportional to the
        transmitted load (gears, linkages); screws override it."""
        return float(getattr(self, "efficiency", 1.0))

    def map(self, z) -> Jet:  # pragma: no cover - abstract
        """The other coordinate (input for backward, output for forward stages)."""
        raise NotImplementedError

    def elements(self, z) -> list[Element]:
        """Inertial elements located by the stage's local coordinate ``z``."""
        return []

    def springs(self, z) -> list[Spring]:
        """Compliances of this stage."""
        return []

    def lashes(self, z) -> list[Lash]:
        """Free play of this stage."""
        return []

    @property
    def stroke(self):
        """Admissible range of the local coordinate, or None."""
        return None
