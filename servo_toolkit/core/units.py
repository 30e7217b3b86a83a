"""Unit parsing at the scene boundary (pint); SI floats everywhere else."""

from __future__ import annotations

import math
import numbers
import re

import numpy as np
import pint

from ..errors import SceneError
from .unit_registry import unit_registry

#: The registry used to parse scene quantities (pint's default units; its parsed definitions
#: come from the user's cache after the first run, :mod:`.unit_registry`). It is only read
#: after import.
UREG = unit_registry()

_NUMBER = re.compile(r"^\s*[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?")
#: a non-finite number written as text ("nan ohm", "-inf N/m"), followed by a unit or the end
_NONFINITE = re.compile(r"^\s*([-+]?)(nan|inf|infinity)(?=\s|$)", re.IGNORECASE)


def looks_like_quantity(text: str) -> bool:
    """Return True when a string starts with a number (``"3 deg"``, ``"1e-4"``, ``"nan Hz"``)."""
    return bool(_NUMBER.match(text) or _NONFINITE.match(text))


#: an exponent in a unit ("m^2", "s**-1") and a leading "1/" ("1/s"): the only digits a unit has
_UNIT_DIGITS = re.compile(r"(\^|\*\*)\s*\(?\s*[-+]?\d+(\.\d+)?\s*\)?|^1\s*/")


def _example(number: str, unit: str | None) -> str:
    """How a key in ``unit`` writes ``number`` (``'50'`` for a ratio, ``'5 mm'``-like otherwise)."""
    if unit is None:
        return "'0.1 ms'"
    if unit in ("dimensionless", "", "1"):
        return number
    return f"'{number} {unit}'"


def _check_unit_text(unit: str, text: str, key: str, number: str, target: str | None) -> None:
    """SceneError unless ``unit`` is a unit, not an expression: a number in it other than
    an exponent ("0.1 ms / 0", "1 mm / 2 s", "50:1") would make pint evaluate arithmetic.
    The example is in the key's own unit ``target``."""
    if any(ch.isdigit() for ch in _UNIT_DIGITS.sub("", unit)):
        if unit.lstrip().startswith(":"):
            raise SceneError(key, f"a ratio N:1 is written as the number N (got {text!r}), e.g. "
                                  f"{_example(number, target)}")
        raise SceneError(key, f"a quantity is a number and a unit, not an expression (got {text!r}): "
                              f"give the value once, e.g. {_example(number, target)}")


def _parse_string(text: str, key: str, target: str | None = None) -> pint.Quantity:
    match = _NUMBER.match(text)
    nonfinite = None if match else _NONFINITE.match(text)
    if nonfinite and nonfinite.group(2).lower() == "nan":
        raise SceneError(key, f"value is NaN (got {text!r}): must be a finite number")
    match = match or nonfinite
    if not match:
        raise SceneError(key, f"expected a number with units, got {text!r}")
    unit = text[match.end():].strip()
    _check_unit_text(unit, text, key, match.group(0).strip(), target)
    try:
        return UREG.Quantity(float(match.group(0)), unit or "dimensionless")
    except (pint.errors.UndefinedUnitError, pint.errors.DefinitionSyntaxError,
            AttributeError, TypeError, ValueError, SyntaxError, ArithmeticError) as exc:
        raise SceneError(key, f"unknown unit {unit!r} in {text!r} ({exc})") from None


def parse_text(text: str, key: str) -> pint.Quantity:
    """A pint quantity from text such as ``"1 mm"`` (a bare number is dimensionless).

    Raises
    ------
    SceneError
        Not a number, NaN, or an unknown unit (naming ``key``).
    """
    return _parse_string(text, key)


def _angle_power(units) -> float:
    """The power of the radian in ``units`` (pint counts the radian as dimensionless)."""
    _, root = UREG.get_root_units(units)
    return root._units.get("radian", 0)


def _cycles(units):
    """``units`` with each hertz counted as a turn per second: pint's hertz is 1/s with no
    angle, but a hertz is a cycle (a turn) per second, so "0.2 V/Hz" is 0.2 V*s per turn."""
    power = sum(p for name, p in units._units.items() if name.endswith("hertz"))
    return units * UREG.turn ** power if power else units


def _angle_part(units):
    """The angle units (rad, deg, turn...) of a target unit, with their powers."""
    part = UREG.dimensionless
    for name, power in units._units.items():
        one = UREG.Unit(name)
        if one.dimensionless and _angle_power(one):
            part = part * one ** power
    return part


def _convert(q: pint.Quantity, unit: str, text: str, key: str) -> float:
    """``q`` in ``unit``, counting angles that pint counts as the number 1.

    pint's radian is dimensionless, so pint converts "5 mm/turn" to 0.796 mm and "0.2 V/Hz"
    to 0.2 V*s/rad. Here every hertz is a turn per second and the angle powers of the two
    units must agree: equal powers convert with a turn of 2 pi rad ("5 mm/turn" is a lead of
    5 mm in m/turn, "0.2 V/Hz" is 0.0318 V*s/rad, "100 rad/s" is 15.9 Hz); a value written
    without an angle is in the key's own angle unit ("5 mm" for m/turn, "0.02 V*s" for
    V*s/rad); an angle the key has no place for ("5 mm/turn" for a length in m) is refused.
    """
    target = UREG.Unit(unit)
    written = UREG.Quantity(q.magnitude, _cycles(q.units))
    wanted = _cycles(target)
    have, need = _angle_power(written.units), _angle_power(wanted)
    if have == 0 and need != 0:
        written = UREG.Quantity(written.magnitude, written.units * _angle_part(wanted))
    elif have != need:
        what = {1: "an angle", -1: "a value per angle (per turn, rad or Hz)"}.get(have - need, "another angle power")
        raise SceneError(key, f"expected a quantity in {unit}, got {text!r}: {what} where the key's unit "
                              "has none (a turn is 2 pi rad, a hertz a turn per second)")
    return float(written.to(wanted).magnitude)


def _reject_angle(q: pint.Quantity, text: str, key: str) -> None:
    """SceneError when ``q`` carries an angle (rad, deg, turn, sr...): pint counts the radian
    as dimensionless, so "3 deg" would pass as the number 0.052 where a ratio or an
    efficiency is expected."""
    if q.unitless:
        return
    _, root = UREG.get_root_units(q.units)
    if any(name in ("radian", "steradian") for name in root._units):
        raise SceneError(key, f"expected a dimensionless number, got an angle {text!r}: give a bare number")


def is_bare_number(value) -> bool:
    """True for a scene value written without a unit: a number, or a string holding only one
    (``45`` or ``"45"``); :func:`parse_quantity` reads it in the key's SI unit."""
    if isinstance(value, bool):
        return False
    if isinstance(value, (int, float)):
        return True
    if not isinstance(value, str):
        return False
    try:
        float(value.strip())
    except ValueError:
        return False
    return True


def read_as(value, si: float, unit: str) -> str:
    """How a bare number was read, for a refusal: ``got 45, read as 45 rad = 2578 deg: a bare
    number is in rad; write '45 deg'`` (an angle), ``got 5, read as 5 m`` (another unit)."""
    if unit != "rad":
        return f"got {value}, read as {si:g} {unit}: a bare number is in {unit}"
    return (f"got {value}, read as {si:g} rad = {math.degrees(si):.4g} deg: a bare number is in rad; "
            f"write '{str(value).strip()} deg'")


def parse_quantity(value, unit: str, key: str) -> float:
    """Convert a scene value to a float in ``unit``.

    Parameters
    ----------
    value : float, int or str
        A bare number (taken as already in ``unit``, which is SI) or a string with
        units such as ``"0.5 mH"``.
    unit : str
        Target unit, e.g. ``"N*m/rad"``; ``"dB"`` keeps decibels as a number.
    key : str
        Scene key path, for error messages.

    Returns
    -------
    float

    Angles count although pint's radian is dimensionless: a hertz is a turn per second and a
    turn 2 pi rad, so an angular rate given for a frequency (``"100 rad/s"``, ``"60 rpm"`` for
    ``"Hz"``) is divided by 2 pi (100 rad/s is 15.9 Hz), ``"0.2 V/Hz"`` for ``"V*s/rad"`` is
    0.0318 V*s/rad, ``"5 mm/turn"`` for ``"m/turn"`` is 0.005; a per-turn or per-hertz value
    for a key without an angle in its unit (``"5 mm/turn"`` for ``"m"``) is refused.

    Raises
    ------
    SceneError
        Unknown unit, wrong dimension (an angle where a dimensionless number is expected, or
        an angle power the key's unit does not have: pint's radian is dimensionless, the
        scene's is not), not a number, or NaN.
    """
    if isinstance(value, bool):
        raise SceneError(key, f"expected a quantity in {unit}, got a boolean")
    if isinstance(value, (int, float)):
        result = float(value)
    elif isinstance(value, str):
        q = _parse_string(value, key, unit)
        if unit == "dB":
            if str(q.units) not in ("decibel", "dimensionless"):
                raise SceneError(key, f"expected a level in dB, got {value!r}")
            result = float(q.magnitude)
        else:
            if unit in ("dimensionless", "", "1"):
                _reject_angle(q, value, key)
            elif str(q.units) != "dimensionless" and _angle_power(_cycles(q.units)) == 0 \
                    and _angle_power(UREG.Unit(unit)) == 1 \
                    and UREG.Unit(unit).dimensionality == q.dimensionality:
                raise SceneError(key, f"expected a quantity in {unit}, got {value!r}: a ratio is not an angle")
            try:
                result = _convert(q, unit, value, key)
            except pint.errors.DimensionalityError:
                raise SceneError(
                    key, f"dimension mismatch: expected a quantity in {unit}, "
                    f"got {value!r} ({q.dimensionality})") from None
            except pint.errors.OffsetUnitCalculusError:
                raise SceneError(key, f"expected a quantity in {unit}, got {value!r}") from None
    else:
        raise SceneError(key, f"expected a quantity in {unit}, got {type(value).__name__}")
    if math.isnan(result):
        raise SceneError(key, "value is NaN")
    return result


def parse_si(value, key: str):
    """Parse a value of unknown dimension to SI base units.

    Strings that start with a number become floats in SI base units (angles in rad,
    frequencies in Hz); other strings stay strings; lists and tables recurse.
    """
    if isinstance(value, dict):
        return {k: parse_si(v, f"{key}.{k}") for k, v in value.items()}
    if isinstance(value, list):
        return [parse_si(v, f"{key}[{i}]") for i, v in enumerate(value)]
    if isinstance(value, str) and looks_like_quantity(value):
        q = _parse_string(value, key)
        if str(q.units) == "decibel":
            return float(q.magnitude)
        result = float(q.to_base_units().magnitude)
        if math.isnan(result):
            raise SceneError(key, "value is NaN")
        return result
    if isinstance(value, float) and math.isnan(value):
        raise SceneError(key, "value is NaN")
    return value


def argument_value(value, unit, name: str, finite: bool = True) -> float:
    """A Python argument as a finite float in ``unit``: a real number is already in it, a
    pint Quantity (of any registry) is converted with the scene's rules for angles
    (:func:`parse_quantity`: pint's radian is dimensionless, a hertz is a turn per second).

    Parameters
    ----------
    value : float, int, numpy scalar or pint.Quantity
    unit : str or tuple of str
        The unit a bare number is in (SI), e.g. ``"s"``, ``"rad"``; a tuple gives the units
        a Quantity may be in (``("rad", "m")``: an angle or a travel), the first that its
        dimension fits is taken.
    name : str
        The argument's name, for the error.
    finite : bool
        Refuse NaN and infinity (False: the caller checks the value).

    Returns
    -------
    float

    Raises
    ------
    SceneError
        Naming ``name``: a str (a Python argument is not parsed: pass a number in the SI
        unit or a Quantity), a bool or another type, a Quantity of another dimension, a value
        that is NaN or infinite.
    """
    units = (unit,) if isinstance(unit, str) else tuple(unit)
    wanted = " or ".join(units)
    if isinstance(value, np.ndarray) and value.ndim == 0:  # a 0-d array is its one number
        value = value.item()
    if isinstance(value, pint.Quantity):
        magnitude = value.magnitude
        if np.ndim(magnitude) != 0 or isinstance(magnitude, bool):
            raise SceneError(name, f"expected one quantity in {wanted}, got {value!r}")
        q = UREG.Quantity(float(magnitude), str(value.units))
        for i, u in enumerate(units):
            try:
                result = _convert(q, u, str(value), name)
                break
            except pint.errors.DimensionalityError:
                if i == len(units) - 1:
                    raise SceneError(name, f"dimension mismatch: expected a quantity in {wanted}, got {value}") from None
            except SceneError:
                if i == len(units) - 1:
                    raise
    elif isinstance(value, str):
        raise SceneError(name, f"expected a number (in {wanted}) or a pint Quantity, got the str {value!r}: a Python "
                               f"argument is not parsed (pint: ureg.Quantity({value!r}))")
    elif isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_)):
        result = float(value)
    else:
        raise SceneError(name, f"expected a number (in {wanted}) or a pint Quantity, got {type(value).__name__}")
    if finite and not math.isfinite(result):
        raise SceneError(name, f"must be a finite number (got {result:g} {units[0]})")
    return result


def quantity_unit(value, unit) -> str | None:
    """The first of ``unit`` (a str or a tuple of str) whose dimension a pint Quantity
    ``value`` fits, as :func:`argument_value` converts it; None for a bare number (in no unit
    of its own) or a Quantity that fits none."""
    if not isinstance(value, pint.Quantity):
        return None
    for u in ((unit,) if isinstance(unit, str) else tuple(unit)):
        try:
            argument_value(value, u, "value", finite=False)
        except SceneError:
            continue
        return u
    return None


def argument_values(values, unit, name: str) -> np.ndarray:
    """A Python argument holding one value or a sequence of them (a list of numbers or of
    Quantities, an array, an array Quantity) as a float array in ``unit``, each value as
    :func:`argument_value` reads it."""
    if isinstance(values, pint.Quantity):
        items = list(values) if np.ndim(values.magnitude) else [values]
    elif isinstance(values, (str, bytes)) or np.ndim(values) == 0 and not isinstance(values, (list, tuple)):
        items = [values]
    else:
        items = list(values)
    return np.array([argument_value(v, unit, name) for v in items], dtype=float)
