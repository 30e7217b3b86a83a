"""How a ``[studies.NAME]`` table is read: with its kind's keys (:mod:`.study_kind`), their
units, ranges and choices, at load time like every other table (a typo, a wrong unit or an
impossible value is one line naming the key, never a traceback when the study runs).

Amplitudes and offsets are positions of the output: angles for an output angle, lengths for
an output travel (a chain ending in a screw); a Kv study's load inertias are kg*m^2 for an
output angle and masses (kg) for an output travel. Durations are bounded so that no study asks for
more memory or time than a workstation has.
"""

from __future__ import annotations

import math
from types import MappingProxyType

from ..errors import SceneError
from ..core.fields import Fields, require
from ..drivetrain.elements import INERTIA_UNIT
from .study_kind import study_kinds

#: longest run a study may ask for (s)
MAX_DURATION_S = 1000.0
#: most frequency points of a sweep
MAX_POINTS = 10_000
#: highest frequency of a study (Hz)
MAX_FREQUENCY_HZ = 1e5
METHODS = ("rk4", "paper", "reference", "auto")
POSITION = "position"  # rad or m, after the scene's output
INERTIA = "inertia"  # kg*m^2 for an output angle, kg (a mass) for an output travel

#: the building blocks of the kinds' schemas (:class:`~.study_kind.StudyKind`): key -> (unit,
#: or [unit] for a list, or a tuple of choices for text, or "sweep" / "moments" / "count"; rule)
AMPLITUDE_KEYS = MappingProxyType({"amplitude": (POSITION, "positive"), "amplitudes": ([POSITION], "positive")})
#: a sine motion: its frequency or period and its amplitude(s)
SINE_KEYS = MappingProxyType({"frequency": ("Hz", "positive"), "period": ("s", "positive"), **AMPLITUDE_KEYS})
#: a time run: its duration, sample time and integration method
RUN_KEYS = MappingProxyType({"duration": ("s", "positive"), "sample_time": ("s", "positive"),
                             "method": (METHODS, None)})


def _sweep_table(f: Fields, name: str):
    """``frequencies``: a list of frequencies or ``{start, stop, points, spacing}``."""
    value = f.raw(name, None)
    if isinstance(value, dict):
        g = Fields(value, f.key(name))
        out = {"start": g.quantity("start", "Hz", rule="positive"), "stop": g.quantity("stop", "Hz", rule="positive"),
               "points": g.integer("points", 20, minimum=2), "spacing": g.text("spacing", "log", choices=("log", "linear"))}
        g.check_unknown()
        require(out["start"] < out["stop"], g.key("stop"), "must be above start")
        require(out["points"] <= MAX_POINTS, g.key("points"), f"at most {MAX_POINTS} points")
        require(out["stop"] <= MAX_FREQUENCY_HZ, g.key("stop"), f"at most {MAX_FREQUENCY_HZ:g} Hz")
        return out
    values = f.quantity_list(name, "Hz", rule="positive")
    require(0 < len(values) <= MAX_POINTS, f.key(name), f"give 1 to {MAX_POINTS} frequencies")
    require(max(values) <= MAX_FREQUENCY_HZ, f.key(name), f"at most {MAX_FREQUENCY_HZ:g} Hz")
    return list(values)


def _moments(f: Fields, name: str):
    value = f.raw(name, None)
    require(isinstance(value, list) and value, f.key(name), "expected a list of [M_x, M_y] pairs")
    out = []
    for i, pair in enumerate(value):
        key = f"{f.key(name)}[{i}]"
        require(isinstance(pair, list) and len(pair) == 2, key, "expected a pair [M_x, M_y]")
        g = Fields({"x": pair[0], "y": pair[1]}, key)
        out.append([g.quantity("x", "N*m", rule="finite"), g.quantity("y", "N*m", rule="finite")])
    return out


def study_params(name: str, table, output_unit: str = "rad") -> tuple:
    """``(kind, params)`` of a ``[studies.NAME]`` table, read with its kind's schema
    (:func:`~.study_kind.study_kinds`): every value checked and in SI
    (positions in rad or m after ``output_unit``, frequencies in Hz).

    Raises
    ------
    SceneError
        Naming ``studies.NAME.key`` and the rule: an unknown kind (the message lists the
        registered ones), an unknown key, a wrong unit, a value out of range, a choice not
        offered.
    """
    f = Fields(table, f"studies.{name}")
    kinds = study_kinds()
    kind = f.text("kind", choices=set(kinds))  # an unknown kind: the registered ones listed
    schema = kinds[kind].schema
    params = {}
    # amplitudes read at the motor gear (a Kv study's) are angles of the motor gear, whatever the output
    at_motor = "amplitude_at" in schema and table.get("amplitude_at") == "motor"
    for key, (unit, rule) in schema.items():
        if not f.has(key):
            continue
        if unit == POSITION:
            params[key] = f.quantity(key, "rad" if at_motor and key == "amplitude" else output_unit, rule=rule)
        elif isinstance(unit, list):
            u = (("rad" if at_motor and key == "amplitudes" else output_unit) if unit[0] == POSITION
                 else INERTIA_UNIT[output_unit] if unit[0] == INERTIA else unit[0])
            params[key] = list(f.quantity_list(key, u, rule=rule))
            require(len(params[key]) > 0, f.key(key), "give at least one value")
        elif isinstance(unit, tuple):
            params[key] = f.text(key, choices=unit)
        elif unit == "sweep":
            params[key] = _sweep_table(f, key)
        elif unit == "moments":
            params[key] = _moments(f, key)
        elif unit == "count":
            params[key] = f.integer(key, minimum=1)
        else:
            params[key] = f.quantity(key, unit, rule=rule)
    f.check_unknown()
    for key in ("duration", "sample_time"):
        if key in params:
            require(params[key] <= MAX_DURATION_S, f.key(key), f"at most {MAX_DURATION_S:g} s (got {params[key]:g} s)")
    if "frequency" in params:
        require(params["frequency"] <= MAX_FREQUENCY_HZ, f.key("frequency"), f"at most {MAX_FREQUENCY_HZ:g} Hz")
    if "frequency" in params and "period" in params:
        raise SceneError(f.key("period"), "give either period or frequency, not both")
    if "period" in params:
        require(params["period"] <= MAX_DURATION_S, f.key("period"), f"at most {MAX_DURATION_S:g} s")
    for key in ("amplitude", "amplitudes"):
        if at_motor:  # motor-gear angles: the output's stroke bounds them once divided by the ratio
            continue
        values = params.get(key)
        values = values if isinstance(values, list) else [values] if values is not None else []
        limit = math.pi if output_unit == "rad" else 10.0
        for v in values:
            require(v <= limit, f.key(key), f"at most {'180 deg' if output_unit == 'rad' else '10 m'} (got {v:g} "
                    f"{output_unit})")
    return kind, params
