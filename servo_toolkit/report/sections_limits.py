"""What the model leaves out: assumptions of the linear design, simplifications of the
simulation, and (when available) the reduction study's measured differences."""

from __future__ import annotations

import math

import numpy as np

from ..core.output_units import OutputUnit, output_unit
from . import figures
from .references import NEGLECT_CRITERION, REFERENCES
from .section import FigureSpec, NotAvailable, Section, badge, esc, fmt, para, plain, table

#: measured / model stiffness at 100, 200, 300 N*m (Ref. [2], its table 1)
SEED001_TEST_OVER_MODEL = (434.25 / 637.65, 467.96 / 648.03, 482.42 / 661.06)


def _design_assumptions(ctx) -> list[str]:
    drive = ctx.scene.drivetrain
    q = np.linspace(*drive.stroke, 121)
    n, _ = drive.ratio(q)
    j, _ = drive.inertia(q)
    out = []
    try:
        d = ctx.design()
    except NotAvailable:
        d = None
    q0 = d.q0 if d is not None else drive.mid_stroke
    out.append(f"The loop is designed and its margins computed on a linear model at one operating point, "
               f"q0 = {output_unit(drive).text(q0)}. Along the stroke the ratio N varies by a factor "
               f"{n.max() / n.min():.3g} and the reflected inertia by {j.max() / j.min():.3g}; use "
               "servo-toolkit check --vary for the worst case over variations.")
    chain = drive.stiffness(q)
    if chain.names:
        neg = [nm for nm, flag in zip(chain.names, chain.negligible()) if flag]
        if neg:
            out.append(f"Stages whose compliance share stays below 0.1 % over the stroke (the {NEGLECT_CRITERION}) "
                       f"could be treated as rigid: {', '.join(neg)}.")
        lo, hi = min(SEED001_TEST_OVER_MODEL), max(SEED001_TEST_OVER_MODEL)
        out.append(f"Stiffness is a chain of ideal series springs. The test rig of {REFERENCES[1].cite} measured {lo:.0%} to {hi:.0%} "
                   "of such a model's stiffness, so the real drivetrain resonance may lie "
                   f"{1 - math.sqrt(hi):.0%} to {1 - math.sqrt(lo):.0%} lower than the one shown here.")
    if d is not None:
        p = d.parameters
        from ..plant import DEFAULT_STRUCTURAL_DAMPING as zeta
        if not p.rigid:
            out.append(f"The drivetrain mode's damping is not in the scene; the design assumes a damping ratio of "
                       f"{zeta:g}.")
        if p.L > 0:
            bw = d.margins.bandwidth_hz
            fe = p.R / (2 * math.pi * p.L)
            out.append(f"Armature inductance is kept: its corner R/(2 pi L) = {fmt(fe)} Hz is "
                       f"{fmt(fe / bw if bw else math.inf, 3)} times the loop bandwidth.")
        out.append("The linear loop leaves out the voltage and current limits, Coulomb friction, backlash and "
                   "encoder quantization; sampling enters as a delay of 1.5 sample times. The time responses "
                   "above compare it with the nonlinear simulation, which includes them.")
    lash = drive.backlash(np.array([q0]))[0]
    if lash > 0:
        u = output_unit(drive)
        total = f"{u.text(lash, 3)}" if u.linear else f"{math.degrees(lash) * 60:.3g} arcmin"
        out.append(f"Total lost motion at the output: {total}; half of it, {u.text(lash / 2, 3)}, is "
                   f"{lash / 2 / u.default_amplitude:.2%} of a {u.text(u.default_amplitude)} sine's amplitude.")
    return out


def _simulation_simplifications() -> list[str]:
    """The bullet list under 'Simplifications' in the simulation model's documentation."""
    from ..sim import model
    doc = model.__doc__ or ""
    if "Simplifications" not in doc:
        return []
    items, current = [], None
    for line in doc.split("Simplifications", 1)[1].splitlines()[1:]:
        stripped = line.strip()
        if stripped.startswith("- "):
            current = [stripped[2:]]
            items.append(current)
        elif stripped and current is not None:
            current.append(stripped)
        elif not stripped and items:
            if current is None:
                continue
            current = None
    from ..sim import chain_split
    texts = [plain(" ".join(i).rstrip(";."), vars(chain_split)) + "." for i in items]
    return [t[:1].upper() + t[1:] for t in texts]


def _measured_reduction(ctx):
    """The reduction of the report's sweep: the a-priori plan and the measured difference.

    :func:`servo_toolkit.studies.reduce.run.reduce` on the scene's sweep study, with the report's
    sweep settings: as defined under full settings (each effect left out also measured on its
    own), the report's light points and short dwells otherwise.
    """
    from dataclasses import replace

    from . import sections_studies as studies
    from ..studies.reduce import reduce
    name, freqs, _, options = studies.sweep_settings(ctx)
    light = {"frequencies": freqs, "plan": options["plan"]} if ctx.light else {}
    res = reduce(ctx.scene, name, controller=ctx.design().controller, executor=ctx.executor, progress=False,
                 per_effect=not ctx.light, **light)
    if ctx.light:
        res = replace(res, notes=tuple(res.notes) + (
            "light settings: the report's sweep points and short dwells (servo-toolkit reduce SCENE, or "
            "report --full, for the study as defined)",))
    return res


def _reduction(ctx):
    """HTML and figures of the reduction study."""
    res = _measured_reduction(ctx)
    plan = res.plan
    alone = {c.effect: c.measured for c in res.per_effect}
    rows = [(e.effect, e.quantity, fmt(e.estimate, 3), fmt(_db(e.estimate), 3), fmt(_deg(e.estimate), 3))
            + ((fmt(alone[e.effect], 3) if e.effect in alone else "",) if alone else ())
            + (badge("left out" if e.omitted else "kept"), _why(e.reason)) for e in plan.effects]
    head = (("effect", "compared", "estimate |dT/T|", "[dB]", "[deg]") + (("measured alone",) if alone else ())
            + ("decision", "why"))
    left = ", ".join(e.effect for e in plan.omitted) or "nothing"
    freqs = res.frequencies_hz
    measured, bound = res.measured, res.bound
    verdict = res.verdict  # "within", "NOT within" or "not applicable" (no point within the limits)
    text = [f"Each modelled effect judged against the sweep study {res.study or '(default: 8 Hz)'} "
            f"({freqs.size} frequencies {fmt(freqs[0], 3)} to {fmt(freqs[-1], 3)} Hz, amplitudes "
            f"{', '.join(OutputUnit(res.output_unit).text(a, 3) for a in res.amplitudes_rad)}): the a-priori estimate is "
            "the largest relative change of the closed-loop response theta/theta_ref if the effect is left out.",
            f"The reduced model leaves out: {left}. Sum of the estimates of what is left out "
            f"{fmt(plan.predicted, 3)}; a-priori bound (tolerance) {fmt(bound, 3)} = {fmt(_db(bound), 3)} dB / "
            f"{fmt(_deg(bound), 3)} deg.",
            ("Nothing to measure: the reduced model is the full model (every effect kept, friction that holds "
             "included), and the sweep ran it." if res.same_model else
             f"Measured full (every effect kept, friction that holds included) against reduced (sine dwell, over "
             f"{res.counts()}): largest relative difference {fmt(measured, 3)} = "
             f"{fmt(_db(measured), 3)} dB / {fmt(_deg(measured), 3)} deg, {verdict} the bound (run times are not "
             "compared here: one sweep of each model is too noisy a timing; servo-toolkit accuracy times the solvers "
             "from the best of repeated runs).")]
    if np.any(res.saturated):
        text.append(f"Points where a run reached the current or voltage limit are outside the linear statement; "
                    f"their largest difference is {fmt(res.measured_saturated, 3)}.")
    if res.failed.any():
        text.append(f"Points whose run failed are not compared: {res.failed_text()}.")
    text += [n[:1].upper() + n[1:] + "." for n in tuple(plan.notes) + tuple(res.notes)]
    fig, ax = figures.new_figure(size=(7.0, 3.4))
    res.plot(ax=ax)
    spec = FigureSpec(fig, "Measured relative difference between the full and the reduced model, with the "
                           "a-priori bound.")
    return table(head, rows, cls="reduce") + para(*text), spec


def _why(reason: str) -> str:
    for prefix in ("left out: ", "kept: "):
        if reason.startswith(prefix):
            return reason[len(prefix):]
    return reason


def _db(e):
    return 20 * math.log10(1 + e) if math.isfinite(e) else math.inf


def _deg(e):
    return math.degrees(math.asin(min(e, 1.0))) if math.isfinite(e) else math.nan


def leaves_out(ctx) -> Section:
    """What the model leaves out, and why."""
    ctx.require_drivetrain("this section")
    parts = ["<h3>Linear design model</h3>", "<ul>" + "".join(f"<li>{esc(plain(t))}</li>" for t in _design_assumptions(ctx)) + "</ul>"]
    sim = _simulation_simplifications()
    if sim:
        parts += ["<h3>Nonlinear simulation</h3>", "<ul>" + "".join(f"<li>{esc(plain(t))}</li>" for t in sim) + "</ul>"]
    parts.append("<h3>Reduction study: what the sweep's model leaves out, and what that costs</h3>")
    figs = ()
    try:
        html, spec = _reduction(ctx)
        parts.append(html)
        figs = (spec,)
    except Exception as exc:  # noqa: BLE001 - the rest of the section stands on its own
        parts.append(f'<div class="unavailable-box">not available: {esc(type(exc).__name__)}: {esc(exc)}</div>')
    return Section("What the model leaves out", para("What the models behind this report simplify, and what "
                   "that may cost.") + "".join(parts), figs, key="reduce")
