"""The ``[duty_cycle]`` table: segments of motion with their external load, repeated.

A duty cycle is the motion an actuator repeats in service, the input of the sizing
(:mod:`servo_toolkit.studies.sizing`)::

    [duty_cycle]
    start = "0 deg"                        # position at the start of the cycle (default mid-stroke)
    required_life = "20000 h"              # screw and bearing L10 must reach it
    ratio_range = [0.25, 4.0]              # ratio sweep: factors of the first stage's ratio
    ratio_points = 50

    [[duty_cycle.segments]]
    kind = "ramp"                          # trapezoidal move to `to` in `duration`
    to = "20 deg"
    duration = "0.5 s"
    accel_time = "0.1 s"                   # default a quarter of the duration
    load = "700 N*m"                       # external moment the drive supplies (default [load])

    [[duty_cycle.segments]]
    kind = "dwell"                         # hold the position
    duration = "1 s"

Segment kinds: ``dwell`` (hold), ``ramp`` (trapezoidal speed profile to ``to``), ``step`` (a
move to ``to`` as a triangular speed profile over ``rise_time``, then hold), ``sine``
(``amplitude`` about the segment's start position, ``frequency`` or ``period``, ``cycles``
periods) and ``points`` (a CSV file of time and position with units in its header, e.g.
``t [s], position [deg]``; cubic spline through the points). Positions are in the output's
unit (angles for an output angle, lengths for an output travel); loads are moments (N*m),
or forces (N) for an output travel, opposing positive motion like ``[load] hinge_moment``.
The cycle repeats back to back, so it must end where it starts.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

from ..core.fields import Fields, require
from ..errors import SceneError

SEGMENT_KINDS = ("dwell", "ramp", "step", "sine", "points")
#: longest cycle (s) and most segments
MAX_CYCLE_S = 1000.0
MAX_SEGMENTS = 1000
#: most points of a ``points`` segment's CSV file, and its largest size (bytes)
MAX_CSV_POINTS = 100_000
MAX_CSV_BYTES = 8 * 1024 * 1024
#: most ratios of the sweep
MAX_RATIO_POINTS = 1000
#: most samples of one cycle for the sizing
MAX_CYCLE_SAMPLES = 2_000_000
#: fewest samples of a sine segment's period, and of a points segment's interval between points
SINE_SAMPLES = 32
POINTS_SAMPLES = 2
POSITION = "position"
#: segment key -> (unit, rule, kinds that take it); ``position`` is the output's unit
_KEYS = {"duration": ("s", "positive", ("dwell", "ramp", "step")),
         "to": (POSITION, "finite", ("ramp", "step")),
         "accel_time": ("s", "positive", ("ramp",)),
         "rise_time": ("s", "positive", ("step",)),
         "amplitude": (POSITION, "positive", ("sine",)),
         "frequency": ("Hz", "positive", ("sine",)),
         "period": ("s", "positive", ("sine",)),
         "cycles": ("dimensionless", "positive", ("sine",)),
         "file": ("path", None, ("points",)),
         "load": ("load", "finite", SEGMENT_KINDS)}
#: the keys each segment kind requires (a sine takes ``frequency`` or ``period`` as well)
REQUIRED_KEYS = {"dwell": ("duration",), "ramp": ("duration", "to"), "step": ("duration", "to"),
                 "sine": ("amplitude",), "points": ("file",)}


@dataclass(frozen=True)
class Segment:
    """One segment of a duty cycle, SI.

    Parameters
    ----------
    kind : str
        ``"dwell"``, ``"ramp"``, ``"step"``, ``"sine"`` or ``"points"``.
    duration : float
        Length of the segment (s); a sine's is cycles / frequency, a points file's the span
        of its times (its first point starts the segment, whatever its time).
    load : float or None
        External moment (N*m; a force, N, for an output travel) the drive supplies, opposing
        positive motion; None: the scene's ``[load] hinge_moment``.
    to : float or None
        Target position of a ramp or step (rad or m).
    accel_time : float or None
        Acceleration (and deceleration) time of a ramp's trapezoidal speed profile (s).
    rise_time : float or None
        Duration of a step's move (s).
    amplitude : float or None
        A sine segment's amplitude about the segment's start position (rad or m).
    frequency, period : float or None
        A sine segment's frequency (Hz), or its period (s; the scene gives one of them).
    cycles : float or None
        Periods of a sine segment (default 1).
    file : str or None
        A points segment's CSV file as the scene gives it (relative to the scene file): a
        header naming two columns with units, e.g. ``t [s], position [deg]``, then rows of
        numbers.
    path : str or None
        A points segment's CSV file as read (resolved against the scene's folder): an input
        of every command on the scene, never overwritten by one of its outputs.
    times, positions : tuple of float
        A points segment: sample times from 0 (s) and positions (rad or m).
    """

    kind: str
    duration: float
    load: float | None = None
    to: float | None = None
    accel_time: float | None = None
    rise_time: float | None = None
    amplitude: float | None = None
    frequency: float | None = None
    cycles: float | None = None
    times: tuple = ()
    positions: tuple = ()
    file: str | None = None
    path: str | None = None


@dataclass(frozen=True)
class DutyCycle:
    """A scene's ``[duty_cycle]``: segments repeated back to back, SI.

    Parameters
    ----------
    segments : tuple of Segment
    start : float or None
        Position at the start of the cycle (rad or m); None: mid-stroke.
    required_life : float or None
        Life the screw and its bearing must reach (s; scene unit h); None: not checked.
    sample_time : float or None
        Sampling of the cycle for the sizing (s); None: about 4000 samples per cycle.
    ratio_range : tuple of float
        The ratio sweep's lowest and highest factor on the first stage's ratio.
    ratio_points : int
        Ratios in the sweep.
    motors : tuple of (str, DCMotor)
        Motor candidates ``[[duty_cycle.motors]]`` compared in the sweep.
    """

    segments: tuple
    start: float | None = None
    required_life: float | None = None
    sample_time: float | None = None
    ratio_range: tuple = (0.25, 4.0)
    ratio_points: int = 50
    motors: tuple = ()

    @property
    def duration(self) -> float:
        """Length of one cycle (s)."""
        return float(sum(s.duration for s in self.segments))


def _csv_points(path: Path, key: str, output_unit: str, source) -> tuple:
    """(times, positions) of a points file: a header ``name [unit], name [unit]`` and rows."""
    from ..core.inputs import read_input_text
    from ..core.units import parse_quantity
    text = read_input_text(path, key, MAX_CSV_BYTES, source=source, what=f"the points file {path.name!r}")
    lines = [ln.strip() for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    require(len(lines) >= 3, key, f"the points file needs a header and at least 2 rows (got {max(len(lines) - 1, 0)})")
    require(len(lines) - 1 <= MAX_CSV_POINTS, key, f"at most {MAX_CSV_POINTS} points (got {len(lines) - 1})")
    head = [h.strip() for h in lines[0].split(",")]
    units = [re.search(r"[\[(]\s*([^\])]+?)\s*[\])]\s*$", h) for h in head]
    require(len(head) == 2 and all(units), key, "the header must name two columns with units, e.g. "
            f"'t [s], position [{'mm' if output_unit == 'm' else 'deg'}]' (got {lines[0][:60]!r})")
    scale = [parse_quantity(f"1 {u.group(1)}", unit, f"{key} (header)") for u, unit in zip(units, ("s", output_unit))]
    times, positions = [], []
    for i, line in enumerate(lines[1:], start=2):
        cells = line.split(",")
        try:
            t, x = (float(c) for c in cells)
        except ValueError:
            raise SceneError(key, f"line {i} of the points file is not two numbers (got {line[:60]!r})") from None
        require(math.isfinite(t) and math.isfinite(x), key, f"line {i} of the points file is not finite")
        times.append(t * scale[0])
        positions.append(x * scale[1])
    require(all(b > a for a, b in zip(times, times[1:])), key, "the times of the points file must increase")
    t0 = times[0]
    return tuple(t - t0 for t in times), tuple(positions)


def _segment(table, i: int, output_unit: str, folder: Path, source) -> Segment:
    f = Fields(table, f"duty_cycle.segments[{i}]")
    kind = f.text("kind", choices=SEGMENT_KINDS)
    load_unit = "N" if output_unit == "m" else "N*m"
    values = {}
    for key, (unit, rule, kinds) in _KEYS.items():
        if not f.has(key):
            continue
        require(kind in kinds, f.key(key), f"a {kind} segment does not take {key} (its keys: "
                f"{sorted(k for k, v in _KEYS.items() if kind in v[2])})")
        if unit == "path":
            values[key] = f.text(key)
        else:
            u = output_unit if unit == POSITION else load_unit if unit == "load" else unit
            values[key] = f.quantity(key, u, rule=rule)
    f.check_unknown()
    for key in REQUIRED_KEYS[kind]:
        require(key in values, f.key(key), f"missing key (required by a {kind} segment)")

    if kind == "sine":
        require(("frequency" in values) != ("period" in values), f.key("frequency"),
                "give either frequency or period (one of them)")
        freq = values.get("frequency") or 1.0 / values["period"]
        amp, cycles = values["amplitude"], values.get("cycles", 1.0)
        require(cycles <= 1e6, f.key("cycles"), f"at most 1e6 periods (got {cycles:g})")
        return Segment(kind, cycles / freq, values.get("load"), amplitude=amp, frequency=freq, cycles=cycles)
    if kind == "points":
        path = Path(values["file"])
        path = path if path.is_absolute() else folder / path
        times, positions = _csv_points(path, f.key("file"), output_unit, source)
        return Segment(kind, times[-1], values.get("load"), times=times, positions=positions, file=values["file"],
                       path=str(path))
    duration = values["duration"]
    if kind == "ramp":
        accel = values.get("accel_time", duration / 4)
        require(accel <= duration / 2, f.key("accel_time"),
                f"must be at most half the duration ({duration / 2:g} s) (got {accel:g} s)")
        return Segment(kind, duration, values.get("load"), to=values["to"], accel_time=accel)
    if kind == "step":
        rise = values.get("rise_time", duration / 10)
        require(rise <= duration, f.key("rise_time"), f"must be at most the duration ({duration:g} s) (got {rise:g} s)")
        return Segment(kind, duration, values.get("load"), to=values["to"], rise_time=rise)
    return Segment(kind, duration, values.get("load"))


def duty_cycle_from_table(table, output_unit: str = "rad", source: str | None = None) -> DutyCycle:
    """The validated ``[duty_cycle]`` of a scene (positions in rad or m after ``output_unit``).

    Raises
    ------
    SceneError
        Naming ``duty_cycle.KEY`` or ``duty_cycle.segments[i].KEY`` and the rule broken.
    """
    from ..components.motor import DCMotor
    f = Fields(table, "duty_cycle")
    raw = f.raw("segments")
    require(isinstance(raw, list) and raw and all(isinstance(t, dict) for t in raw), f.key("segments"),
            "must be a non-empty array of tables [[duty_cycle.segments]]")
    require(len(raw) <= MAX_SEGMENTS, f.key("segments"), f"at most {MAX_SEGMENTS} segments (got {len(raw)})")
    folder = Path(source).parent if source else Path.cwd()
    segments = tuple(_segment(t, i, output_unit, folder, source) for i, t in enumerate(raw))
    start = f.quantity("start", output_unit, rule="finite") if f.has("start") else None
    life = f.quantity("required_life", "s", rule="positive") if f.has("required_life") else None
    dt = f.quantity("sample_time", "s", rule="positive") if f.has("sample_time") else None
    span = tuple(f.quantity_list("ratio_range", "dimensionless", (0.25, 4.0), rule="positive"))
    require(len(span) == 2 and span[0] < span[1], f.key("ratio_range"), "must be [lowest, highest] with lowest < highest")
    points = f.integer("ratio_points", 50, minimum=2)
    require(points <= MAX_RATIO_POINTS, f.key("ratio_points"), f"at most {MAX_RATIO_POINTS} (got {points})")
    raw_motors = f.raw("motors", [])
    require(isinstance(raw_motors, list), f.key("motors"), "must be an array of tables [[duty_cycle.motors]]")
    motors = []
    for i, t in enumerate(raw_motors):
        g = Fields(t, f"duty_cycle.motors[{i}]")
        name = g.text("name", f"motor {i + 1}")
        motors.append((name, DCMotor.from_table(g)))
    f.check_unknown()
    duty = DutyCycle(segments, start, life, dt, span, points, tuple(motors))
    require(duty.duration <= MAX_CYCLE_S, f.key("segments"),
            f"the cycle lasts at most {MAX_CYCLE_S:g} s (got {duty.duration:g} s)")
    if dt is not None:
        require(duty.duration / dt <= MAX_CYCLE_SAMPLES, f.key("sample_time"),
                f"at most {MAX_CYCLE_SAMPLES:.0e} samples per cycle (got {duty.duration / dt:.3g})")
    resolved = 0.0   # the samples that resolve the sines' periods and the points' intervals
    for i, seg in enumerate(segments):
        resolved += resolving_samples(seg)
        key = f"duty_cycle.segments[{i}]." + ("cycles" if seg.kind == "sine" else "file")
        require(resolved <= MAX_CYCLE_SAMPLES, key,
                f"at most {MAX_CYCLE_SAMPLES:.0e} samples per cycle: each sine period takes {SINE_SAMPLES}, each "
                f"interval between points {POINTS_SAMPLES} (got {resolved:.3g} up to this segment)")
    return duty


def resolving_samples(segment: Segment) -> float:
    """Samples the sizing takes to resolve a segment's motion at least: :data:`SINE_SAMPLES`
    per sine period, :data:`POINTS_SAMPLES` per interval between a points file's points (0
    for the others, whose pieces are polynomials)."""
    if segment.kind == "sine":
        return segment.cycles * SINE_SAMPLES
    if segment.kind == "points":
        return (len(segment.times) - 1) * POINTS_SAMPLES
    return 0.0


def segment_end(segment: Segment, start: float) -> float:
    """Position at the end of ``segment`` when it begins at ``start``."""
    if segment.kind in ("ramp", "step"):
        return segment.to
    if segment.kind == "sine":
        return start + segment.amplitude * math.sin(2 * math.pi * segment.cycles)
    if segment.kind == "points":
        return segment.positions[-1]
    return start


def check_positions(duty: DutyCycle, stroke: tuple, mid: float, output_unit: str = "rad") -> None:
    """Every position of the cycle within ``stroke``, each points file starting where the cycle
    stands, and the cycle ending where it starts (it repeats).

    Raises
    ------
    SceneError
        Naming the segment's key.
    """
    lo, hi = stroke
    show = (lambda v: f"{v * 1e3:g} mm") if output_unit == "m" else (lambda v: f"{math.degrees(v):g} deg")
    tol = 1e-9 * max(1.0, hi - lo)

    def inside(v, key):
        require(lo - tol <= v <= hi + tol, key, f"must lie within the stroke [{show(lo)}, {show(hi)}] (got {show(v)})")

    start = mid if duty.start is None else duty.start
    inside(start, "duty_cycle.start")
    at = start
    for i, s in enumerate(duty.segments):
        key = f"duty_cycle.segments[{i}]"
        if s.kind in ("ramp", "step"):
            inside(s.to, f"{key}.to")
        elif s.kind == "sine":
            inside(at + s.amplitude, f"{key}.amplitude")
            inside(at - s.amplitude, f"{key}.amplitude")
        elif s.kind == "points":
            require(abs(s.positions[0] - at) <= 1e-6 * max(1.0, hi - lo), f"{key}.file",
                    f"the points must start where the cycle stands ({show(at)}; got {show(s.positions[0])})")
            for v in (min(s.positions), max(s.positions)):
                inside(v, f"{key}.file")
        at = segment_end(s, at)
    require(abs(at - start) <= 1e-6 * max(1.0, hi - lo), f"duty_cycle.segments[{len(duty.segments) - 1}]",
            f"the cycle repeats, so it must end where it starts ({show(start)}; it ends at {show(at)})")


__all__ = ["DutyCycle", "Segment", "SEGMENT_KINDS", "duty_cycle_from_table", "check_positions", "segment_end",
           "resolving_samples", "SINE_SAMPLES", "POINTS_SAMPLES", "MAX_CYCLE_SAMPLES"]
