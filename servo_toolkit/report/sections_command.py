"""Control that uses the model: the 8 Hz sine's tracking error with and without feedforward
at operating points along the stroke (nonlinear simulation), the gain schedule's effect on the
stroke check, and the command shapers with their delays."""

from __future__ import annotations

import numpy as np

from . import figures
from .section import FigureSpec, NotApplicable, Section, fmt, para, table

#: the sine of the tracking table (its amplitude: the output's default command)
SINE_HZ = 8.0
#: fraction of the stroke's half span at which the side operating points sit
SIDE = 0.6


def _points(scene, q0):
    lo, hi = scene.drivetrain.stroke
    half = 0.5 * (hi - lo)
    return [q0 - SIDE * half, q0, q0 + SIDE * half] if lo < q0 - SIDE * half and q0 + SIDE * half < hi else [q0]


def tracking_along_stroke(scene, design, kinds=("off", "gains", "model"), duration: float | None = None):
    """Peak |tracking error| after the start's transient of the default sine at operating
    points along the stroke, per feedforward kind: ``(points, {kind: errors})`` (rad or m)."""
    from ..core.output_units import output_unit
    from ..sim import Reference, simulate
    from ..studies.time.run import sine_run_options
    u = output_unit(scene)
    points = _points(scene, design.q0)
    duration = 4.0 / SINE_HZ if duration is None else duration
    refs = [Reference.sine(u.default_amplitude, SINE_HZ, offset=q) for q in points]
    options = [sine_run_options(scene, design.controller, ref)[0] for ref in refs]  # the same for every kind
    out = {}
    for kind in kinds:
        out[kind] = np.array([simulate(scene, design.controller, reference=ref, duration=duration, options=opts,
                                       feedforward=kind).settled_tracking_error for ref, opts in zip(refs, options)])
    return np.array(points), out


def command_section(ctx) -> Section:
    """Tracking with and without feedforward along the stroke; schedule; shapers."""
    from ..core.output_units import output_unit
    from ..loop.command_design import command_design
    ctx.require_drivetrain("control that uses the model")
    d = ctx.design()
    scene = ctx.scene
    if scene.sensors.sample_time <= 0:
        raise NotApplicable("the feedforward and the gain schedule run in a sampled controller; the scene's "
                            "controller is continuous")
    u = output_unit(scene)
    cd = command_design(scene, d)
    points, errs = tracking_along_stroke(scene, d)
    rows = [(u.text(q, 4), *(f"{fmt(u.show(errs[k][i]))} {u.shown}" for k in errs),
             f"{fmt(errs['off'][i] / errs['model'][i], 3)}x") for i, q in enumerate(points)]
    text = para(f"The {u.text(u.default_amplitude, 3)}, {SINE_HZ:g} Hz sine at {len(points)} operating points, "
                "simulated with the reduced nonlinear model: the peak tracking error after the start's transient "
                "(its first two periods) with the feedback alone, with the designed velocity and acceleration "
                "gains and with the model-based feedforward (the drivetrain's inverse dynamics along the stroke). "
                "The feedforward is outside the loop: the margins are those of the loop section.")
    body = table(("operating point", "feedback alone", "designed gains", "model-based", "improvement"), rows,
                 table_id="feedforward-table")
    body += para("Command options of the design: " + "; ".join(line.strip() for line in cd.lines()) + ".")
    fig, (ax, bx) = figures.new_figure(1, 2, size=(10.0, 3.6))
    x = u.show(points)
    for k, style in (("off", "o-"), ("gains", "s-"), ("model", "^-")):
        ax.semilogy(x, u.show(errs[k]), style, label={"off": "feedback alone", "gains": "designed gains",
                                                      "model": "model-based"}[k])
    ax.set(xlabel=f"operating point [{u.shown}]", ylabel=f"peak tracking error [{u.shown}]",
           title=f"{SINE_HZ:g} Hz sine after the start's transient")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize="x-small")
    if cd.stroke_fixed is not None and cd.stroke_scheduled is not None:
        # colours of their own: the figure's one legend serves both panels
        for st, label, style in ((cd.stroke_fixed, "fixed gains", "C3.-"), (cd.stroke_scheduled, "scheduled gains",
                                                                             "C4.--")):
            order = np.argsort(st.q)
            bx.plot(u.show(st.q[order]), st.crossover_hz[order], style, label=label)
        bx.set(xlabel=f"operating point [{u.shown}]", ylabel="loop crossover [Hz]", title="Crossover along the stroke")
        bx.legend(fontsize="x-small")
    else:
        bx.text(0.5, 0.5, "no gain schedule (ratio and inertia constant)", ha="center", va="center",
                transform=bx.transAxes)
    bx.grid(True, alpha=0.3)
    better = float(np.min(errs["off"] / errs["model"]))
    text += para(f"The model-based feedforward cuts the peak error at least {better:.3g}x at these points.")
    return Section("Control that uses the model: feedforward, gain schedule, command shaping", text + body,
                   (FigureSpec(fig, "Tracking error along the stroke with and without feedforward, and the loop's "
                                    "crossover with fixed and scheduled gains."),), key="command")


__all__ = ["command_section", "tracking_along_stroke"]
