"""The actuator's nonlinear closed loop judged in time: figures read off the step and the
requirement sine (:mod:`.runs`), against the bounds of :mod:`.spec`, as requirement rows."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ...core.output_units import OutputUnit
from ...display.cards import RichDisplay, card, facts, svg
from ...display.legends import legend_beside
from ...display.html import fmt, telling_digits
from .figures import HARMONICS, LimitCycle, limit_cycle, ripple, rms, step_figures, time_at_limit
from .runs import JUDGED_CYCLES, SINE_CYCLES, STEP_AT, TRANSIENT_CYCLES, window

#: row ID -> words of the requirement ({f}: the sine's frequency)
LABELS = {
    "step_overshoot": "step: overshoot (nonlinear, full model)",
    "step_settling_time": "step: settling time into the band (nonlinear, full model)",
    "position_error_at_rest": "step: |position error| at rest after the motion",
    "limit_cycle": "step: limit cycle or hunting after the motion (amplitude)",
    "tracking_error": "sine {f}: peak tracking error (nonlinear, full model)",
    "current_ripple": "current ripple: rms of the motor current above the motion's content",
    "rms_current": "sine {f}: rms motor current against the continuous rating",
    "time_at_current_limit": "sine {f}: time at the current limit (within 1 %)",
    "time_at_voltage_limit": "sine {f}: time at the voltage limit (within 1 %)",
}
#: the rows read off the step run, and off the sine run
STEP_ROWS = ("step_overshoot", "step_settling_time", "position_error_at_rest", "limit_cycle")
SINE_ROWS = ("tracking_error", "rms_current", "time_at_current_limit", "time_at_voltage_limit")
IDS = tuple(LABELS)


@dataclass(frozen=True, repr=False)
class ActuatorCheck(RichDisplay):
    """The nonlinear closed loop's step and requirement sine, their figures and rows.

    Attributes
    ----------
    plan : Plan
        The commands and bounds (:func:`.spec.plan`).
    step_run, sine_run : SimulationResult or None
        None for a run that left the stroke (``failure``).
    q0 : float
        The operating point (SI).
    figures : dict
        Row ID -> achieved figure (SI: fraction, s, rad or m, A; ``inf`` for a step that
        never settles; NaN for a run that left the stroke).
    limit_cycle, motor_cycle : LimitCycle or None
        The output's, and the motor side's (at the output), oscillation after the step.
    details : dict
        Row ID -> where the figure comes from.
    ripples : dict
        ``"step"`` (at rest after the step) and ``"sine"`` (its judged periods) -> the
        current ripple of each run (A); the ``current_ripple`` figure is the larger.
    failure : str
        Why a run ended early ("" when both went through).
    stroke_end_s : float
        When the first run that left the stroke did so (NaN when none did).
    output_unit : str
    notes : tuple of str
    current_limit : float
        The motor's current limit (A), drawn beside the currents.
    """

    plan: object
    step_run: object
    sine_run: object
    q0: float
    figures: dict
    limit_cycle: LimitCycle | None
    motor_cycle: LimitCycle | None
    details: dict = field(default_factory=dict)
    ripples: dict = field(default_factory=dict)
    failure: str = ""
    stroke_end_s: float = math.nan
    output_unit: str = "rad"
    notes: tuple = ()
    current_limit: float = math.inf

    @property
    def unit(self) -> OutputUnit:
        return OutputUnit(self.output_unit)

    def rows(self) -> list:
        """The requirement rows (:class:`~servo_toolkit.studies.gate.RequirementRow`), one per bound."""
        from ..gate import RequirementRow
        out = []
        f = f"{fmt(self.plan.frequency)} Hz"
        for b in self.plan.bounds:
            label = LABELS[b.name].format(f=f)
            value = self.figures.get(b.name, math.nan)
            detail = "; ".join(x for x in ((f"default: {b.rule}" if b.source == "default" else ""),
                                           self.details.get(b.name, "")) if x)
            required = f"<= {fmt(b.value * b.factor)} {b.unit}"
            if math.isnan(value):
                why = self.failure or "no figure"
                out.append(RequirementRow(b.name, label, required, "no figure", "", "fail",
                                          "; ".join(x for x in (why, detail) if x)))
                continue
            ok = bool(value <= b.value * (1 + 1e-12) + 1e-300)
            shown = value * b.factor
            achieved = "not settled" if math.isinf(value) else \
                f"{fmt(shown, telling_digits(shown, b.value * b.factor, 4))} {b.unit}"
            short = "" if ok else ("inf" if math.isinf(value) else f"{fmt((value - b.value) * b.factor, 3)} {b.unit}")
            out.append(RequirementRow(b.name, label, required, achieved, short, "pass" if ok else "fail", detail))
        return out

    @property
    def passed(self) -> bool:
        return all(r.passed for r in self.rows())

    def to_dict(self) -> dict:
        """JSON-ready: the commands, the figures (SI, units in the keys) and the rows."""
        u = self.unit
        pos = {"position_error_at_rest", "limit_cycle", "tracking_error"}
        figs = {}
        for k, v in self.figures.items():
            key = f"{k}_{u.si}" if k in pos else {"step_overshoot": "step_overshoot_fraction",
                                                 "step_settling_time": "step_settling_time_s"}.get(k, f"{k}_{'s' if k.startswith('time_') else 'A'}")
            figs[key] = None if isinstance(v, float) and math.isnan(v) else v
        cyc = {n: None if c is None else {f"amplitude_{u.si}": c.amplitude, "frequency_Hz": c.frequency}
               for n, c in (("limit_cycle", self.limit_cycle), ("motor_side_cycle", self.motor_cycle))}
        return {f"step_{u.si}": self.plan.step, f"sine_amplitude_{u.si}": self.plan.sine_amplitude,
                "sine_frequency_Hz": self.plan.frequency, "model": "full chain, friction that holds",
                "figures": figs, **cyc, "failure": self.failure or None,
                "rows": [r.to_dict() for r in self.rows()], "notes": list(self.notes)}

    def step_trace(self):
        """``(t, y)``: times from the step (s) and the output's change (SI)."""
        r = self.step_run
        t = r.times - STEP_AT
        y = r.output_angle - r.output_angle[max(int(np.searchsorted(t, 0.0)) - 1, 0)]
        return t, y

    def plot(self, axes=None):
        """The step and the sine (command and output) and their currents; returns the axes."""
        import matplotlib.pyplot as plt
        if axes is None:
            _, axes = plt.subplots(2, 2, figsize=(10.0, 5.6), sharex="col", layout="constrained")
        u = self.unit
        (a1, a2), (a3, a4) = np.asarray(axes).reshape(2, 2)
        if self.step_run is not None:
            t, y = self.step_trace()
            a1.plot(t * 1e3, u.show(np.where(t >= 0, self.plan.step, 0.0)), color="0.55", lw=0.9, label="command")
            a1.plot(t * 1e3, u.show(y), color="C0", label="output")
            band = self.plan.rest_band
            a1.axhspan(u.show(self.plan.step - band), u.show(self.plan.step + band), color="C2", alpha=0.15,
                       label="settling band")
            a3.plot(t * 1e3, self.step_run.motor_current, color="C1", lw=0.8, label="motor current")
        if self.sine_run is not None:
            r = self.sine_run
            a2.plot(r.times * 1e3, u.show(r.reference_angle - self.q0), color="0.55", lw=0.9, label="command")
            a2.plot(r.times * 1e3, u.show(r.output_angle - self.q0), color="C0", label="output")
            a4.plot(r.times * 1e3, r.motor_current, color="C1", lw=0.8, label="motor current")
        for ax in (a3, a4):
            if math.isfinite(self.current_limit):
                ax.axhline(self.current_limit, color="C3", ls="--", lw=0.8, label="current limit")
                ax.axhline(-self.current_limit, color="C3", ls="--", lw=0.8)
            ax.set(xlabel="time [ms]", ylabel="current [A]")
        a1.set(ylabel=f"output change [{u.shown}]", title=f"{u.text(self.plan.step, 3)} step")
        a2.set(ylabel=f"output [{u.shown}]", title=f"{u.text(self.plan.sine_amplitude, 3)} sine at "
                                                  f"{fmt(self.plan.frequency)} Hz")
        for ax in (a1, a2, a3, a4):
            ax.grid(True, alpha=0.3)
        # one legend per row, right of it: the sine and the current limits cross every corner
        legend_beside(a2, [a1], fontsize="x-small")
        legend_beside(a4, [a3], fontsize="x-small")
        return axes

    def _repr_line(self) -> str:
        rows = self.rows()
        failed = [r.id for r in rows if not r.passed]
        return (f"nonlinear step and {fmt(self.plan.frequency)} Hz sine: "
                + ("every row met" if not failed else f"{len(failed)} of {len(rows)} NOT met: {', '.join(failed)}"))

    def _repr_card(self) -> str:
        rows = [(r.id, f"{r.achieved} ({r.required}) {'ok' if r.passed else 'FAIL'}") for r in self.rows()]
        return card("Nonlinear closed loop", status=self.passed,
                    parts=[facts(rows), svg(self.plot, size=(10.0, 5.6), rows=2, cols=2, sharex="col")],
                    notes=self.notes)


def _step_figures(plan, run, u, figures, details):
    t = run.times - STEP_AT
    k = t >= 0.0
    y = run.output_angle - run.output_angle[max(int(np.argmax(k)) - 1, 0)]
    over, settle = step_figures(t[k], y[k], plan.step, plan.rest_band)
    figures["step_overshoot"], figures["step_settling_time"] = over, settle
    details["step_settling_time"] = f"band +-{u.text(plan.rest_band, 3)} about the step"
    rest = window(t, plan.settling_time)
    tail = window(t, 0.5 * (plan.settling_time + t[-1]))
    # the largest |error| once the motion is over: a response still settling through the
    # window (a mean would cancel its two signs) or resting off the command shows here
    figures["position_error_at_rest"] = float(np.max(np.abs(plan.step - y[tail])))
    resolution = 1e-3 * plan.rest_band
    cyc = limit_cycle(t[rest], y[rest], resolution)
    motor_side = run.trace("motor_side_angle_rad")
    mot = limit_cycle(t[rest], motor_side[rest], resolution)
    figures["limit_cycle"] = 0.0 if cyc is None else cyc.amplitude
    if cyc is not None:
        words = f"{u.text(cyc.amplitude, 3)} at {fmt(cyc.frequency, 3)} Hz at the output"
    else:  # no cycle; a response moving through the window by a tenth of the rest band is not at rest
        moved = float(np.max(y[rest]) - np.min(y[rest])) if np.any(rest) else 0.0
        words = ("none" if not moved > 0.1 * plan.rest_band else
                 f"no cycle, but the output still moves {u.text(moved, 3)} over the window (a drift or a creep "
                 "to rest: see position_error_at_rest)")
    if mot is not None:
        words += f"; the motor side oscillates {u.text(mot.amplitude, 3)} (at the output) at {fmt(mot.frequency, 3)} Hz"
    details["limit_cycle"] = f"{words}, over {fmt(t[rest][0] * 1e3)}-{fmt(t[-1] * 1e3)} ms after the step"
    details["position_error_at_rest"] = f"largest over {fmt(t[tail][0] * 1e3)}-{fmt(t[-1] * 1e3)} ms after the step"
    return ripple(t[rest], run.motor_current[rest], HARMONICS * plan.frequency), cyc, mot


def _sine_figures(plan, run, motor, figures, details):
    f = plan.frequency
    judged = window(run.times, (SINE_CYCLES - JUDGED_CYCLES) / f)
    settled = window(run.times, TRANSIENT_CYCLES / f)
    t, i = run.times[judged], run.motor_current[judged]
    figures["tracking_error"] = float(np.max(np.abs(run.output_angle - run.reference_angle)[judged]))
    figures["rms_current"] = rms(i)
    figures["time_at_current_limit"] = time_at_limit(run.times[settled], run.motor_current[settled], motor.current_limit)
    figures["time_at_voltage_limit"] = time_at_limit(run.times[settled], run.motor_voltage[settled], motor.voltage_limit)
    span = f"the last {JUDGED_CYCLES} of {SINE_CYCLES} periods"
    details["tracking_error"] = f"over {span}"
    details["rms_current"] = f"over {span}"
    after = f"after the first {TRANSIENT_CYCLES} periods (the start's transient)"
    peak_i, peak_v = float(np.max(np.abs(run.motor_current[settled]))), float(np.max(np.abs(run.motor_voltage[settled])))
    details["time_at_current_limit"] = f"{after}; peak {fmt(peak_i, 3)} A of {fmt(motor.current_limit)} A"
    details["time_at_voltage_limit"] = f"{after}; peak {fmt(peak_v, 3)} V of {fmt(motor.voltage_limit)} V"
    return ripple(t, i, HARMONICS * f)


def evaluate(scene, design, plan, step_run, sine_run, failure: str = "", stroke_end_s: float = math.nan) -> ActuatorCheck:
    """The figures of the two runs against ``plan``'s bounds."""
    from ...core.output_units import output_unit
    u = output_unit(scene)
    figures = {name: math.nan for name in IDS}
    details, cyc, mot = {}, None, None
    ripples = {}
    if step_run is not None:
        ripples["step"], cyc, mot = _step_figures(plan, step_run, u, figures, details)
    if sine_run is not None:
        ripples["sine"] = _sine_figures(plan, sine_run, scene.motor, figures, details)
    if len(ripples) == 2:
        words = {"step": "at rest after the step", "sine": f"in the sine's last {JUDGED_CYCLES} periods"}
        where = max(ripples, key=ripples.get)
        figures["current_ripple"] = ripples[where]
        other = next(k for k in ripples if k != where)
        details["current_ripple"] = (f"above {fmt(HARMONICS * plan.frequency)} Hz ({HARMONICS} x the command's "
                                     f"frequency), {words[where]} (the other: {fmt(ripples[other], 3)} A "
                                     f"{words[other]})")
    notes = (*plan.notes, "nonlinear rows: the full model (every drivetrain mode, backlash, the limits, the sampled "
             "controller and its encoders) with friction that holds at the motor, each stage and the load")
    return ActuatorCheck(plan, step_run, sine_run, float(design.q0), figures, cyc, mot, details, ripples, failure,
                         stroke_end_s, scene.drivetrain.output_unit, notes, scene.motor.current_limit)


def actuator_check(scene, design, options=None) -> ActuatorCheck:
    """Run and judge ``design``'s controller on the nonlinear actuator (:mod:`.runs`).

    Parameters
    ----------
    scene : Scene
    design : DesignResult
    options : ModelOptions, optional
        Default: the full model with friction that holds (:func:`.runs.full_options`).

    Raises
    ------
    SimulationError
        A run could not be carried out numerically (no verdict on it).
    SceneError
        A position requirement given in the other dimension than the output's, or a design
        made for another scene.
    """
    from .runs import run_both
    from .spec import plan as make_plan
    design.require_scene(scene)
    p = make_plan(scene, design)
    step, sine, failure, end = run_both(scene, design.controller, p, options)
    return evaluate(scene, design, p, step, sine, failure, end)


__all__ = ["ActuatorCheck", "IDS", "LABELS", "SINE_ROWS", "STEP_ROWS", "actuator_check", "evaluate"]
