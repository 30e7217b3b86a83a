"""What a designed loop offers around its feedback: the designed feedforward gains, the gain
schedule along the stroke (with the stroke check's spread with and without it) and the ZV /
ZVD command shapers on the drivetrain mode with their delays, and the speed, acceleration and
jerk a command may ask within the motor's limits (``design --json``'s ``command``, the
report's loop section)."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..display.cards import RichDisplay, card, facts, num
from .feedforward import feedforward_gains
from .schedule import gain_schedule
from .shaper import SHAPER_KINDS, drivetrain_modes, shaper_for


@dataclass(frozen=True, repr=False)
class CommandDesign(RichDisplay):
    """The command options of a design.

    Attributes
    ----------
    scene_name : str
    gains : dict
        :func:`~.feedforward.feedforward_gains` at the design's q0.
    schedule : GainSchedule or None
        None when the stroke does not move the ratio or inertia (nothing to schedule).
    stroke_fixed, stroke_scheduled : StrokeCheck or None
        The stroke check of the design's controller as it is, and with the schedule.
    shapers : dict
        ``"zv"`` / ``"zvd"`` -> InputShaper on the mode a command through the loop excites
        (empty for a rigid drivetrain).
    modes : dict
        :func:`~.shaper.drivetrain_modes` (frequency Hz, damping ratio) by name.
    output_unit : {"rad", "m"}
    reach : Reach or None
        The limits a command within the motor's reach keeps (:mod:`.reach`; a step through
        them is :func:`~.reach.reach_profile`); None when the motor cannot hold the load.
    """

    scene_name: str
    gains: dict
    schedule: object = None
    stroke_fixed: object = None
    stroke_scheduled: object = None
    shapers: dict | None = None
    modes: dict | None = None
    output_unit: str = "rad"
    reach: object = None

    def to_dict(self) -> dict:
        """JSON-ready (SI)."""
        out = {"feedforward_gains": {"velocity_A_per_unit_s": self.gains["velocity"],
                                     "acceleration_A_per_unit_s2": self.gains["acceleration"],
                                     "q0": self.gains["q0"], "inertia": self.gains["inertia"],
                                     "ratio": self.gains["ratio"],
                                     "formula": "Ka = J(q0) / (N(q0) Kt), Kv = (b N(q0)^2 + c_load) / (N(q0) Kt)"},
               "schedule": None if self.schedule is None else self.schedule.to_dict(),
               "shapers": {k: s.to_dict() for k, s in (self.shapers or {}).items()},
               "modes": {k: {"frequency_hz": f, "damping_ratio": z} for k, (f, z) in (self.modes or {}).items()}}
        out["reach"] = None if self.reach is None else self.reach.to_dict()
        if self.stroke_fixed is not None and self.stroke_scheduled is not None:
            out["stroke_spread"] = {"fixed_gains": self.stroke_fixed.spread(),
                                    "scheduled_gains": self.stroke_scheduled.spread()}
        return out

    def lines(self) -> list:
        """Text lines for the command line and the report."""
        u = "m" if self.output_unit == "m" else "rad"
        g = self.gains
        out = [f"  feedforward gains at q0: velocity {g['velocity']:.4g} A*s/{u}, acceleration "
               f"{g['acceleration']:.4g} A*s^2/{u} (J {g['inertia']:.4g} {'kg' if u == 'm' else 'kg*m^2'}, "
               f"N {g['ratio']:.4g} rad/{u})"]
        if self.schedule is not None:
            out.append(f"  {self.schedule.describe()}")
            if self.stroke_fixed is not None and self.stroke_scheduled is not None \
                    and not (self.stroke_fixed.all_stable and self.stroke_scheduled.all_stable):
                out.append("  over the stroke, fixed -> scheduled gains: no margin spread, the closed loop is "
                           f"unstable at {int(np.sum(~self.stroke_fixed.stable))} -> "
                           f"{int(np.sum(~self.stroke_scheduled.stable))} of {self.stroke_fixed.q.size} points")
            elif self.stroke_fixed is not None and self.stroke_scheduled is not None:
                a, b = self.stroke_fixed.spread(), self.stroke_scheduled.spread()
                out.append(f"  over the stroke, fixed -> scheduled gains: crossover spread "
                           f"{100 * a.get('crossover', math.nan):.3g} % -> {100 * b.get('crossover', math.nan):.3g} %, "
                           f"phase margin spread {a.get('phase_margin_deg', math.nan):.3g} -> "
                           f"{b.get('phase_margin_deg', math.nan):.3g} deg, gain margin spread "
                           f"{a.get('gain_margin_db', math.nan):.3g} -> {b.get('gain_margin_db', math.nan):.3g} dB")
        for s in (self.shapers or {}).values():
            out.append(f"  command shaper: {s.describe()}")
        if self.reach is not None:
            out.append(f"  {self.reach.describe(self.output_unit)} (a step through them: loop.reach.reach_profile)")
        return out

    def _repr_line(self) -> str:
        return (f"{self.scene_name}: feedforward Kv {self.gains['velocity']:.3g}, Ka {self.gains['acceleration']:.3g}"
                + ("" if self.schedule is None else ", scheduled gains") + f", {len(self.shapers or {})} shapers")

    def _repr_card(self) -> str:
        rows = [("velocity gain", num(self.gains["velocity"])), ("acceleration gain", num(self.gains["acceleration"]))]
        rows += [(f"{k.upper()} shaper delay", f"{num(s.delay * 1e3)} ms") for k, s in (self.shapers or {}).items()]
        return card(f"Command options of {self.scene_name}", parts=[facts(rows)], notes=self.lines())


def command_design(scene, result) -> CommandDesign:
    """The command options of a designed loop ``result`` on ``scene``.

    The gain schedule is left out when the ratio and the motor-side inertia vary by less than
    0.1 % over the stroke; the shapers when the drivetrain is rigid.
    """
    from .stroke import stroke_check
    gains = feedforward_gains(scene, result.q0)
    schedule = gain_schedule(scene, result.q0)
    spread = max(max(schedule.error_factor) - min(schedule.error_factor),
                 max(schedule.speed_factor) - min(schedule.speed_factor))
    fixed = scheduled = None
    if spread < 1e-3:
        schedule = None
    elif result.stroke is not None:
        fixed = result.stroke
        scheduled = stroke_check(scene, replace(result.controller, schedule=schedule), result.q0)
    shapers, modes = {}, {}
    if not result.parameters.rigid:
        modes = drivetrain_modes(scene, result.controller, result.q0)
        shapers = {k: shaper_for(scene, k, q0=result.q0, controller=result.controller) for k in SHAPER_KINDS}
    from ..errors import SceneError
    from .reach import reach
    try:
        limits = reach(scene, result.q0)
    except SceneError:  # the motor cannot hold the load: no move fits (the sizing says so)
        limits = None
    return CommandDesign(scene.name, gains, schedule, fixed, scheduled, shapers, modes, scene.drivetrain.output_unit,
                         limits)


__all__ = ["CommandDesign", "command_design"]
