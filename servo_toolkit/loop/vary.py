"""The parameters a robustness study varies (``check --vary``, ``montecarlo --vary``, a
scene's ``[robustness]``): their names, the range their models are conditioned for, and
how a variant's values read with their units.

A load inertia is in kg*m^2 at an output angle (a mass in kg at an output travel) and is
shown in the scene's ``[display]`` inertia unit; a stiffness is a factor on the drivetrain's
series stiffness (``0.7 x nominal``). Every value is written in the toolkit's one number
format (:func:`servo_toolkit.display.html.fmt`).
"""

from __future__ import annotations

import math

from ..core.ranges import VARIED
from ..display.html import fmt
from ..display.units import DisplayUnits
from ..errors import SceneError

PARAMETERS = {"load_inertia": "kg*m^2 at the output (kg for a travel), replaces the scene's load inertia",
              "stiffness": "factor on the series stiffness"}

#: name -> (smallest nonzero value, largest value) a varied parameter's models are
#: conditioned for (:data:`servo_toolkit.core.ranges.VARIED`, as a scene's ``[robustness]``)
VARY_RANGES = VARIED


def parse_vary(text: str):
    """``"load_inertia=0:4"`` -> ``("load_inertia", (0.0, 4.0))``.

    Raises
    ------
    SceneError
        Naming the option as typed (``--vary NAME=LO:HI``): an unknown name, a range that is not ``LO:HI`` numbers with
        ``LO <= HI``, a negative load inertia, a stiffness factor that is not positive, or
        an end outside :data:`VARY_RANGES`.
    """
    option = f"--vary {text}"
    name, _, rng = text.partition("=")
    name = name.strip()
    if name not in PARAMETERS:
        raise SceneError(option, f"unknown parameter; known: {sorted(PARAMETERS)}")
    try:
        lo, hi = (float(v) for v in rng.split(":"))
    except ValueError:
        raise SceneError(option, f"expected LO:HI numbers, got {rng!r}") from None
    if not (math.isfinite(lo) and math.isfinite(hi)) or hi < lo or (name == "stiffness" and lo <= 0) or lo < 0:
        raise SceneError(option, f"need 0 <= LO <= HI (stiffness LO > 0), got {rng!r}")
    low, high = VARY_RANGES[name]
    for end in (lo, hi):
        if end != 0 and not low <= end <= high:
            what = "a load inertia in kg*m^2 (kg for a travel) of 0 or" if name == "load_inertia" else "a factor"
            raise SceneError(option, f"{what} in [{low:g}, {high:g}], the range the model is "
                                     f"conditioned for (got {rng})")
    return name, (lo, hi)


def _shown(name: str, value, display: DisplayUnits, linear: bool):
    """(value in its shown unit, unit text) of a varied parameter."""
    if name == "load_inertia":
        return display.show("inertia", value, linear), " " + display.inertia_unit(linear)
    if name == "stiffness":
        return value, " x nominal"
    return value, ""


def variant_text(values: dict, display: DisplayUnits | None = None, linear: bool = False, digits: int = 4,
                 index=None) -> str:
    """One variant's parameters with their units: ``load_inertia = 3.99 kg*m^2, stiffness =
    0.7 x nominal``.

    Parameters
    ----------
    values : dict
        name -> SI value, or name -> array of values with ``index`` the variant.
    display : DisplayUnits, optional
        The scene's ``[display]`` units (default SI).
    linear : bool
        The output is a travel (a load inertia is then a mass).
    digits : int
    index : int, optional
    """
    display = display or DisplayUnits()
    parts = []
    for name, v in values.items():
        x, unit = _shown(name, float(v if index is None else v[index]), display, linear)
        parts.append(f"{name} = {fmt(x, digits)}{unit}")
    return ", ".join(parts)


def ranges_text(values: dict, display: DisplayUnits | None = None, linear: bool = False, digits: int = 3) -> str:
    """The varied parameters' spans with their units: ``load_inertia 0..4 kg*m^2, stiffness
    0.7..1.3 x nominal``.

    Parameters
    ----------
    values : dict
        name -> array of the variants' SI values.
    display, linear, digits
        As :func:`variant_text`.
    """
    display = display or DisplayUnits()
    parts = []
    for name, v in values.items():
        lo, unit = _shown(name, float(min(v)), display, linear)
        hi, _ = _shown(name, float(max(v)), display, linear)
        parts.append(f"{name} {fmt(lo, digits)}..{fmt(hi, digits)}{unit}")
    return ", ".join(parts)


__all__ = ["PARAMETERS", "VARY_RANGES", "parse_vary", "ranges_text", "variant_text"]
