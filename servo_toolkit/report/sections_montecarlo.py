"""Nonlinear Monte Carlo over the scene's ``[robustness]`` variants: every variant's closed-loop
time run with the designed controller (backlash, saturation, friction and the sampled
controller included), the worst tracking error and peak current over the spread, and the
worst variants' traces."""

from __future__ import annotations

import numpy as np

from . import figures
from .section import FigureSpec, NotApplicable, Section, fmt, para, table

#: worst variants listed in the table and traced in the figure
WORST = 3
_LABELS = {"tracking_error": "worst tracking error", "peak_current": "worst peak current"}


def montecarlo_results(ctx):
    """(MonteCarloResult, checks of the scene's Monte Carlo requirements) for the scene's
    ``[robustness]`` variants and the reported design's controller, computed once."""
    spec = ctx.scene.robustness
    if spec is None:
        raise NotApplicable("the scene sets no [robustness] variations")
    ctx.require_drivetrain("the Monte Carlo time runs")

    def compute():
        from ..studies.montecarlo import montecarlo_requirements, result_checks, spec_montecarlo
        requirements = montecarlo_requirements(ctx.scene, spec)
        result = spec_montecarlo(ctx.scene, spec, ctx.design().controller, executor=ctx.executor)
        return result, (result_checks(requirements, result) if requirements else [])
    return ctx.result("montecarlo", compute)


def _traces(result, axes):
    """Tracking error and current of the worst variants over time."""
    for i in result.worst_indices(WORST):
        tr = result.trace(int(i))
        axes[0].plot(tr.times, tr.unit.show(tr.output_angle - tr.reference_angle), lw=1, label=f"#{i}")
        axes[1].plot(tr.times, tr.motor_current, lw=1, label=f"#{i}")
    unit = result.unit
    axes[0].set(xlabel="time [s]", ylabel=f"tracking error [{unit.shown}]",
                title=f"the {WORST} worst variants (tracking error)")
    axes[1].set(xlabel="time [s]", ylabel="motor current [A]", title="their motor current")
    for ax in axes:
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize="x-small")


def montecarlo_section(ctx) -> Section:
    """Worst tracking error and peak current of the nonlinear closed loop over the
    ``[robustness]`` variants: scatter over the spread, the worst variants' traces and a
    table of them, and the Monte Carlo requirements when the scene sets them."""
    result, checks = montecarlo_results(ctx)
    unit = result.unit
    reference = result.runner[2]
    fig, axes = figures.new_figure(2, 2, size=(11.0, 7.0))
    result.plot(axes[0])
    _traces(result, axes[1])
    failed = int(np.sum(result.failed))
    text = para(
        f"{result.count} variants ({result.settings['method'].replace('_', ' ')}): {result.ranges_text()}. "
        f"Each runs the {reference.describe(unit.si)} for {result.duration_s:g} s with the reported design's "
        f"controller on the {result.settings['model']} nonlinear model that simulate runs for this command "
        f"(friction, current and voltage limits, the sampled controller; what it leaves out is noted below), "
        f"{result.steps_per_variant} RK4 steps of {fmt(result.dt_s, 3)} s, in {fmt(result.wall_s, 2)} s of integration.",
        f"{int(np.sum(result.saturated))} variants reached a current or voltage limit; {failed} failed"
        + (" (" + "; ".join(sorted({result.reasons[i] for i in np.flatnonzero(result.failed)}))[:300] + ")"
           if failed else "") + ".")
    if result.notes:
        text += para(*(f"Note: {n}" for n in result.notes))
    if not checks:
        text += para("The scene bounds neither the variants' tracking error nor their peak current "
                     "([robustness] max_tracking_error, max_peak_current): the variants are shown here, not judged. "
                     "The time rows of the requirements (tracking_error and the others) judge the nominal "
                     "actuator alone, so a variant above the nominal bound contradicts none of them.")
    worst_rows = []
    for i in result.worst_indices(WORST):
        worst_rows.append((f"#{i}", result.variant_text(i),
                           f"{fmt(result.error_display[i])} {result.error_unit}",
                           f"{fmt(result.peak_current[i])} A", "yes" if result.saturated[i] else "no"))
    body = table(("variant", "parameters", "max |tracking error|", "peak |current|", "at a limit"), worst_rows,
                 table_id="montecarlo-worst")
    status = "info"
    if checks:
        status = "pass" if all(c.passed for c in checks) else "fail"
        body += table(("requirement", "required", "achieved", "status"),
                      [(_LABELS[c.name], f"{c.sense} {fmt(c.required)} {c.unit}", f"{fmt(c.achieved)} {c.unit}",
                        "pass" if c.passed else "FAIL") for c in checks], table_id="montecarlo-requirements")
    return Section("Nonlinear Monte Carlo over the parameter variants", text + body,
                   (FigureSpec(fig, "Top: each variant's largest tracking error and peak current against the load "
                                    "inertia (colour: stiffness factor; red x: failed). Bottom: the worst "
                                    "variants run again with every step recorded (#i: the variant of the table, its parameters there)."),),
                   status=status, key="montecarlo")
