"""Step response and 8 Hz sine tracking: the linear closed loop and the nonlinear simulation;
the same step with friction that holds (stick phases, position error at rest, hunting)."""

from __future__ import annotations

import math

import numpy as np

from . import figures
from ..errors import SceneError, SimulationError
from ..core.output_units import REQUIREMENT_SINE_HZ, output_unit
from .section import FigureSpec, NotAvailable, Section, fmt, para, table

SINE_HZ = REQUIREMENT_SINE_HZ
#: the step is this fraction of the sine's amplitude (the output's default command amplitude:
#: 2 deg for an angle, 1 mm for a travel)
STEP_FRACTION = 0.5
#: the step with friction that holds runs this many times the step plot's span (a loop
#: hunting against static friction or creeping to rest is slower than its step)
REST_SPANS = 2.0


def _fit_sine(t, y, f):
    """Amplitude and phase (deg) of the component of ``y`` at ``f`` (least squares with offset)."""
    w = 2 * np.pi * f
    a = np.column_stack([np.sin(w * t), np.cos(w * t), np.ones_like(t)])
    (s, c, _), *_ = np.linalg.lstsq(a, y, rcond=None)
    return math.hypot(s, c), math.degrees(math.atan2(c, s))


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
    voltage within 0.1 % of the supply, the current within 0.1 % of its limit."""
    dt = np.diff(result.times, append=result.times[-1])
    i, v = np.abs(result.motor_current), np.abs(result.motor_voltage)
    at_v = v >= motor.voltage_limit * (1 - 1e-3) if math.isfinite(motor.voltage_limit) else np.zeros_like(v, bool)
    at_i = i >= motor.current_limit * (1 - 1e-3) if math.isfinite(motor.current_limit) else np.zeros_like(i, bool)
    return {"peak_current_A": float(i.max()), "peak_voltage_V": float(v.max()),
            "time_at_voltage_limit_s": float(np.sum(dt[at_v])), "time_at_current_limit_s": float(np.sum(dt[at_i]))}


def _electrics(runs, motor):
    """Figure of current and voltage against their limits, one column per run."""
    fig, axes = figures.new_figure(2, len(runs), size=(10.0, 5.0), sharex="col")
    axes = np.asarray(axes).reshape(2, len(runs))
    for col, (title, t, r) in enumerate(runs):
        ai, av = axes[:, col]
        ai.plot(t * 1e3, r.motor_current, label="current")
        av.plot(t * 1e3, r.motor_voltage, "C1", label="voltage")
        for ax, lim, unit in ((ai, motor.current_limit, "A"), (av, motor.voltage_limit, "V")):
            if math.isfinite(lim):
                for sign in (1, -1):
                    ax.axhline(sign * lim, color="C3", ls="--", lw=0.9, label=f"limit +-{lim:g} {unit}" if sign > 0 else None)
            ax.grid(True, alpha=0.3)
            ax.legend(fontsize="x-small")
        ai.set(ylabel="motor current [A]", title=title)
        av.set(ylabel="armature voltage [V]", xlabel="time [ms]")
    return fig


def rest_rows(rest, u):
    """Rows (quantity, value) of a step run to rest with friction that holds: the position
    error at rest and the hunting (amplitude and period of a limit cycle, or none)."""
    from ..studies.hunting import hunting_text
    span = f"{fmt(rest.window * 1e3)}-{fmt(rest.times[-1] * 1e3)} ms"
    err = rest.position_error_at_rest
    if err is None:
        at_rest = f"not at rest at {fmt(rest.times[-1] * 1e3)} ms (error there {fmt(u.show(rest.error[-1]))})"
    else:
        at_rest = fmt(u.show(err)) + (" (largest while hunting)" if rest.hunting is not None else "")
    hunting = hunting_text(rest.hunting, u)
    band = "none (no proportional stiffness)" if rest.dead_band is None else f"+-{fmt(u.show(rest.dead_band))}"
    return [(f"dead band of the proportional path [{u.shown}]", band),
            (f"position error at rest [{u.shown}]", at_rest),
            (f"hunting (amplitude [{u.shown}], period [ms])", f"{hunting} within {span}"),
            ("time stuck (speed exactly 0)", f"{rest.stuck.mean():.0%} ({len(rest.stick_phases)} stick phases)")]


def time_responses(ctx) -> Section:
    """Step and 8 Hz sine: linear closed loop (python-control) and, when available, the
    nonlinear simulation with the same controller (limits, friction, backlash)."""
    import control as ct
    d = ctx.design()
    cl = d.closed_loop
    q0 = d.q0
    u = output_unit(ctx.scene)
    sine_amp = u.show(u.default_amplitude)      # in the shown unit (deg or mm)
    step_amp = STEP_FRACTION * sine_amp
    what = "output travel" if u.linear else "output angle"
    step_title = f"{step_amp:g} {u.shown} step"
    sine_title = f"{sine_amp:g} {u.shown} sine at {SINE_HZ:g} Hz"
    t_step = np.linspace(0.0, 0.25 if ctx.light else 0.5, 1001)
    _, y_step = ct.step_response(cl, t_step)
    y_step = np.asarray(y_step).reshape(-1) * step_amp
    n_cycles = 6 if ctx.light else 12
    t_sine = np.linspace(0.0, n_cycles / SINE_HZ, 200 * n_cycles + 1)
    ref = sine_amp * np.sin(2 * np.pi * SINE_HZ * t_sine)
    _, y_sine = ct.forced_response(cl, t_sine, ref)
    y_sine = np.asarray(y_sine).reshape(-1)
    last = t_sine >= (n_cycles - 2) / SINE_HZ
    amp, ph = _fit_sine(t_sine[last], y_sine[last], SINE_HZ)
    cells, note = step_cells(t_step, y_step, step_amp, "linear")
    rows = [("linear closed loop", *cells, fmt(20 * math.log10(amp / sine_amp)), fmt(ph))]
    notes = [note] if note else []
    nonlinear = None
    electrics, electric_fig = [], None
    try:
        from ..sim import simulate
        from ..sim import Reference as reference
        t_at = 0.01
        r1 = simulate(ctx.scene, d.controller, reference=reference.step(step_amp / u.factor, at=t_at),
                      duration=t_step[-1] + t_at, method="rk4")
        r2 = simulate(ctx.scene, d.controller, reference=reference.sine(sine_amp / u.factor, SINE_HZ),
                      duration=t_sine[-1], method="rk4")
        ts1 = r1.times - t_at
        ys1 = u.show(r1.output_angle - q0)
        ys1 -= ys1[ts1 < 0][-1] if np.any(ts1 < 0) else 0.0
        keep = ts1 >= 0
        ts2, ys2 = r2.times, u.show(r2.output_angle - q0)
        last2 = ts2 >= (n_cycles - 2) / SINE_HZ
        amp2, ph2 = _fit_sine(ts2[last2], ys2[last2], SINE_HZ)
        cells2, note2 = step_cells(ts1[keep], ys1[keep], step_amp, "nonlinear")
        rows.append(("nonlinear simulation", *cells2, fmt(20 * math.log10(amp2 / sine_amp)), fmt(ph2)))
        if note2:
            notes.append(note2)
        nonlinear = (ts1[keep], ys1[keep], ts2, ys2, r2)
        notes.append(f"Nonlinear runs: {r1.method}, step {fmt(r1.dt_s)} s ({r1.choice}); peak motor torque "
                     f"in the sine run {fmt(r2.max_abs_motor_torque)} N*m.")
        motor = ctx.scene.motor
        for name, r in (("step", r1), (f"{SINE_HZ:g} Hz sine", r2)):
            lf = limit_figures(r, motor)
            electrics.append((name, fmt(lf["peak_current_A"]), fmt(motor.current_limit), fmt(lf["peak_voltage_V"]),
                              fmt(motor.voltage_limit), fmt(lf["time_at_current_limit_s"] * 1e3),
                              fmt(lf["time_at_voltage_limit_s"] * 1e3)))
        electric_fig = _electrics(((step_title, r1.times - t_at, r1), (sine_title, r2.times, r2)), motor)
    except NotAvailable as exc:
        notes.append(f"Nonlinear simulation not available: {exc}")
    rest, rest_body = None, ""
    try:
        from ..studies.hunting import rest_study
        rest = rest_study(ctx.scene, d.controller, step=step_amp / u.factor, duration=REST_SPANS * t_step[-1],
                          method="rk4")
        motor = ctx.scene.motor
        rest_body = para(
            f"The same step with friction that holds (the motor's breakaway {fmt(motor.breakaway_torque)} N*m, "
            f"Coulomb {fmt(motor.coulomb_friction)} N*m, and the load's where it has any; the runs above smooth "
            "the motor's Coulomb friction and never stick): the loop stops where the moment it applies no "
            "longer breaks the static friction (within the dead band of its proportional path, before integral "
            "action winds up), or hunts when integral action winds up against it. Stick "
            f"phases (the speed exactly 0) are shaded on the step plot; the run lasts {REST_SPANS:g} times "
            "the plot's span, and the rest and the hunting are judged on its second half.")
        rest_body += table(("friction that holds", "value"), rest_rows(rest, u), table_id="rest-table")
    except (SimulationError, SceneError) as exc:  # the section's time limit (NotAvailable) still stops it
        notes.append(f"Step with friction that holds not available: {exc}")
    fig, (a1, a2) = figures.new_figure(1, 2, size=(10.0, 3.6))
    a1.plot(t_step * 1e3, y_step, label="linear")
    a1.axhline(step_amp, color="0.6", lw=0.8)
    a2.plot(t_sine * 1e3, ref, color="0.6", lw=0.8, label="command")
    a2.plot(t_sine * 1e3, y_sine, label="linear")
    if nonlinear is not None:
        a1.plot(nonlinear[0] * 1e3, nonlinear[1], "--", label="nonlinear")
        a2.plot(nonlinear[2] * 1e3, nonlinear[3], "--", label="nonlinear")
    if rest is not None:
        from ..studies.hunting import shade_stick_phases, show_dead_band
        a1.plot(rest.times * 1e3, step_amp - u.show(rest.error), ":", label="nonlinear, friction that holds")
        shade_stick_phases(a1, rest.stick_phases, scale=1e3)
        if rest.dead_band is not None:
            show_dead_band(a1, step_amp, float(u.show(rest.dead_band)))
        a1.set_xlim(0.0, t_step[-1] * 1e3)
    a1.set(xlabel="time [ms]", ylabel=f"{what} change [{u.shown}]", title=step_title)
    a2.set(xlabel="time [ms]", ylabel=f"{what} change [{u.shown}]", title=sine_title)
    for ax in (a1, a2):
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize="small")
    head = ("model", "rise 10-90 % [ms]", "overshoot", "settling 2 % [ms]", f"gain at {SINE_HZ:g} Hz [dB]",
            f"phase at {SINE_HZ:g} Hz [deg]")
    body = table(head, rows) + rest_body
    figs = [FigureSpec(fig, "Step response and 8 Hz sine tracking"
                       + ("; grey: the shaft stuck in the step with friction that holds; green: the dead band of the loop's "
                          "proportional path about the command." if rest is not None else "."))]
    if electrics:
        body += para("Motor electrics in the nonlinear runs against the drive's limits (time at a limit: within "
                     "0.1 % of it).") + table(("run", "peak current [A]", "current limit [A]", "peak voltage [V]",
                                               "voltage limit [V]", "time at current limit [ms]",
                                               "time at voltage limit [ms]"), electrics, table_id="electrics-table")
        figs.append(FigureSpec(electric_fig, "Motor current and armature voltage against their limits."))
    return Section("Step response and 8 Hz sine tracking",
                   para(f"Small-signal commands about q0 = {u.text(q0)} with the designed controller.",
                        *notes) + body, tuple(figs), key="time")
