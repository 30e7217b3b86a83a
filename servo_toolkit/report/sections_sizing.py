"""Section on the sizing along the scene's ``[duty_cycle]``: the motor's torque-speed points
against its envelope, the winding's thermal trace and the ratio sweep, with the margins the
requirement table gates on (:func:`servo_toolkit.studies.gate.sizing_rows`)."""

from __future__ import annotations

from . import figures
from .section import FigureSpec, NotApplicable, Section, fmt, para, table


def sizing_result(ctx):
    """The scene's :class:`~servo_toolkit.studies.sizing.SizingResult` (inverse dynamics, with
    the ratio sweep), computed once per report; :class:`NotApplicable` without a duty cycle."""
    if ctx.scene.duty_cycle is None:
        raise NotApplicable("the scene has no [duty_cycle] to size the motor and the screw along")
    ctx.require_drivetrain("the sizing")

    def compute():
        from ..studies.sizing import size
        return size(ctx.scene, sweep=True, progress=False)
    return ctx.result("sizing", compute)


def sizing_for_gate(ctx):
    """What :func:`~servo_toolkit.studies.gate.gate` takes as ``sizing``: the result, the
    error it raised, or None when the scene has no duty cycle."""
    if ctx.scene.duty_cycle is None or not ctx.has_drivetrain():
        return None
    try:
        return sizing_result(ctx)
    except Exception as exc:  # noqa: BLE001 - no verdict: the rows say why
        return exc


def _figure(draw, size=(7.0, 3.6)):
    fig, ax = figures.new_figure(1, 1, size=size)
    draw(ax)
    return fig


def sizing(ctx) -> Section:
    """Torque-speed points on the envelope, thermal trace, ratio sweep and the margins."""
    res = sizing_result(ctx)
    from ..studies.gate import sizing_rows
    rows = [(r.id, r.requirement, r.required, r.achieved, r.status) for r in sizing_rows(res)]
    facts = [("cycle duration", f"{fmt(res.motion.duration)} s"), ("RMS torque", f"{fmt(res.rms_torque)} N*m"),
             ("RMS current", f"{fmt(res.rms_current)} A"), ("peak mechanical power", f"{fmt(res.peak_power)} W"),
             ("peak electrical power", f"{fmt(res.peak_electrical_power)} W"),
             ("regenerated energy per cycle", f"{fmt(res.regenerated_energy)} J")]
    facts += [(f"L10 {life.part}", f"{fmt(life.hours)} h (F_m {fmt(life.equivalent_load)} N, C {fmt(life.rating)} N)")
              for life in res.lives]
    text = para("The motor and the screw along the scene's [duty_cycle], repeated back to back, from the inverse "
                "dynamics (efficiency by direction of power flow, ratio and inertia along the stroke): the same "
                "figures as servo-toolkit size, and the margins as rows of servo-toolkit check.")
    text += table(("quantity", "value"), facts)
    text += table(("ID", "requirement", "required", "achieved", "status"), rows, table_id="sizing-table")
    figs = [FigureSpec(_figure(res.plot_torque_speed),
                       "Motor torque against speed over the cycle, inside the peak torque and the supply's "
                       "voltage line (hot winding), with the continuous torque."),
            FigureSpec(_figure(res.plot_thermal),
                       "Winding temperature at the end of each cycle from a cold start, and the peak of the "
                       "steady periodic state (two-node network, copper resistance rising with temperature).")]
    if res.sweep is not None:
        from ..studies.sizing.sweep_plot import layout
        rows, cols = layout(res.sweep)
        fig, axes = figures.new_figure(rows, cols, size=(3.2 * cols, 6.0), sharex=True)
        res.plot_sweep(axes)
        what = "the screw's L10 (its lead swept), " if res.sweep.lives else ""
        figs.append(FigureSpec(fig, f"Ratio sweep ({res.sweep.swept}) over the overall ratio, per motor: RMS "
                               "current, peak torque and speed, peak voltage (hot winding), peak winding "
                               "temperature, the achievable bandwidth (an estimate from the chain's resonance), "
                               f"{what}the output stiffness (the chain's, the same at every ratio); dashed lines "
                               "the limits, shaded the feasible ratios (every limit holds; the legend names the "
                               "limits that end them), dotted the scene's ratio."))
    return Section("Sizing along the duty cycle", text, tuple(figs), status="pass" if res.passed else "fail",
                   key="sizing")


__all__ = ["sizing", "sizing_for_gate", "sizing_result"]
