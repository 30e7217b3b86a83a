"""Hand tuning of a designed loop: control values -> a DesignResult, and a design's file.

:func:`tuned_design` is a pure function from the tuner's control values
(:class:`LoopTuning`: bandwidth target, the cascade's gains, the resonance filter and the
operating point) to a :class:`~.result.DesignResult` evaluated exactly as
:func:`~.design.design` evaluates its own result (margins on the Nyquist criterion, the
requirement rows, the check along the stroke). The interactive tuner
(:func:`servo_toolkit.tune`) calls it on every change; tests call it without a browser.

A design's controller is written to a small JSON file (:func:`save_design`) that
``check``, ``export`` and ``report`` take with ``--design FILE`` (:func:`load_design`).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

from ..drivetrain.operating_point import checked_q0
from .controller import FEEDFORWARD_KINDS, CascadeController
from .feedforward import designed_feedforward
from ..errors import SceneError
from .design import design, evaluate
from .structures import FILTERS, Motion

#: version of the design file
DESIGN_FILE_VERSION = 1
#: notch defaults when the tuner switches a notch on: pole damping (width) and depth
DEFAULT_NOTCH_WIDTH = 0.5
DEFAULT_NOTCH_DEPTH_DB = -20.0


@dataclass(frozen=True)
class LoopTuning:
    """The tuner's control values; None keeps the base design's value.

    Attributes
    ----------
    bandwidth_hz : float or None
        Bandwidth target of the automatic design the tuning starts from (Hz).
    kp : float or None
        Position gain (1/s).
    kv : float or None
        Speed gain (A per output rad/s).
    wvi : float or None
        Speed-PI integral corner (rad/s).
    resonance_filter : {None, "none", "notch", "lowpass"}
    filter_hz : float or None
        Notch or low-pass frequency (Hz).
    depth_db : float or None
        Notch depth at its frequency (dB, negative): 20 log10(zeta_zero / zeta_pole).
    width : float or None
        Notch pole damping ratio (its width), or the low-pass damping ratio.
    q0 : float or None
        Operating point where the loop is evaluated (rad, or m for an output travel); the
        controller is the same (a loop runs unchanged along the stroke).
    feedforward : {None, "off", "gains", "model"}
        The controller's feedforward (:func:`~.feedforward.designed_feedforward`); outside the
        loop: it changes the tracking, not the margins.
    """

    bandwidth_hz: float | None = None
    kp: float | None = None
    kv: float | None = None
    wvi: float | None = None
    resonance_filter: str | None = None
    filter_hz: float | None = None
    depth_db: float | None = None
    width: float | None = None
    q0: float | None = None
    feedforward: str | None = None

    def check(self) -> None:
        """Raise SceneError(``tuning.<name>``, rule) for a value out of range."""
        for name in ("bandwidth_hz", "kp", "kv", "wvi", "filter_hz", "width"):
            v = getattr(self, name)
            if v is not None and not (math.isfinite(v) and v > 0):
                raise SceneError(f"tuning.{name}", f"must be positive and finite (got {v!r})")
        if self.depth_db is not None and not (math.isfinite(self.depth_db) and self.depth_db < 0):
            raise SceneError("tuning.depth_db", f"a notch depth is negative dB (got {self.depth_db!r})")
        if self.resonance_filter is not None and self.resonance_filter not in FILTERS:
            raise SceneError("tuning.resonance_filter", f"must be one of {FILTERS} (got {self.resonance_filter!r})")
        if self.feedforward is not None and self.feedforward not in FEEDFORWARD_KINDS:
            raise SceneError("tuning.feedforward", f"must be one of {FEEDFORWARD_KINDS} (got {self.feedforward!r})")


def base_design(scene, bandwidth_hz: float | None = None):
    """The automatic design the tuning starts from (a bandwidth target replaces the scene's)."""
    require = {"bandwidth": float(bandwidth_hz)} if bandwidth_hz is not None else None
    return design(scene, require=require, progress=False)


def tuning_of(result) -> LoopTuning:
    """The control values of a design (what the tuner shows first)."""
    m = result.motion
    if m is None or m.structure != "cascade":
        raise SceneError("design", "the tuner tunes a cascade design (position P, speed PI)")
    g, fp = m.gains, m.filter_params
    values = dict(kp=float(g["kp"]), kv=float(g["kv"]), wvi=float(g["wvi"]), resonance_filter=m.filter,
                  q0=float(result.q0))
    if m.filter == "notch":
        values.update(filter_hz=float(fp["wn"]) / (2 * math.pi), width=float(fp["zeta_pole"]),
                      depth_db=20 * math.log10(fp["zeta_zero"] / fp["zeta_pole"]))
    elif m.filter == "lowpass":
        values.update(filter_hz=float(fp["wn"]) / (2 * math.pi), width=float(fp["zeta"]))
    return LoopTuning(**values)


def _filter(tuning: LoopTuning, motion: Motion, base_hz: float):
    kind = tuning.resonance_filter or motion.filter
    if kind == "none":
        return "none", {}
    old = motion.filter_params if motion.filter == kind else {}
    wn = 2 * math.pi * tuning.filter_hz if tuning.filter_hz is not None else old.get("wn", 2 * math.pi * base_hz)
    if kind == "notch":
        zp = tuning.width if tuning.width is not None else old.get("zeta_pole", DEFAULT_NOTCH_WIDTH)
        depth = (tuning.depth_db if tuning.depth_db is not None else
                 20 * math.log10(old["zeta_zero"] / old["zeta_pole"]) if old else DEFAULT_NOTCH_DEPTH_DB)
        return "notch", {"wn": wn, "zeta_zero": zp * 10 ** (depth / 20), "zeta_pole": zp}
    zeta = tuning.width if tuning.width is not None else old.get("zeta", 0.5)
    return "lowpass", {"wn": wn, "zeta": zeta}


def tuned_design(scene, tuning: LoopTuning = LoopTuning(), base=None):
    """The loop with the tuner's values, evaluated as :func:`~.design.design` evaluates.

    Parameters
    ----------
    scene : Scene
    tuning : LoopTuning
        Control values; None keeps the base design's.
    base : DesignResult, optional
        The design to start from (default :func:`base_design` at ``tuning.bandwidth_hz``).

    Returns
    -------
    DesignResult
        Its notes say what was tuned; ``motion`` holds the tuned gains and filter.
    """
    tuning.check()
    if base is None:
        base = base_design(scene, tuning.bandwidth_hz)
    tuning_of(base)  # a cascade design, or a clear error
    m = base.motion
    gains = dict(m.gains)
    changed = []
    for name in ("kp", "kv", "wvi"):
        value = getattr(tuning, name)
        if value is not None:
            if not math.isclose(value, gains[name], rel_tol=1e-12):
                changed.append(f"{name} {gains[name]:.4g} -> {value:.4g}")
            gains[name] = float(value)
    res_hz = base.parameters.resonance_hz if math.isfinite(base.parameters.resonance_hz) else 50.0
    kind, params = _filter(tuning, m, res_hz)
    if kind != m.filter or any(not math.isclose(params[k], m.filter_params.get(k, math.nan)) for k in params):
        changed.append(f"filter {m.filter} -> {kind}" + (" (" + ", ".join(f"{k}={v:.4g}" for k, v in params.items())
                                                         + ")" if params else ""))
    motion = Motion("cascade", gains, kind, params, m.ratio)
    c = base.controller
    ff = c.feedforward if tuning.feedforward is None else designed_feedforward(scene, tuning.feedforward, base.q0)
    ctrl = CascadeController(motion.state_space(), c.current_kp, c.current_ki, c.sample_time,
                             motion.describe(scene.drivetrain.output_unit),
                             feedforward=ff, schedule=c.schedule, shaper=c.shaper)
    if (ff is not None) != (c.feedforward is not None):
        changed.append(f"feedforward {'off' if c.feedforward is None else c.feedforward.kind} -> "
                       f"{'off' if ff is None else ff.kind}")
    q0 = base.q0 if tuning.q0 is None else checked_q0(scene, tuning.q0, "tuning.q0")
    require = {"bandwidth": float(tuning.bandwidth_hz)} if tuning.bandwidth_hz is not None else None
    notes = (f"tuned from the automatic design{' at ' + format(tuning.bandwidth_hz, 'g') + ' Hz' if tuning.bandwidth_hz else ''}: "
             + ("; ".join(changed) if changed else "no change"),)
    if q0 != base.q0:
        notes += (f"evaluated at q0 = {base.unit.text(q0)} (designed at {base.unit.text(base.q0)})",)
    return evaluate(scene, ctrl, q0, motion=motion, notes=notes, require=require)


# --- design files -------------------------------------------------------------------------

def design_data(result) -> dict:
    """The controller of a design as JSON-ready data (what :func:`load_design` reads)."""
    m, c = result.motion, result.controller
    if m is None:
        raise SceneError("design", "only a designed motion controller can be saved")
    return {"servo_toolkit_design": DESIGN_FILE_VERSION, "scene": result.scene_name, "q0_rad": result.q0,
            "structure": m.structure, "gains": dict(m.gains), "filter": m.filter,
            "filter_params": dict(m.filter_params), "ratio": m.ratio,
            "current_kp_v_per_a": c.current_kp, "current_ki_v_per_a_s": c.current_ki,
            "sample_time_s": c.sample_time, **_command_data(c)}


def _command_data(controller) -> dict:
    """The controller's feedforward (its gains and the model switch), gain schedule and command
    shaper, where it has them."""
    out = {}
    ff = controller.feedforward
    if ff is not None and ff.active:
        out["feedforward"] = {"velocity_gain": ff.velocity, "acceleration_gain": ff.acceleration, "model": ff.model}
    if controller.schedule is not None:
        out["schedule"] = controller.schedule.to_dict()
    if controller.shaper is not None:
        out["shaper"] = controller.shaper.to_dict()
    return out


def save_design(result, path, inputs=()) -> Path:
    """Write the design's controller to ``path`` (JSON, atomically; never over an input)."""
    from ..core.files import check_output_file, write_text
    path = check_output_file(path, "--design", (".json",), inputs=inputs)
    write_text(path, json.dumps(design_data(result), indent=2) + "\n", "--design")
    return path


#: largest design file read (bytes): a design is well under a kilobyte of JSON
MAX_DESIGN_BYTES = 1024 * 1024


def read_design_text(path) -> str:
    """The text of the design file ``path`` (a regular UTF-8 file of at most
    :data:`MAX_DESIGN_BYTES`; a FIFO or device is refused without blocking): a command checks
    it before any long work.

    Raises
    ------
    SceneError
        ``--design``: not a readable design file.
    """
    from ..core.inputs import read_input_text
    return read_input_text(path, "--design", MAX_DESIGN_BYTES, what=f"the design file {str(path)!r}")


def load_design(scene, path, require=None, text=None):
    """The design saved in ``path``, evaluated on ``scene`` (margins, requirements, stroke).
    ``text``, the file's text read before (:func:`read_design_text`), is used instead of
    reading it again: a command that checks several scenes with one design file reads it
    once, so every scene is checked against the same design.

    Raises
    ------
    SceneError
        ``--design``: not a readable design file, a missing or bad field (named by its JSON
        key, see :func:`.design_file.design_fields`).
    """
    key = "--design"
    if text is None:
        text = read_design_text(path)
    try:
        data = json.loads(text)
    except (json.JSONDecodeError, ValueError) as exc:
        raise SceneError(key, f"cannot read the design file {str(path)!r}: {exc}") from None
    except RecursionError:
        raise SceneError(key, f"the design file {str(path)!r} is nested too deeply") from None
    if not isinstance(data, dict) or data.get("servo_toolkit_design") != DESIGN_FILE_VERSION:
        raise SceneError(key, f"{str(path)!r} is not a servo_toolkit design file (version {DESIGN_FILE_VERSION})")
    from .design_file import command_options, design_fields
    motion, kp_i, ki_i, ts, q0 = design_fields(data, scene)  # every field checked: one line naming it
    ctrl = CascadeController(motion.state_space(), kp_i, ki_i, ts, motion.describe(scene.drivetrain.output_unit),
                             **command_options(data))
    notes = (f"controller from {Path(path).name} (designed for {data.get('scene', '?')})",)
    return evaluate(scene, ctrl, q0, motion=motion, notes=notes, require=require)


__all__ = ["LoopTuning", "base_design", "design_data", "load_design", "save_design", "tuned_design", "tuning_of"]
