"""The step and the requirement sine: the linear closed loop beside the actuator's nonlinear
closed loop, the very runs ``check`` judges (:mod:`servo_toolkit.studies.actuator`: the full
model, friction that holds), their rows, their electrics and their friction at rest (stick
phases, position error at rest, hunting)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from . import figures
from ..errors import SceneError, SimulationError
from ..core.output_units import output_unit
from ..studies.gate import fit_sine
from .section import FigureSpec, NotAvailable, Section, badge, fmt, para, table


def _step_metrics(t, y, final):
    """Rise time 10-90 %, overshoot and 2 % settling time of a step of size ``final``."""
    yn = y / final
    rise = t[np.argmax(yn >= 0.9)] - t[np.argmax(yn >= 0.1)] if np.any(yn >= 0.9) else math.nan
    over = max(0.0, float(yn.max() - 1.0))
    outside = np.nonzero(np.abs(yn - 1.0) > 0.02)[0]
    settle = t[outside[-1] + 1] if outside.size and outside[-1] + 1 < t.size else (t[0] if not outside.size else math.nan)
    return rise, over, settle


def step_cells(t, y, final, what: str):
    """(rise, overshoot, settling) cells of a step and a sentence when the response does
    not settle: a missing figure is said in words (how far the output got, and when)."""
    rise, over, settle = _step_metrics(t, y, final)
    reached = float(y[-1] / final)
    cells = (fmt(rise * 1e3) if math.isfinite(rise) else f"not reached ({reached:.0%} at the end)",
             f"{over:.1%}",
             fmt(settle * 1e3) if math.isfinite(settle) else f"not settled within {fmt(t[-1] * 1e3)} ms")
    note = ""
    if not (math.isfinite(rise) and math.isfinite(settle)):
        note = (f"The {what} step does not settle within the {fmt(t[-1] * 1e3)} ms shown: after "
                f"{fmt(t[-1] * 1e3)} ms the output is at {reached:.0%} of the step"
                + ("" if math.isfinite(rise) else ", short of the 90 % a rise time needs")
                + " (2 % band for the settling time).")
    return cells, note


def limit_figures(result, motor) -> dict:
    """Peak |current| and |voltage| of a run and the time spent at each limit (s): the
    voltage within 1 % of the supply, the current within 1 % of its limit (a current pinned at
    99 % of its limit is at it)."""
    from ..studies.actuator.figures import time_at_limit
    t, i, v = result.times, np.abs(result.motor_current), np.abs(result.motor_voltage)
    return {"peak_current_A": float(i.max()), "peak_voltage_V": float(v.max()),
            "time_at_voltage_limit_s": time_at_limit(t, v, motor.voltage_limit),
            "time_at_current_limit_s": time_at_limit(t, i, motor.current_limit)}


def _electrics(runs, motor):
    """Figure of current and voltage against their limits, one column per run."""
    fig, axes = figures.new_figure(2, len(runs), size=(10.0, 5.0), sharex="col")
    axes = np.asarray(axes).reshape(2, len(runs))
    for col, (title, t, r) in enumerate(runs):
        ai, av = axes[:, col]
        ai.plot(t * 1e3, r.motor_current, label="current")
        av.plot(t * 1e3, r.motor_voltage, "C1", label="voltage")
        for ax, lim, unit, style in ((ai, motor.current_limit, "A", dict(color="C3", ls="--")),
                                     (av, motor.voltage_limit, "V", dict(color="C5", ls=":"))):
            if math.isfinite(lim):
                what = "current" if unit == "A" else "voltage"
                for sign in (1, -1):
                    ax.axhline(sign * lim, lw=0.9, label=f"{what} limit +-{lim:g} {unit}" if sign > 0 else None, **style)
            ax.grid(True, alpha=0.3)
            ax.legend(fontsize="x-small")
        ai.set(ylabel="motor current [A]", title=title)
        av.set(ylabel="armature voltage [V]", xlabel="time [ms]")
    return fig


def rest_rows(rest, u, judged=None):
    """Rows (quantity, value) of a step run to rest with friction that holds: the position
    error at rest and the hunting (amplitude and period of a limit cycle, or none).

    ``judged``: ``(figure, detail)`` of the ``position_error_at_rest`` row check judges on the
    same run (the largest error after the motion, SI); shown first when the output is still
    moving at the run's end, so the table and the row say the same."""
    from ..studies.hunting import hunting_text
    span = f"{fmt(rest.window * 1e3)}-{fmt(rest.times[-1] * 1e3)} ms"
    err = rest.position_error_at_rest
    if err is None:
        moving = (f"the output still moves at {fmt(rest.times[-1] * 1e3)} ms, not held by friction "
                  f"(error there {fmt(u.show(rest.error[-1]))})")
        at_rest = moving if judged is None else \
            f"{fmt(u.show(judged[0]))} ({judged[1]}: the figure check judges); {moving}"
    else:
        at_rest = fmt(u.show(err)) + (" (largest while hunting)" if rest.hunting is not None else "")
    hunting = hunting_text(rest.hunting, u)
    band = "none (no proportional stiffness)" if rest.dead_band is None else f"+-{fmt(u.show(rest.dead_band))}"
    return [(f"dead band of the proportional path [{u.shown}]", band),
            (f"position error at rest [{u.shown}]", at_rest),
            (f"hunting (amplitude [{u.shown}], period [ms])", f"{hunting} within {span}"),
            ("time stuck (speed exactly 0)", f"{rest.stuck.mean():.0%} ({len(rest.stick_phases)} stick phases)")]


def _judged_rest(act):
    """``(figure, detail)`` of check's ``position_error_at_rest`` row of ``act``, or None."""
    figure = act.figures.get("position_error_at_rest")
    return None if figure is None else (figure, act.details.get("position_error_at_rest", "largest after the motion"))


def time_title(ctx) -> str:
    """The section's title: the step and the sine at the required bandwidth."""
    try:
        f = next(c.required for c in ctx.design().requirements if c.name == "bandwidth")
    except Exception:  # noqa: BLE001 - the section itself says why it has no design
        return "Step response and sine tracking"
    return f"Step response and {fmt(f)} Hz sine tracking"


def _linear(cl, plan, t_step, t_sine):
    """The linear closed loop's step and sine on the nonlinear runs' grids (SI), computed on
    evenly spaced copies of them (python-control's forced response needs even steps)."""
    import control as ct
    even = np.linspace(t_step[0], t_step[-1], t_step.size)
    _, y_step = ct.step_response(cl, even)
    even_sine = np.linspace(t_sine[0], t_sine[-1], t_sine.size)
    ref = plan.sine_amplitude * np.sin(2 * np.pi * plan.frequency * even_sine)
    _, y_sine = ct.forced_response(cl, even_sine, ref)
    return (np.interp(t_step, even, np.asarray(y_step).reshape(-1) * plan.step),
            plan.sine_amplitude * np.sin(2 * np.pi * plan.frequency * t_sine),
            np.interp(t_sine, even_sine, np.asarray(y_sine).reshape(-1)))


def _model_rows(act, lin_step, t_sine, y_sine_lin, u):
    """(model, rise, overshoot, settling, gain, phase) rows of the linear and the nonlinear loop."""
    plan, f = act.plan, act.plan.frequency
    t, y = act.step_trace()
    keep = t >= 0.0
    last = t_sine >= (t_sine[-1] - 2.0 / f)
    amp, ph = fit_sine(t_sine[last], y_sine_lin[last], f)
    cells, note = step_cells(t[keep], lin_step, plan.step, "linear")
    rows = [("linear closed loop", *cells, fmt(20 * math.log10(amp / plan.sine_amplitude)), fmt(ph))]
    notes = [note] if note else []
    r2 = act.sine_run
    last2 = r2.times >= (r2.times[-1] - 2.0 / f)
    amp2, ph2 = fit_sine(r2.times[last2], r2.output_angle[last2] - act.q0, f)
    cells2, note2 = step_cells(t[keep], y[keep], plan.step, "nonlinear")
    rows.append(("nonlinear simulation", *cells2, fmt(20 * math.log10(amp2 / plan.sine_amplitude)), fmt(ph2)))
    return rows, notes + ([note2] if note2 else [])


def time_responses(ctx) -> Section:
    """The step and the requirement sine: the linear closed loop and the actuator's nonlinear
    runs that ``check`` judges (one set of runs, :meth:`~.context.Context.actuator`), their
    rows, electrics and friction at rest."""
    from ..studies.actuator.runs import STEP_AT
    from ..studies.hunting import analyse, dead_band, load_holds, shade_stick_phases, show_dead_band
    d = ctx.design()
    u = output_unit(ctx.scene)
    try:
        act = ctx.actuator()
    except (SimulationError, SceneError) as exc:
        raise NotAvailable(f"the nonlinear runs could not be carried out: {exc}") from None
    if act is None:
        raise NotAvailable("the linear closed loop is unstable: the nonlinear runs are not made "
                           "(closed_loop_stable fails)")
    if act.step_run is None or act.sine_run is None:
        raise NotAvailable(f"a nonlinear run left the stroke: {act.failure}")
    plan, motor = act.plan, ctx.scene.motor
    t, y = act.step_trace()
    keep = t >= 0.0
    r1, r2 = act.step_run, act.sine_run
    lin_step, ref, y_sine = _linear(d.closed_loop, plan, t[keep], r2.times)
    rows, notes = _model_rows(act, lin_step, r2.times, y_sine, u)
    step_title = f"{u.text(plan.step, 3)} step"
    sine_title = f"{u.text(plan.sine_amplitude, 3)} sine at {fmt(plan.frequency)} Hz"
    notes.append(f"Nonlinear runs: {r1.method}, step {fmt(r1.dt_s)} s ({r1.choice}); the full model with friction "
                 "that holds at the motor, each stage and the load (the runs check judges). "
                 + " ".join(n[0].upper() + n[1:] + "." for n in plan.notes))
    rest = analyse(r1, load_friction=load_holds(ctx.scene), window=plan.settling_time + STEP_AT)
    band = dead_band(ctx.scene, d.controller)
    rest = replace(rest, dead_band=band)
    rest_body = para(
        f"Friction at rest in the same step (the motor's breakaway {fmt(motor.breakaway_torque)} N*m, Coulomb "
        f"{fmt(motor.coulomb_friction)} N*m, and each stage's and the load's): the loop stops where the moment it "
        "applies no longer breaks the static friction, or hunts when integral action winds up against it. Stick "
        "phases (the speed exactly 0) are shaded on the step plot; rest and hunting are judged after the settling "
        "allowance.") + table(("friction that holds", "value"),
                                 rest_rows(rest, u, _judged_rest(act)), table_id="rest-table")
    fig, (a1, a2) = figures.new_figure(1, 2, size=(10.0, 3.6))
    a1.plot(t[keep] * 1e3, u.show(np.full(keep.sum(), plan.step)), color="0.6", lw=0.8, label="command")
    a1.plot(t[keep] * 1e3, u.show(lin_step), label="linear")
    a1.plot(t[keep] * 1e3, u.show(y[keep]), "--", label="nonlinear")
    shade_stick_phases(a1, [(a - STEP_AT, b - STEP_AT) for a, b in rest.stick_phases], scale=1e3)
    if band is not None:
        show_dead_band(a1, float(u.show(plan.step)), float(u.show(band)))
    a1.axhspan(u.show(plan.step - plan.rest_band), u.show(plan.step + plan.rest_band), color="C4", alpha=0.15,
               label="settling band")
    a1.set_xlim(0.0, t[-1] * 1e3)
    a2.plot(r2.times * 1e3, u.show(ref), color="0.6", lw=0.8, label="command")
    a2.plot(r2.times * 1e3, u.show(y_sine), label="linear")
    a2.plot(r2.times * 1e3, u.show(r2.output_angle - act.q0), "--", label="nonlinear")
    what = "output travel" if u.linear else "output angle"
    a1.set(xlabel="time [ms]", ylabel=f"{what} change [{u.shown}]", title=step_title)
    a2.set(xlabel="time [ms]", ylabel=f"{what} change [{u.shown}]", title=sine_title)
    for ax in (a1, a2):
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize="small")
    electrics = []
    for name, r in (("step", r1), (f"{fmt(plan.frequency)} Hz sine", r2)):
        lf = limit_figures(r, motor)
        electrics.append((name, fmt(lf["peak_current_A"]), fmt(motor.current_limit), fmt(lf["peak_voltage_V"]),
                          fmt(motor.voltage_limit), fmt(lf["time_at_current_limit_s"] * 1e3),
                          fmt(lf["time_at_voltage_limit_s"] * 1e3)))
    electric_fig = _electrics(((step_title, r1.times - STEP_AT, r1), (sine_title, r2.times, r2)), motor)
    verdict = [(r.id, r.requirement, r.required, r.achieved, badge(r.status)) for r in act.rows()]
    head = ("model", "rise 10-90 % [ms]", "overshoot", "settling 2 % [ms]", f"gain at {fmt(plan.frequency)} Hz [dB]",
            f"phase at {fmt(plan.frequency)} Hz [deg]")
    body = (para("The rows check judges on these runs (the same rows as the requirements table):")
            + table(("ID", "requirement", "required", "achieved", "status"), verdict, table_id="actuator-table")
            + table(head, rows) + rest_body
            + para("Motor electrics in the nonlinear runs against the drive's limits (time at a limit: within 1 % "
                   "of it).")
            + table(("run", "peak current [A]", "current limit [A]", "peak voltage [V]", "voltage limit [V]",
                     "time at current limit [ms]", "time at voltage limit [ms]"), electrics, table_id="electrics-table"))
    figs = (FigureSpec(fig, f"{step_title} and {sine_title}: linear and nonlinear (full model, friction that holds); "
                            "grey: the shaft stuck; purple: the settling band"
                            + ("; the dead band of the loop's proportional path about the command." if band is not None
                               else ".")),
            FigureSpec(electric_fig, "Motor current and armature voltage against their limits."))
    return Section(time_title(ctx), para(f"Commands about q0 = {u.text(d.q0)} with the designed controller.", *notes)
                   + body, figs, key="time")
