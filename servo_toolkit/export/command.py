"""What the exported controller adds around its feedback: the feedforward gains with the
ratio table of the speed reference, the gain schedule's table and the command shaper's
impulses at the motion sample rate (JSON and C helpers, :mod:`.c_command`).

In a fixed-point export every table value is rounded to the coefficient word in its own Q
format (as the motion controller's coefficients, :func:`.quantize.q_format`); the C helpers
compute with the rounded values, and the export states what the rounding costs: the largest
relative error of each table and, for the schedule, the crossover's largest deviation from
q0 over the stroke with the rounded factors (:func:`servo_toolkit.loop.stroke.stroke_check`).
The shaper's impulse times are whole motion samples (the drive delays its command by samples):
their rounding leaves the residual vibration that
:meth:`~servo_toolkit.loop.shaper.InputShaper.residual_vibration` states at the mode.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .quantize import FORMATS, q_format, q_name

#: points of the ratio table of the feedforward's speed reference (without a schedule)
RATIO_POINTS = 17


def _rounded(values, word: int | None):
    """``(rounded values, Q name, largest relative error)``; unrounded without a word."""
    v = np.asarray(values, float)
    if word is None:
        return v, "float64", 0.0
    f = q_format(v, word)
    r = np.round(v * 2.0**f) / 2.0**f
    scale = np.max(np.abs(v)) if v.size else 1.0
    return r, q_name(word, f), float(np.max(np.abs(r - v)) / scale) if scale > 0 else 0.0


@dataclass(frozen=True)
class CommandExport:
    """The exported command options (each None when the controller has none).

    Attributes
    ----------
    sample_time : float
        Motion sample time (s).
    feedforward : dict or None
        ``velocity``, ``acceleration`` (rounded gains), ``model`` (True: the model-based
        feedforward ran in the simulation; the export carries the designed gains at q0 for
        it), ``ratio_q`` and ``ratio`` (the table of N(q) for the speed reference N(r) r').
    schedule : GainSchedule or None
        The schedule with its rounded factors.
    shaper : dict or None
        ``amplitudes`` (rounded), ``delays_samples``, ``residual_vibration`` of the rounded
        shaper at the mode (0 for the exact one), the design's shaper as ``design``.
    rounding : dict
        Largest relative rounding error and Q format per table.
    crossover_deviation : float or None
        With a schedule: the largest |f_c / f_c(q0) - 1| over the stroke with the exported
        (rounded) factors.
    """

    sample_time: float
    feedforward: dict | None = None
    schedule: object = None
    shaper: dict | None = None
    rounding: dict | None = None
    crossover_deviation: float | None = None

    @property
    def empty(self) -> bool:
        return self.feedforward is None and self.schedule is None and self.shaper is None

    def to_dict(self) -> dict:
        out = {"rounding": self.rounding or {}}
        if self.feedforward is not None:
            ff = self.feedforward
            out["feedforward"] = {"velocity_gain": ff["velocity"], "acceleration_gain": ff["acceleration"],
                                  "model_in_simulation": ff["model"], "ratio_table": {
                                      "q": list(map(float, ff["ratio_q"])), "ratio": list(map(float, ff["ratio"]))},
                                  "i_ff": "velocity_gain * r' + acceleration_gain * r''",
                                  "speed_reference": "N(r) r' (ratio table, linear, ends held), subtracted from "
                                                     "the measured motor speed"}
        if self.schedule is not None:
            out["schedule"] = {**self.schedule.to_dict(), "crossover_deviation_from_q0": self.crossover_deviation}
        if self.shaper is not None:
            out["shaper"] = {k: v for k, v in self.shaper.items() if k != "design"}
            out["shaper"]["design"] = self.shaper["design"].to_dict()
        return out


def command_export(design_result, scene, fmt: str | None = None) -> CommandExport:
    """The command options of ``design_result.controller`` for export (rounded to ``fmt``'s
    coefficient word when given)."""
    ctrl = design_result.controller
    ts = ctrl.sample_time
    word = None if fmt is None else FORMATS[fmt][0]
    rounding, out = {}, {}
    ff = ctrl.feedforward
    schedule = ctrl.schedule
    if ff is not None and ff.active:
        kv, ka = ff.velocity, ff.acceleration
        if ff.model:  # the drive's share of the model-based feedforward: the designed gains at q0
            from ..loop.feedforward import feedforward_gains
            g = feedforward_gains(scene, design_result.q0)
            kv, ka = kv + g["velocity"], ka + g["acceleration"]
        gains, name, err = _rounded([kv, ka], word)
        rounding["feedforward_gains"] = {"format": name, "relative_error": err}
        if schedule is not None:
            q = np.array(schedule.q)
        else:
            lo, hi = scene.drivetrain.stroke
            q = np.linspace(lo, hi, RATIO_POINTS)
        ratio, name, err = _rounded(np.abs(scene.drivetrain.ratio(q)[0]), word)
        rounding["ratio_table"] = {"format": name, "relative_error": err}
        out["feedforward"] = {"velocity": float(gains[0]), "acceleration": float(gains[1]), "model": ff.model,
                              "ratio_q": q, "ratio": ratio}
    deviation = None
    if schedule is not None:
        ge, name_e, err_e = _rounded(schedule.error_factor, word)
        gw, name_w, err_w = _rounded(schedule.speed_factor, word)
        rounding["schedule"] = {"format": f"{name_e} / {name_w}", "relative_error": max(err_e, err_w)}
        schedule = replace(schedule, error_factor=tuple(map(float, ge)), speed_factor=tuple(map(float, gw)))
        from ..loop.stroke import stroke_check
        check = stroke_check(scene, replace(ctrl, schedule=schedule), design_result.q0)
        deviation = check.spread().get("crossover_deviation_from_q0")
    if ctrl.shaper is not None:
        s = ctrl.shaper
        amps, name, err = _rounded(s.amplitudes, word)
        delays = [int(round(t / ts)) for t in s.times]
        rounded = replace(s, times=tuple(d * ts for d in delays), amplitudes=tuple(map(float, amps)))
        rounding["shaper"] = {"format": name, "relative_error": err}
        out["shaper"] = {"amplitudes": list(map(float, amps)), "delays_samples": delays,
                         "delays_s": [d * ts for d in delays], "delay_s": delays[-1] * ts,
                         "residual_vibration": rounded.residual_vibration(s.frequency, s.damping_ratio),
                         "design": s}
    return CommandExport(ts, out.get("feedforward"), schedule, out.get("shaper"), rounding, deviation)


def describe(export) -> list:
    """Text lines of an export's command options."""
    lines = []
    if export.feedforward is not None:
        ff = export.feedforward
        lines.append(f"  feedforward: i_ff = {ff['velocity']:.6g} r' + {ff['acceleration']:.6g} r'' A, speed reference "
                     f"N(r) r' ({len(ff['ratio'])}-point ratio table)"
                     + (" (the simulation's model-based feedforward exported as its gains at q0)" if ff["model"] else ""))
    if export.schedule is not None:
        lines.append(f"  {export.schedule.describe()}; crossover within "
                     f"{100 * (export.crossover_deviation or 0.0):.2g} % of q0's over the stroke with the exported table")
    if export.shaper is not None:
        s = export.shaper
        lines.append(f"  shaper: {s['design'].describe()}; impulses at {s['delays_samples']} samples, residual "
                     f"vibration {100 * s['residual_vibration']:.2g} % of the unshaped at the mode")
    for key, r in (export.rounding or {}).items():
        if r["relative_error"] > 0:
            lines.append(f"  {key} rounded to {r['format']}: largest relative error {r['relative_error']:.2g}")
    return lines


def ring_length(export) -> int:
    """Samples of the shaper's command history (its longest delay + 1; 1 without a shaper)."""
    return 1 if export.shaper is None else int(max(export.shaper["delays_samples"])) + 1


__all__ = ["CommandExport", "RATIO_POINTS", "command_export", "describe", "ring_length"]
