"""The fixed-point position count against what the loop must hold at rest.

The integer motion controller reads the position error in counts of the position's LSB
(:func:`.quantize.full_scales`): an error below half a count rounds to zero and the code
does not act on it, however long it lasts (the floating-point controller's integral would
grow on it). The output then rests anywhere within half a count of the command, on top of
what the friction and the sensor leave, and a loop with an integral can hunt over a count.
So half a count must stay below the error at rest and the limit cycle that ``check``
requires of the actuator (the scene's ``max_position_error_at_rest`` and
``max_limit_cycle``, else their defaults: :func:`servo_toolkit.studies.actuator.spec.plan`).
Those rows of ``check`` run the floating-point controller at the sensor's own count; a
position LSB coarser than the sensor's count is said, with the ratio.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..core.output_units import OutputUnit, output_unit

#: the ``check`` rows a position count must stay within (half a count below each bound)
ROWS = ("position_error_at_rest", "limit_cycle")


@dataclass(frozen=True)
class PositionCount:
    """The fixed-point position count and what it is judged against.

    Attributes
    ----------
    fmt : str
        ``"q15"`` or ``"q31"``.
    lsb : float
        One count of the position (rad or m).
    sensor_count : float
        The output sensor's count (rad or m; 0: an ideal sensor).
    bounds : tuple of Bound
        The rows of :data:`ROWS` with their bounds (scene's or default).
    output : OutputUnit
        The output's units (a position shown in deg or mm).
    """

    fmt: str
    lsb: float
    sensor_count: float
    bounds: tuple
    output: OutputUnit

    def _shown(self, value: float) -> str:
        return self.output.text(value, 3)

    def failures(self) -> tuple:
        """Each row whose bound half a count reaches: named with both figures."""
        half = 0.5 * self.lsb
        hint = "; q31 keeps more bits" if self.fmt == "q15" else ""
        return tuple(
            f"{b.name}: a position error below half a {self.fmt} count ({self._shown(half)}) reads as zero in "
            f"the fixed-point code, so it cannot hold the {self._shown(b.value)} required ({_source(b)}){hint}"
            for b in self.bounds if half >= b.value)

    def describe(self) -> str:
        """One line: the count, its half, the sensor's count, the tightest bound."""
        words = f"position count {self._shown(self.lsb)} ({self.fmt}): errors below {self._shown(0.5 * self.lsb)} " \
                "read as zero"
        if self.sensor_count > 0:
            ratio = self.lsb / self.sensor_count
            words += (f"; {ratio:.3g}x the output sensor's {self._shown(self.sensor_count)} count" if ratio > 1 else
                      f"; finer than the output sensor's {self._shown(self.sensor_count)} count")
        if self.bounds:
            b = min(self.bounds, key=lambda b: b.value)
            words += f"; {b.name.replace('_', ' ')} allowed {self._shown(b.value)}"
        return words

    def to_dict(self) -> dict:
        """SI figures: the count, its half, the sensor's count and each row's bound."""
        return {"lsb": self.lsb, "half_count": 0.5 * self.lsb, "sensor_count": self.sensor_count,
                "bounds": {b.name: b.value for b in self.bounds}}


def _source(bound) -> str:
    """Where a bound comes from, in words."""
    from ..studies.actuator.spec import ROW_KEYS
    return f"requirements.{ROW_KEYS[bound.name]}" if bound.source == "scene" else f"default: {bound.rule}"


def position_count(quantized, scene, design_result) -> PositionCount:
    """The position count of ``quantized`` (a :class:`.quantize.Quantized`) judged against
    the rows of :data:`ROWS` of ``check`` for ``design_result`` on ``scene``."""
    from ..studies.actuator.spec import plan
    u = output_unit(scene)
    bounds = plan(scene, design_result).bounds
    return PositionCount(quantized.fmt, float(quantized.lsb["theta"]), float(scene.sensors.output_count(u.linear)),
                         tuple(b for b in bounds if b.name in ROWS), u)


__all__ = ["PositionCount", "ROWS", "position_count"]
