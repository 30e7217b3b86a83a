"""The contents of a design file (``--design FILE``, :func:`.tuning.save_design`) checked
field by field after JSON parsing: every number a real, finite number in its physical
range, the operating point within the scene's stroke. A bad field is one SceneError naming
``--design`` and the field's JSON key (``gains.kp``), never a traceback further on.
"""

from __future__ import annotations

import math

from ..errors import SceneError
from .structures import FILTERS, STRUCTURES, Motion

KEY = "--design"
#: largest magnitude of a gain, a frequency (rad/s), a ratio or a current-loop gain
BOUND = 1e9
#: gains of each structure (Motion.gains)
GAINS = {"cascade": ("kp", "kv", "wvi"), "pid": ("kc", "wi", "wz", "wp"), "lead_lag": ("kc", "wz", "wp"),
         "pi": ("kc", "wi")}
#: parameters of each filter (Motion.filter_params)
FILTER_PARAMS = {"none": (), "notch": ("wn", "zeta_zero", "zeta_pole"), "lowpass": ("wn", "zeta")}
#: a damping ratio of a filter: at most this
MAX_ZETA = 100.0
#: sample time of a sampled controller (s): 0 (continuous) or within this range
SAMPLE_TIME_RANGE = (1e-7, 1.0)


def _fail(field: str, rule: str, value) -> SceneError:
    return SceneError(KEY, f"{field}: {rule} (got {value!r})" if not isinstance(value, float)
                      else f"{field}: {rule} (got {value:g})")


def number(data: dict, field: str, lo: float, hi: float, *, lo_open: bool = False, container=None) -> float:
    """``data[name]`` as a float in ``[lo, hi]`` (``(lo, hi]`` with ``lo_open``); ``field`` is
    the dotted JSON key named in the error."""
    name = field.rsplit(".", 1)[-1]
    source = data if container is None else container
    if name not in source:
        raise SceneError(KEY, f"{field}: missing")
    value = source[name]
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise _fail(field, "must be a number", value if not isinstance(value, str) else value[:40])
    if isinstance(value, int) and abs(value) > 2 ** 53:  # beyond what a float holds exactly
        raise SceneError(KEY, f"{field}: must lie in {'(' if lo_open else '['}{lo:g}, {hi:g}] "
                              f"(got an integer of {len(str(abs(value)))} digits)")
    value = float(value)
    if math.isnan(value):
        raise SceneError(KEY, f"{field}: value is NaN")
    if not (value > lo if lo_open else value >= lo) or not value <= hi:
        raise _fail(field, f"must lie in {'(' if lo_open else '['}{lo:g}, {hi:g}]", value)
    return value


def _table(data: dict, name: str) -> dict:
    value = data.get(name)
    if not isinstance(value, dict):
        raise SceneError(KEY, f"{name}: missing or not a table of numbers")
    return value


def design_fields(data: dict, scene):
    """``(motion, current_kp, current_ki, sample_time, q0)`` of a parsed design file.

    Parameters
    ----------
    data : dict
        The parsed JSON (version already checked).
    scene : Scene
        The scene the design is evaluated on: ``q0_rad`` must lie within its stroke.

    Raises
    ------
    SceneError
        ``--design``, naming the field: an unknown structure or filter, a missing, unknown or
        non-numeric field, a number that is NaN, infinite, a huge integer or outside its range
        (gains, frequencies and the ratio positive and at most :data:`BOUND`; damping ratios
        at most :data:`MAX_ZETA`; current-loop gains >= 0; a sample time of 0 or within
        :data:`SAMPLE_TIME_RANGE`), or an operating point outside the scene's stroke.
    """
    structure, kind = data.get("structure"), data.get("filter")
    if structure not in STRUCTURES:
        raise _fail("structure", f"must be one of {STRUCTURES}", structure)
    if kind not in FILTERS:
        raise _fail("filter", f"must be one of {FILTERS}", kind)
    gains_in, params_in = _table(data, "gains"), _table(data, "filter_params")
    for table, name, known in (("gains", gains_in, GAINS[structure]), ("filter_params", params_in, FILTER_PARAMS[kind])):
        extra = sorted(set(map(str, name)) - set(known))
        if extra:
            raise SceneError(KEY, f"{table}.{extra[0]}: unknown for {structure if table == 'gains' else kind} "
                                  f"(known: {', '.join(known) or 'none'})")
    gains = {g: number(data, f"gains.{g}", 0.0, BOUND, lo_open=True, container=gains_in) for g in GAINS[structure]}
    params = {}
    for p in FILTER_PARAMS[kind]:
        if p == "wn":
            params[p] = number(data, f"filter_params.{p}", 0.0, BOUND, lo_open=True, container=params_in)
        else:
            params[p] = number(data, f"filter_params.{p}", 0.0, MAX_ZETA, lo_open=p != "zeta_zero",
                               container=params_in)
    ratio = number(data, "ratio", 1.0 / BOUND, BOUND)
    kp_i = number(data, "current_kp_v_per_a", 0.0, BOUND)
    ki_i = number(data, "current_ki_v_per_a_s", 0.0, BOUND)
    ts = number(data, "sample_time_s", 0.0, SAMPLE_TIME_RANGE[1])
    if 0 < ts < SAMPLE_TIME_RANGE[0]:
        raise _fail("sample_time_s", f"must be 0 (a continuous controller) or within "
                                     f"[{SAMPLE_TIME_RANGE[0]:g}, {SAMPLE_TIME_RANGE[1]:g}] s", ts)
    lo, hi = scene.drivetrain.stroke
    unit = "m" if scene.drivetrain.output_unit == "m" else "rad"
    q0 = number(data, "q0_rad", -math.inf, math.inf)
    if not lo - 1e-9 * (hi - lo) <= q0 <= hi + 1e-9 * (hi - lo):
        from ..core.output_units import output_unit
        u = output_unit(scene)
        raise SceneError(KEY, f"q0_rad: the operating point must lie within the scene's stroke "
                              f"[{u.text(lo)}, {u.text(hi)}] (got {q0:g} {unit}, {u.text(q0)})")
    return Motion(structure, gains, kind, params, ratio), kp_i, ki_i, ts, q0


def _numbers(data: dict, field: str, lo: float, hi: float, min_len: int = 2, max_len: int = 1025) -> tuple:
    values = data.get(field.rsplit(".", 1)[-1])
    if not isinstance(values, list) or not min_len <= len(values) <= max_len:
        raise SceneError(KEY, f"{field}: must be a list of {min_len} to {max_len} numbers")
    return tuple(number({"v": v}, f"{field}[{k}]", lo, hi, container={f"{field}[{k}]".rsplit(".", 1)[-1]: v})
                 for k, v in enumerate(values))


def command_options(data: dict) -> dict:
    """The optional ``feedforward``, ``schedule`` and ``shaper`` tables of a design file as
    ``Feedforward``, ``GainSchedule`` and ``InputShaper`` (None where a table is absent or
    null), every field checked.

    Raises
    ------
    SceneError
        ``--design``, naming the field (``feedforward.velocity_gain``, ``schedule.error_factor[3]``,
        ``shaper.kind``, ...).
    """
    from .controller import Feedforward
    from .schedule import GainSchedule
    from .shaper import SHAPER_KINDS, InputShaper
    out = {"feedforward": None, "schedule": None, "shaper": None}
    ff = data.get("feedforward")
    if ff is not None:
        if not isinstance(ff, dict):
            raise SceneError(KEY, "feedforward: must be a table (or null)")
        model = ff.get("model", False)
        if not isinstance(model, bool):
            raise _fail("feedforward.model", "must be true or false", model)
        out["feedforward"] = Feedforward(
            velocity=number(ff, "feedforward.velocity_gain", -BOUND, BOUND),
            acceleration=number(ff, "feedforward.acceleration_gain", -BOUND, BOUND), model=model)
    sched = data.get("schedule")
    if sched is not None:
        if not isinstance(sched, dict):
            raise SceneError(KEY, "schedule: must be a table (or null)")
        key = "q_m" if sched.get("output_unit") == "m" else "q_rad"
        q = _numbers(sched, f"schedule.{key}", -BOUND, BOUND)
        ge = _numbers(sched, "schedule.error_factor", 1.0 / BOUND, BOUND, len(q), len(q))
        gw = _numbers(sched, "schedule.speed_factor", 1.0 / BOUND, BOUND, len(q), len(q))
        q0 = number(sched, "schedule.q0", -BOUND, BOUND)
        try:
            out["schedule"] = GainSchedule(q, ge, gw, q0, output_unit="m" if key == "q_m" else "rad")
        except SceneError as exc:
            raise SceneError(KEY, f"schedule: {exc.rule}") from None
    shaper = data.get("shaper")
    if shaper is not None:
        if not isinstance(shaper, dict):
            raise SceneError(KEY, "shaper: must be a table (or null)")
        if shaper.get("kind") not in SHAPER_KINDS:
            raise _fail("shaper.kind", f"must be one of {SHAPER_KINDS}", shaper.get("kind"))
        f = number(shaper, "shaper.frequency_hz", 0.0, BOUND, lo_open=True)
        z = number(shaper, "shaper.damping_ratio", 0.0, 0.99)
        out["shaper"] = InputShaper.from_dict({"kind": shaper["kind"], "frequency_hz": f, "damping_ratio": z,
                                               "mode": str(shaper.get("mode", ""))[:40]})
    return out

