"""One unit per quantity wherever a result is shown: the report, the CLI, JSON and Jupyter.

Stiffness at the output is in N*m/rad (N/m for an output travel), inertia in kg*m^2 (a mass
in kg for a travel), as :class:`servo_toolkit.core.output_units.OutputUnit` gives them and
``servo-toolkit design`` prints them; angles are shown in deg, frequencies in Hz. Axis
labels read ``quantity [unit]``; a dimensionless value carries no unit at all.

A scene may prefer other units for the reader (its ``[display]`` table, read into
:class:`DisplayUnits`): a stiffness in N*m/deg or N/um, an inertia in kg*cm^2. Tables,
cards, report figures and the CLI's text then show those; JSON stays SI.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import pint

from ..core.fields import Fields, unknown_key_rule
from ..core.output_units import OutputUnit
from ..core.units import UREG, parse_text
from ..errors import SceneError

#: the unit cell of a dimensionless value (a ratio, an efficiency, a damping ratio)
DIMENSIONLESS = ""

#: the value of a ``[display]`` key that keeps the SI unit (its default)
SI = "SI"

#: quantity -> ((what it is, an example) at an output angle, the same at an output travel)
PREFERENCES = {
    "stiffness": (("a torque per angle", "N*m/deg"), ("a force per length", "N/um")),
    "inertia": (("a moment of inertia, mass times length squared", "kg*cm^2"), ("a mass", "g")),
}


def _si(quantity: str, linear: bool) -> str:
    """The SI unit of ``quantity`` at the output."""
    u = OutputUnit("m" if linear else "rad")
    return u.stiffness if quantity == "stiffness" else u.inertia


def _angle_power(unit) -> float:
    """Exponent of the radian in ``unit``'s root units (pint counts an angle as dimensionless)."""
    _, root = UREG.get_root_units(unit)
    return float(dict(root._units).get("radian", 0))


@lru_cache(maxsize=64)
def _factor(si: str, unit: str) -> float:
    """Shown units per SI unit."""
    return float(UREG.Quantity(1.0, si).to(unit).magnitude)


@dataclass(frozen=True)
class DisplayUnits:
    """The units a reader sees for quantities at the output (a scene's ``[display]``).

    ``None`` (``"SI"`` in a scene) keeps the SI unit: N*m/rad and kg*m^2 at an output
    angle, N/m and kg at an output travel. Only what is shown changes: tables, cards,
    figures and text; results, JSON and the scene stay SI.

    Attributes
    ----------
    stiffness : str or None
        Unit of a stiffness at the output: a torque per angle at an output angle
        (``"N*m/deg"``, ``"kN*m/rad"``), a force per length at an output travel
        (``"N/um"``, ``"N/mm"``). Shown by ``servo-toolkit stiffness``, ``design`` and the
        report's stiffness tables and figures.
    inertia : str or None
        Unit of an inertia at the output: a moment of inertia at an output angle
        (``"kg*cm^2"``, ``"g*mm^2"``), a mass at an output travel (``"g"``). The motor's own
        rotor inertia stays in kg*m^2.
    """

    stiffness: str | None = None
    inertia: str | None = None

    def unit(self, quantity: str, linear: bool = False) -> str:
        """The unit shown for ``quantity`` (``"stiffness"`` or ``"inertia"``)."""
        return getattr(self, quantity) or _si(quantity, linear)

    def factor(self, quantity: str, linear: bool = False) -> float:
        """Shown units per SI unit of ``quantity`` (1 for the SI default)."""
        chosen = getattr(self, quantity)
        return 1.0 if chosen is None else _factor(_si(quantity, linear), chosen)

    def show(self, quantity: str, value, linear: bool = False):
        """An SI value (or array) of ``quantity`` in its shown unit."""
        return value * self.factor(quantity, linear)

    def stiffness_unit(self, linear: bool = False) -> str:
        """Unit shown for a stiffness at the output."""
        return self.unit("stiffness", linear)

    def inertia_unit(self, linear: bool = False) -> str:
        """Unit shown for an inertia (a mass at an output travel) at the output."""
        return self.unit("inertia", linear)

    def to_dict(self, linear: bool = False) -> dict:
        """``{"stiffness": unit, "inertia": unit}``: the units a reader is shown."""
        return {q: self.unit(q, linear) for q in PREFERENCES}


def display_units_from_table(f: Fields, linear: bool) -> DisplayUnits:
    """Read a scene's ``[display]`` table (absent: an empty table, everything SI).

    Parameters
    ----------
    f : Fields
        The ``[display]`` table: ``stiffness`` and ``inertia``, each a unit string, or
        ``"SI"`` (the default) for the SI unit of the output.
    linear : bool
        True when the scene's output is a travel (a stiffness is then a force per length,
        an inertia a mass).

    Raises
    ------
    SceneError
        Key ``display.NAME``: an unknown key, not a unit, or a unit of the wrong dimension
        (naming the dimension expected).
    """
    chosen = {name: _preference(f, name, linear) for name in PREFERENCES}
    unknown = sorted(set(f.table) - set(PREFERENCES))
    if unknown:
        raise SceneError(f.key(unknown[0]), unknown_key_rule(unknown[0], PREFERENCES))
    return DisplayUnits(**chosen)


def _preference(f: Fields, name: str, linear: bool) -> str | None:
    """A checked unit string for preference ``name`` (None for SI)."""
    text = f.text(name, SI)
    if text.strip() == SI:
        return None
    key = f.key(name)
    what, example = PREFERENCES[name][1 if linear else 0]
    coordinate = "an output travel" if linear else "an output angle"
    expected = f"expected a unit of {name} at {coordinate}, {what} such as '{example}'"
    if not isinstance(text, str) or not text.strip() or text.strip()[0].isdigit():
        raise SceneError(key, f"{expected} (got {text!r})")
    try:
        unit = parse_text(f"1 {text.strip()}", key).units
    except SceneError:
        raise SceneError(key, f"{expected}; unknown unit (got {text!r})") from None
    si = UREG.Unit(_si(name, linear))
    if UREG.Quantity(1.0, unit).dimensionality != UREG.Quantity(1.0, si).dimensionality \
            or _angle_power(unit) != _angle_power(si):
        raise SceneError(key, f"{expected} (got {text!r})")
    try:
        _factor(str(si), text.strip())
    except (pint.errors.PintError, ValueError, TypeError):  # pragma: no cover - checked above
        raise SceneError(key, f"{expected} (got {text!r})") from None
    return text.strip()


def stiffness_unit(linear: bool = False, display: DisplayUnits | None = None) -> str:
    """Unit of a stiffness at the output: the scene's preference, else SI (``"N*m/rad"``
    or ``"N/m"``)."""
    return (display or DisplayUnits()).stiffness_unit(linear)


def inertia_unit(linear: bool = False, display: DisplayUnits | None = None) -> str:
    """Unit of an inertia at the output: the scene's preference, else SI (``"kg*m^2"``,
    or ``"kg"`` for a travel)."""
    return (display or DisplayUnits()).inertia_unit(linear)


def label(quantity: str, unit: str = DIMENSIONLESS) -> str:
    """An axis or column label, ``"quantity [unit]"``; the bare quantity when dimensionless."""
    return f"{quantity} [{unit}]" if unit else quantity


__all__ = ["DIMENSIONLESS", "SI", "DisplayUnits", "display_units_from_table", "inertia_unit", "label",
           "stiffness_unit"]
