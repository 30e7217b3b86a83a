"""The range of values each scene quantity's model is conditioned for.

A finite value can still be far outside what the toolkit's models compute with: an
efficiency of 1e-300 makes a singular matrix, a nut mass of 1e30 kg cancels the motor's
inertia in double precision, a stiffness of 1e-30 N*m/rad puts a mode at 1e-15 Hz. Every
numeric scene key therefore has a range; a value outside it is refused when the scene loads,
naming the key and the range (``drivetrain[1].nut_mass: must be in [1e-09, 1e+06] kg, the
range the model is conditioned for (got 1e+30)``).

The ranges here are per SI unit, wide enough for every actuator from a camera gimbal to a
flight-control EMA; a component that needs a narrower one for a key passes its own
``bounds`` (e.g. an efficiency in [0.01, 1]). A zero is allowed wherever the key's rule
allows it (a missing friction, a massless nut); a signed value (``finite``) is bounded in
magnitude only.
"""

from __future__ import annotations

#: SI unit -> (smallest nonzero magnitude, largest magnitude)
CONDITIONED = {
    "m": (1e-9, 1e3),
    "m/turn": (1e-9, 1e3),  # a screw lead: travel per turn
    "rad": (1e-12, 1e3),
    "kg": (1e-9, 1e6),
    "kg*m^2": (1e-12, 1e6),
    "N*m/rad": (1e-2, 1e12),
    "N/m": (1.0, 1e13),
    "ohm": (1e-3, 1e4),
    "H": (1e-9, 10.0),
    "N*m/A": (1e-5, 1e4),
    "V*s/rad": (1e-5, 1e4),
    "N*m*s/rad": (1e-12, 1e6),
    "N*s/m": (1e-9, 1e9),
    "N*m": (1e-12, 1e9),
    "N": (1e-9, 1e10),
    "V": (1e-3, 1e5),
    "A": (1e-3, 1e5),
    "s": (1e-13, 1e10),  # up to a required bearing life (300 years)
    "Hz": (1e-6, 1e5),
    "rad/s": (1e-9, 1e5),
    "rad/s^3": (1e-6, 1e15),
    "dB": (1e-9, 200.0),
    "dimensionless": (1e-6, 1e6),
    "K": (1e-3, 1e4),
    "K/W": (1e-6, 1e6),
    "1/K": (1e-9, 1.0),
    "m/s": (1e-9, 1e3),
}


#: a robustness study's varied parameter -> (smallest nonzero value, largest value): a load
#: inertia as a scene's (0 allowed), a stiffness factor that keeps a stiffness of the
#: reference class (1e3 .. 1e6 N*m/rad) within the stiffness range above
VARIED = {"load_inertia": CONDITIONED["kg*m^2"], "stiffness": (1e-3, 1e3)}


def conditioned_range(unit: str | None, bounds=None):
    """``(low, high)`` for a key in ``unit`` (``bounds`` overrides), or None when the unit
    has no range here."""
    if bounds is not None:
        return tuple(bounds)
    return CONDITIONED.get(unit if unit not in (None, "", "1") else "dimensionless")


def range_rule(value: float, rule: str | None, unit: str | None, bounds=None) -> str | None:
    """The rule a finite ``value`` breaks, or None.

    Parameters
    ----------
    value : float
        Finite value in ``unit`` (SI).
    rule : {"positive", "nonnegative", "finite", None}
        The key's sign rule (already checked); None: no range applies.
    unit : str
        SI unit of the key.
    bounds : tuple of float, optional
        The component's own ``(low, high)``.
    """
    if rule is None and bounds is None:
        return None
    rng = conditioned_range(unit, bounds)
    if rng is None:
        return None
    low, high = rng
    mag = abs(value)
    shown = "" if unit in (None, "", "1", "dimensionless") else f" {unit}"
    if rule == "finite" and bounds is None:
        if mag <= high:
            return None
        return f"must be within +-{high:g}{shown}, the range the model is conditioned for (got {value:g})"
    if value == 0 and rule in ("nonnegative", "finite"):
        return None
    if low <= mag <= high:
        return None
    return f"must be in [{low:g}, {high:g}]{shown}, the range the model is conditioned for (got {value:g})"


__all__ = ["CONDITIONED", "VARIED", "conditioned_range", "range_rule"]
