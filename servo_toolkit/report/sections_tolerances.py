"""Tolerances: the yield of the design over the scene's ``[tolerances]`` (and ``[robustness]``
ranges) with its confidence intervals, which tolerance drives each figure, and the worst
corner run again."""

from __future__ import annotations

import numpy as np

from . import figures
from .section import FigureSpec, NotApplicable, Section, fmt, para, table


def tolerance_results(ctx):
    """The :class:`~servo_toolkit.studies.tolerances.result.ToleranceResult` of the scene and
    the reported design, computed once (shared with the requirement rows)."""
    tol = ctx.scene.tolerances
    if tol is None:
        raise NotApplicable("the scene sets no [tolerances] (nor [robustness] ranges)")
    ctx.require_drivetrain("the tolerance study")

    def compute():
        from ..studies.tolerances import tolerance_study
        return tolerance_study(ctx.scene, ctx.design(), executor=ctx.executor, progress=False)
    return ctx.result("tolerances", compute)


def _yield_axes(result, ax) -> None:
    """Each requirement's yield with its interval; the required yield as a line."""
    ys = list(result.yields)
    pos = np.arange(len(ys))[::-1]
    frac = np.array([100 * y.fraction for y in ys])
    err = np.array([[100 * (y.fraction - y.low) for y in ys], [100 * (y.high - y.fraction) for y in ys]])
    ax.errorbar(frac, pos, xerr=np.clip(err, 0, None), fmt="o", color="C0", capsize=3)
    ax.set_yticks(pos, [y.name for y in ys])
    if result.tolerances.min_yield is not None:
        ax.axvline(100 * result.tolerances.min_yield, color="C3", ls="--", lw=1, label="required yield")
        ax.legend(fontsize="x-small")
    ax.set(xlabel=f"yield, {100 * ys[-1].confidence:g} % Clopper-Pearson interval [%]",
           title="fraction of the variants meeting each requirement")
    ax.grid(True, axis="x", alpha=0.3)


def tolerances_section(ctx) -> Section:
    """Yields with intervals, the sensitivity ranking as bars, the worst corner."""
    r = tolerance_results(ctx)
    fig, axes = figures.new_figure(1, 2, size=(11.0, 0.9 + 0.42 * max(len(r.yields), len(r.tolerances.items))))
    _yield_axes(r, axes[0])
    r.plot(axes[1])
    tol = r.tolerances
    req = tol.min_yield
    text = para(
        f"{r.count} variants drawn by {r.settings['method']} (random seed {r.settings['seed']}) from {len(tol.items)} "
        "tolerances, each with the reported design's controller: " + "; ".join(
            f"{t.key} {r.describe(t)}" for t in tol.items) + ".",
        ("The design must reach a yield of " + f"{fmt(100 * req)} % on the lower end of the interval."
         if req is not None else "The scene requires no yield (min_yield); the yields are reported."),
        "A Clopper-Pearson interval covers the true yield at least at its stated rate for independent draws and "
        "stays conservative for a Latin hypercube or Sobol sample.")
    rows = [(y.name, y.label, f"{fmt(100 * y.fraction, 4)} %", f"{fmt(100 * y.low, 4)}..{fmt(100 * y.high, 4)} %",
             f"{y.passed} / {y.total}", "" if y.required is None else ("pass" if y.met else "FAIL"))
            for y in r.yields]
    body = table(("requirement", "met by", "yield", "interval", "variants", "status"), rows,
                 table_id="tolerance-yields")
    rank_rows = []
    for s in r.sensitivities:
        top = ", ".join(f"{k} {fmt(100 * v, 3)} % [{fmt(100 * lo, 2)}..{fmt(100 * hi, 2)}]"
                        for k, v, lo, hi in [x for x in s.ranking() if not s.inert[s.keys.index(x[0])]][:3]
                        ) if s.method != "none" else ""
        rank_rows.append((s.label, s.method, fmt(s.r2, 3), top, s.reason))
    body += table(("figure", "method", "R^2", "largest shares of its variance", "why"), rank_rows,
                  table_id="tolerance-sensitivity")
    if r.worst is not None:
        w = r.worst
        at = r.corner_text()
        ref = w.reference
        run = f" {w.run_text()[0].upper()}{w.run_text()[1:]}." if w.run_text() else ""
        how = (f"smallest margin to a requirement {fmt(100 * w.score, 3)} % ({w.figure})" if np.isfinite(w.score)
               else w.verdict())
        body += para(f"Worst corner over {w.basis} ({w.evaluated()}): {at}; {how}. "
                     f"python-control on its plant built exactly: gain margin "
                     f"{fmt(ref.get('gain_margin_db'), 4)} dB, phase margin {fmt(ref.get('phase_margin_deg'), 4)} deg "
                     f"(the vectorized study: {fmt(w.figures['gain_margin_db'], 4)} dB, "
                     f"{fmt(w.figures['phase_margin_deg'], 4)} deg)." + run)
    if r.notes:
        body += para(*(f"Note: {n}" for n in r.notes))
    status = "info" if req is None else ("pass" if r.passed else "fail")
    return Section("Tolerances: yield and sensitivity", text + body,
                   (FigureSpec(fig, "Left: the yield of each requirement with its interval (dashed: the required "
                                    "yield). Right: the share of the variance of a figure each tolerance explains, "
                                    "with its interval."),),
                   status=status, key="tolerances")
