"""What the model leaves out: assumptions of the linear design, simplifications of the
simulation, and (when available) the reduction study's measured differences."""

from __future__ import annotations

import importlib
import math

import numpy as np

from .context import api
from .section import NotAvailable, Section, esc, fmt, para, table

#: seed 001 table 1: measured / model stiffness at 100, 200, 300 N*m
SEED001_TEST_OVER_MODEL = (434.25 / 637.65, 467.96 / 648.03, 482.42 / 661.06)


def _design_assumptions(ctx) -> list[str]:
    dt = ctx.scene.drivetrain
    q = np.linspace(*dt.stroke, 121)
    n, _ = dt.ratio(q)
    j, _ = dt.inertia(q)
    out = []
    try:
        d = ctx.design()
    except NotAvailable:
        d = None
    q0 = d.q0 if d is not None else dt.mid_stroke
    out.append(f"The loop is designed and its margins computed on a linear model at one operating point, "
               f"q0 = {math.degrees(q0):+.1f} deg. Along the stroke the ratio N varies by a factor "
               f"{n.max() / n.min():.3g} and the reflected inertia by {j.max() / j.min():.3g}; use "
               "`servo-toolkit check --vary` for the worst case over variations.")
    chain = dt.stiffness(q)
    if chain.names:
        neg = [nm for nm, flag in zip(chain.names, chain.negligible()) if flag]
        if neg:
            out.append("Stages whose compliance share stays below 0.1 % over the stroke (seed 001's criterion) "
                       f"could be treated as rigid: {', '.join(neg)}.")
        lo, hi = min(SEED001_TEST_OVER_MODEL), max(SEED001_TEST_OVER_MODEL)
        out.append(f"Stiffness is a chain of ideal series springs. Seed 001's test rig measured {lo:.0%} to {hi:.0%} "
                   "of such a model's stiffness, so the real drivetrain resonance may lie "
                   f"{1 - math.sqrt(hi):.0%} to {1 - math.sqrt(lo):.0%} lower than the one shown here.")
    if d is not None:
        p = d.parameters
        plant_mod = importlib.import_module("servo_toolkit.plant")
        zeta = getattr(plant_mod, "DEFAULT_STRUCTURAL_DAMPING", None)
        if zeta is not None and not p.rigid:
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
    lash = dt.backlash(np.array([q0]))[0]
    if lash > 0:
        half = math.degrees(lash) / 2
        out.append(f"Total lost motion at the output: {math.degrees(lash) * 60:.3g} arcmin; half of it, "
                   f"{half:.3g} deg, is {half / 2:.2%} of a 2 deg sine's amplitude.")
    return out


def _simulation_simplifications() -> list[str]:
    """The bullet list under 'Simplifications' in the simulation model's documentation."""
    try:
        doc = importlib.import_module("servo_toolkit.sim.model").__doc__ or ""
    except ImportError:
        return []
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
    texts = [" ".join(i).rstrip(";.").replace("``", "") + "." for i in items]
    return [t[:1].upper() + t[1:] for t in texts]


def _reduction(ctx) -> str:
    reduce = api("servo_toolkit.studies.reduce", "reduce")
    res = reduce(ctx.scene)
    if hasattr(res, "to_dict"):
        d = res.to_dict()
        rows = []
        for item in d.get("effects", d.get("items", [])):
            rows.append((item.get("name", ""), "left out" if item.get("left_out", item.get("dropped")) else "kept",
                         item.get("reason", ""), fmt(item.get("difference", item.get("error", math.nan)))))
        if rows:
            return table(("effect", "decision", "why", "measured difference"), rows)
        return f"<pre>{esc(res.table() if hasattr(res, 'table') else d)}</pre>"
    return f"<pre>{esc(res)}</pre>"


def leaves_out(ctx) -> Section:
    """What the model leaves out, and why."""
    ctx.require_drivetrain("this section")
    parts = ["<h3>Linear design model</h3>", "<ul>" + "".join(f"<li>{esc(t)}</li>" for t in _design_assumptions(ctx)) + "</ul>"]
    sim = _simulation_simplifications()
    if sim:
        parts += ["<h3>Nonlinear simulation</h3>", "<ul>" + "".join(f"<li>{esc(t)}</li>" for t in sim) + "</ul>"]
    parts.append("<h3>Reduction study</h3>")
    try:
        parts.append(_reduction(ctx))
    except NotAvailable as exc:
        parts.append(f'<div class="unavailable-box">not available: {esc(exc)}</div>')
    return Section("What the model leaves out", para("What the models behind this report simplify, and what "
                   "that may cost.") + "".join(parts), key="reduce")
