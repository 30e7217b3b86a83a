"""The output coordinate's units: an angle (rad inside, deg shown) or a travel (m inside, mm shown).

An EMA's output is a shaft angle; a chain ending in a screw (a linear actuator) has an
output travel. Every command amplitude, tracking error and stroke figure is given and shown
in the output's unit: ``"2 deg"`` for an angle, ``"1 mm"`` for a travel; a bare number is
read in the shown unit (deg or mm).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import pint

from ..errors import SceneError
from .units import UREG, looks_like_quantity, parse_text

#: The requirement sine of seed 000, the one default command of the toolkit: its frequency (Hz),
#: its amplitude for an angle output (deg) and for a travel output (mm), and the length of a
#: default closed-loop run (s). Designs report the phase at this frequency; ``simulate``,
#: ``kv``, ``sweep`` and the report run it when a scene names no study.
REQUIREMENT_SINE_HZ = 8.0
REQUIREMENT_SINE_DEG = 2.0
REQUIREMENT_SINE_MM = 1.0
DEFAULT_RUN_S = 1.0


@dataclass(frozen=True)
class OutputUnit:
    """Units of an output coordinate.

    Attributes
    ----------
    si : {"rad", "m"}
        Unit of the coordinate inside the toolkit.
    """

    si: str = "rad"

    @property
    def linear(self) -> bool:
        """True for an output travel."""
        return self.si == "m"

    @property
    def shown(self) -> str:
        """Unit shown to users and used in JSON keys: ``"deg"`` or ``"mm"``."""
        return "mm" if self.linear else "deg"

    @property
    def factor(self) -> float:
        """Shown units per SI unit (180/pi or 1000)."""
        return 1e3 if self.linear else 180.0 / math.pi

    @property
    def default_amplitude(self) -> float:
        """The default command amplitude (SI): seed 000's 2 deg, or 1 mm for a travel."""
        return REQUIREMENT_SINE_MM * 1e-3 if self.linear else math.radians(REQUIREMENT_SINE_DEG)

    @property
    def largest_amplitude(self) -> float:
        """Largest command amplitude a study may ask for (SI): 180 deg or 10 m."""
        return 10.0 if self.linear else math.pi

    def show(self, value):
        """An SI value (or array) in the shown unit."""
        return value * self.factor

    @property
    def inertia(self) -> str:
        """Unit of an inertia at the output: ``"kg*m^2"`` for an angle, ``"kg"`` (a mass) for a travel."""
        return "kg" if self.linear else "kg*m^2"

    @property
    def stiffness(self) -> str:
        """Unit of a stiffness at the output: ``"N*m/rad"`` or ``"N/m"``."""
        return "N/m" if self.linear else "N*m/rad"

    @property
    def moment(self) -> str:
        """Unit of a load at the output: ``"N*m"`` or ``"N"``."""
        return "N" if self.linear else "N*m"

    def key(self, name: str) -> str:
        """A JSON key carrying the shown unit, e.g. ``key("max_abs_tracking_error")``."""
        return f"{name}_{self.shown}"

    def text(self, value: float, digits: int = 4) -> str:
        """An SI value as text in the shown unit (``"2 deg"``, ``"0.486 mm"``)."""
        return f"{self.show(value):.{digits}g} {self.shown}"

    def parse(self, value, key: str) -> float:
        """A command amplitude (SI) from ``"1 mm"``, ``"2 deg"`` or a bare number in the shown unit.

        Raises
        ------
        SceneError
            Not a number, an unknown unit, a unit of the other kind (a length for an
            angle output or the reverse), a ratio (``"10 %"``, ``"1000 ppm"``), not positive, or beyond :attr:`largest_amplitude`.
        """
        if isinstance(value, bool):
            raise SceneError(key, f"expected an amplitude in {self.shown}, got a boolean")
        if isinstance(value, str) and not looks_like_quantity(value):
            raise SceneError(key, f"expected an amplitude such as '{self._example}', got {value!r}")
        if isinstance(value, str):
            q = parse_text(value, key)
            if q.unitless and str(q.units) != "dimensionless":  # "10 %", "1000 ppm": pint's unitless ratios
                kind = "a travel" if self.linear else "an angle"
                raise SceneError(key, f"expected an amplitude in {self.shown} (e.g. '{self._example}'), "
                                      f"got {value!r}: a ratio is not {kind}")
            if q.unitless:  # a bare number: the shown unit
                q = UREG.Quantity(float(q.magnitude), self.shown)
            try:
                if self.linear and q.dimensionless:  # pint's angles are dimensionless
                    raise pint.errors.DimensionalityError(q.units, "m")
                si = float(q.to(self.si).magnitude)
            except pint.errors.DimensionalityError:
                kind = "a travel" if self.linear else "an angle"
                raise SceneError(key, f"the output is {kind}: give the amplitude in {self.shown} "
                                 f"(e.g. '{self._example}'), got {value!r}") from None
        elif isinstance(value, (int, float)):
            si = float(value) / self.factor
        else:
            raise SceneError(key, f"expected an amplitude in {self.shown}, got {type(value).__name__}")
        if not math.isfinite(si) or si <= 0:
            raise SceneError(key, f"must be positive and finite (got {value!r})")
        if si > self.largest_amplitude:
            raise SceneError(key, f"at most {self.text(self.largest_amplitude)} (got {value!r})")
        return si

    @property
    def _example(self) -> str:
        return "1 mm" if self.linear else "2 deg"


def output_unit(scene) -> OutputUnit:
    """The output unit of a scene (or of a drivetrain); an angle when it has no drivetrain."""
    try:
        dt = getattr(scene, "drivetrain", scene)
        linear = bool(getattr(dt, "output_is_linear", False))
    except SceneError:  # a mechanism-only scene: its studies use angles
        linear = False
    return OutputUnit("m" if linear else "rad")


__all__ = ["OutputUnit", "output_unit"]
