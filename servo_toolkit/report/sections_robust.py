"""Robustness of the design over the scene's ``[robustness]`` variants, beside the nominal
design over the same variants."""

from __future__ import annotations

import numpy as np

from . import figures
from .section import FigureSpec, NotApplicable, Section, fmt, para, table

#: figure -> (label, unit)
FIGURES = {"gain_margin_db": ("gain margin", "dB"), "phase_margin_deg": ("phase margin", "deg"),
           "sensitivity_peak_db": ("sensitivity peak Ms", "dB")}
_LABELS = {"stable_fraction": "stable variants (fraction)", "gain_margin": "gain margin",
           "phase_margin": "phase margin", "sensitivity_peak": "sensitivity peak Ms",
           "bandwidth": "closed-loop bandwidth", "phase_lag_at_bandwidth": "phase lag at the bandwidth"}


def robust_results(ctx):
    """(robust design's RobustnessResult, the nominal design's over the same variants)."""
    d = ctx.design()
    if d.robustness is None:
        raise NotApplicable("the scene sets no [robustness] variations")

    def nominal():
        from ..loop import design
        from ..loop.robustness import robustness
        nom = design(ctx.scene, robust=False, progress=False)
        return robustness(ctx.scene, nom, spec=ctx.scene.robustness, progress=False)
    return d.robustness, ctx.result("nominal_robustness", nominal)


def robustness(ctx) -> Section:
    """Variant margins as scatter and histogram, worst cases, robust against nominal."""
    robust, nominal = robust_results(ctx)
    linear = ctx.scene.drivetrain.output_is_linear
    shown = ctx.scene.display
    x = (shown.show("inertia", np.asarray(robust.values["load_inertia"]), linear)
         if "load_inertia" in robust.values else np.arange(robust.count))
    xlabel = (f"load {'mass' if linear else 'inertia'} [{shown.inertia_unit(linear)}]"
              if "load_inertia" in robust.values else "variant")
    fig, axes = figures.new_figure(2, 3, size=(11.0, 6.0))
    for col, (key, (label, unit)) in enumerate(FIGURES.items()):
        ax, hist = axes[0, col], axes[1, col]
        for res, name, colour in ((nominal, "nominal design", "C1"), (robust, "robust design", "C0")):
            stable = res.figures["stable"]
            y = np.where(stable, res.figures[key], np.nan)
            ax.scatter(x, y, s=4, color=colour, alpha=0.6, label=name)
            finite = y[np.isfinite(y)]
            if finite.size:
                hist.hist(finite, bins=30, color=colour, alpha=0.5, label=name)
            if np.any(~stable):
                ax.scatter(x[~stable], np.zeros(int(np.sum(~stable))), marker="x", color="r", s=10)
        ax.set(xlabel=xlabel, ylabel=f"{label} [{unit}]")
        hist.set(xlabel=f"{label} [{unit}]", ylabel="variants")
        for a in (ax, hist):
            a.grid(True, alpha=0.3)
        ax.legend(fontsize="x-small", markerscale=3)
    fig.suptitle(f"Margins over {robust.count} variants (red x: unstable)")
    rows = []
    nom = {c.name: c for c in nominal.requirements}
    for c in robust.requirements:
        n = nom.get(c.name)
        at = robust.variant_text(robust.worst.get(c.name, {}))
        rows.append((_LABELS.get(c.name, c.name), f"{c.sense} {fmt(c.required)} {c.unit}",
                     f"{fmt(c.achieved)} {c.unit}", "pass" if c.passed else "FAIL", at,
                     f"{fmt(n.achieved)} {n.unit} ({'pass' if n.passed else 'FAIL'})" if n is not None else ""))
    text = para(f"Variants: {robust.count} ({robust.settings.get('method', '').replace('_', ' ')}), "
                f"{robust.ranges_text()}; the robust design has "
                f"{robust.unstable_count} unstable variants, the nominal design {nominal.unstable_count}.",
                "Worst case over the stable variants against the robustness requirements; the last column is "
                "the nominal design (designed for the nominal plant alone) over the same variants.")
    body = table(("requirement", "required", "robust design", "status", "worst variant", "nominal design"), rows,
                 table_id="robustness-table")
    return Section("Robustness over the parameter variants", text + body,
                   (FigureSpec(fig, "Margins of each variant: scatter against the load inertia and histograms."),),
                   status="pass" if robust.passed else "fail", key="robustness")
