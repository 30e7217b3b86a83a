"""What the actuator must do in time, in a scene's ``[requirements]``: the nonlinear closed
loop's step and requirement sine, and the rows ``servo-toolkit check`` judges them on.

Every key is optional; a key left out takes the default of
:mod:`servo_toolkit.studies.actuator.spec` (stated as a default in the rows and the notes).
Positions are angles, or lengths for an output travel (a bare number is SI: rad or m);
the overshoot a ratio (``"20 %"``); times in s; currents in A.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..errors import SceneError

#: keys of an output position (an angle, or a length for an output travel)
POSITION_KEYS = ("step_amplitude", "sine_amplitude", "max_tracking_error", "max_position_error_at_rest",
                 "max_limit_cycle")
#: other keys -> (unit, rule)
OTHER_KEYS = {"max_overshoot": ("dimensionless", "nonnegative"), "max_settling_time": ("s", "positive"),
              "max_current_ripple": ("A", "positive"), "max_rms_current": ("A", "positive"),
              "max_time_at_current_limit": ("s", "nonnegative"), "max_time_at_voltage_limit": ("s", "nonnegative")}
KEYS = POSITION_KEYS + tuple(OTHER_KEYS)


def output_quantity(f, name: str):
    """``(value, dimension)`` of a position key: an angle (rad), a length (m; for an output
    travel), or a bare SI number (dimension None); None when the table does not set it."""
    if not f.has(name):
        return None
    if not isinstance(f.raw(name), str):
        return f.quantity(name, "rad", rule="positive"), None
    for unit, dimension in (("rad", "angle"), ("m", "length")):
        try:
            return f.quantity(name, unit, rule="positive"), dimension
        except SceneError as exc:
            if "positive" in str(exc) or "finite" in str(exc):
                raise
    raise SceneError(f.key(name), "expected an angle (e.g. '0.5 deg') or, for an output travel, a length "
                                  "(e.g. '0.2 mm')")


@dataclass(frozen=True)
class TimeRequirements:
    """The time keys of ``[requirements]`` (SI; None where the scene sets none).

    Attributes
    ----------
    step_amplitude, sine_amplitude : float or None
        The step and the requirement sine's amplitude (rad, or m).
    max_overshoot : float or None
        Fraction of the step.
    max_settling_time : float or None
        Seconds into the settling band (2 % of the step, or the position error allowed at
        rest when larger).
    max_tracking_error, max_position_error_at_rest, max_limit_cycle : float or None
        Peak |command - output| over the sine's judged cycles; |command - output| at rest
        after the step; amplitude of an oscillation after the step (rad, or m).
    max_current_ripple, max_rms_current : float or None
        A (rms).
    max_time_at_current_limit, max_time_at_voltage_limit : float or None
        Seconds within 1 % of the limit in the requirement sine.
    dimensions : tuple of (str, str)
        ``(key, "angle" | "length")`` as the scene gave each position.
    """

    step_amplitude: float | None = None
    sine_amplitude: float | None = None
    max_overshoot: float | None = None
    max_settling_time: float | None = None
    max_tracking_error: float | None = None
    max_position_error_at_rest: float | None = None
    max_limit_cycle: float | None = None
    max_current_ripple: float | None = None
    max_rms_current: float | None = None
    max_time_at_current_limit: float | None = None
    max_time_at_voltage_limit: float | None = None
    dimensions: tuple = ()

    @classmethod
    def from_fields(cls, f) -> "TimeRequirements":
        """The time keys of a ``[requirements]`` table (its other keys are left to it)."""
        values, dims = {}, []
        for name in POSITION_KEYS:
            got = output_quantity(f, name)
            if got is not None:
                values[name] = got[0]
                if got[1] is not None:
                    dims.append((name, got[1]))
        for name, (unit, rule) in OTHER_KEYS.items():
            if f.has(name):
                values[name] = f.quantity(name, unit, rule=rule)
        if values.get("max_overshoot", 0.0) > 10.0:
            raise SceneError(f.key("max_overshoot"), f"a fraction of the step, at most 1000 % (got "
                                                     f"{values['max_overshoot']:g}; write e.g. '20 %')")
        return cls(**values, dimensions=tuple(dims))

    def given(self) -> dict:
        """The keys the scene set, name -> SI value."""
        return {k: getattr(self, k) for k in KEYS if getattr(self, k) is not None}

    def check_output(self, linear: bool) -> None:
        """SceneError naming ``requirements.<key>`` when a position was given as a length for
        an output angle, or as an angle for an output travel."""
        want = "length" if linear else "angle"
        for key, dim in self.dimensions:
            if dim != want:
                raise SceneError(f"requirements.{key}", f"the output is {'a travel' if linear else 'an angle'}: "
                                                        f"give {'a length' if linear else 'an angle'} "
                                                        f"(e.g. {'0.5 mm' if linear else '1 deg'}), got {'an angle' if linear else 'a length'}")


__all__ = ["KEYS", "OTHER_KEYS", "POSITION_KEYS", "TimeRequirements", "output_quantity"]
