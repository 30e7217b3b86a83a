"""Margins along the stroke: the designed loop's gain margin, phase margin, Ms and
bandwidth against the operating point, and the loop at the binding point beside q0."""

from __future__ import annotations

import math

import numpy as np

from . import figures
from .section import FigureSpec, NotApplicable, Section, fmt, para, table

F_MIN, F_MAX = 0.1, 1000.0
#: figure -> (label, unit, requirement attribute, the requirement's sense)
FIGURES = {"gain_margin_db": ("gain margin", "dB", "min_gain_margin", ">="),
           "phase_margin_deg": ("phase margin", "deg", "min_phase_margin", ">="),
           "sensitivity_peak_db": ("sensitivity peak Ms", "dB", "max_sensitivity_peak", "<="),
           "bandwidth_hz": ("closed-loop bandwidth", "Hz", "bandwidth", ">=")}


def _required(scene, attr):
    value = getattr(scene.requirements, attr, None)
    if value is None:
        return None
    return math.degrees(value) if attr == "min_phase_margin" else value


def binding_point(stroke, scene):
    """(figure, q) of the stroke point that binds: the smallest slack against the scene's
    requirement (the smallest gain margin when the scene sets none); an unstable point
    binds first."""
    if not stroke.all_stable:
        k = int(np.argmax(stroke.max_pole_real))
        return "max_pole_real", float(stroke.q[k])
    best = None
    for key, (_, _, attr, sense) in FIGURES.items():
        req = _required(scene, attr)
        vals = np.asarray(getattr(stroke, key), float)
        if req is None or not np.any(np.isfinite(vals)):
            continue
        slack = (vals - req) / abs(req) if sense == ">=" else (req - vals) / abs(req)
        k = int(np.nanargmin(slack))
        if best is None or slack[k] < best[0]:
            best = (slack[k], key, float(stroke.q[k]))
    if best is None:
        k = int(np.argmin(stroke.gain_margin_db))
        return "gain_margin_db", float(stroke.q[k])
    return best[1], best[2]


def _x(stroke):
    if stroke.output_unit == "m":
        return stroke.q * 1e3, "output travel [mm]", 1e3
    return np.degrees(stroke.q), "output angle [deg]", 180 / math.pi


def margins_along_stroke(ctx) -> Section:
    """GM, PM, Ms and bandwidth along the stroke; Bode and Nyquist at the binding point."""
    from ..loop.closed_loop import open_loop
    d = ctx.design()
    st = d.stroke
    if st is None:
        raise NotApplicable("the design was not checked along the stroke (a drivetrain without a stroke)")
    x, xlabel, scale = _x(st)
    order = np.argsort(st.q)
    fig, axes = figures.new_figure(2, 2, size=(9.0, 6.0), sharex=True)
    rows = []
    which, q_bind = binding_point(st, ctx.scene)
    for ax, (key, (label, unit, attr, sense)) in zip(np.ravel(axes), FIGURES.items()):
        vals = np.asarray(getattr(st, key), float)
        shown = np.where(st.stable, vals, np.nan)
        ax.plot(x[order], shown[order], "C0.-", ms=3)
        if np.any(~st.stable):
            ax.plot(x[~st.stable], np.zeros(int(np.sum(~st.stable))), "rx", label="unstable")
        req = _required(ctx.scene, attr)
        if req is not None:
            ax.axhline(req, color="C3", ls="--", lw=0.9, label="requirement (table below)")
        ax.axvline(st.q0 * scale, color="C2", lw=0.8, ls=":", label="q0")
        ax.set(ylabel=f"{label} [{unit}]")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize="x-small")
        worst = st.worst().get(key)
        if worst is not None:
            rows.append((label, f"{fmt(worst['value'])} {unit}", st.show(worst["q"]),
                         f"{fmt(vals[np.argmin(np.abs(st.q - st.q0))])} {unit}",
                         "" if req is None else f"{sense} {fmt(req)} {unit}"))
    for ax in np.ravel(axes)[2:]:
        ax.set_xlabel(xlabel)
    fig.suptitle("The loop designed at q0 along the stroke")
    f = np.logspace(math.log10(F_MIN), math.log10(F_MAX), 1200)
    fig2, (am, ap, an) = figures.new_figure(1, 3, size=(11.0, 3.8))
    import control as ct
    for q, label, style in ((d.q0, f"q0 = {st.show(d.q0)}", "-"), (q_bind, f"binding q = {st.show(q_bind)}", "--")):
        loop = d.loop if q == d.q0 else open_loop(ctx.scene, d.controller, q)
        lw = np.asarray(ct.frequency_response(loop, 2 * np.pi * f).complex).reshape(-1)
        am.semilogx(f, 20 * np.log10(np.abs(lw)), style, label=label)
        ap.semilogx(f, np.degrees(np.unwrap(np.angle(lw))), style, label=label)
        an.plot(lw.real, lw.imag, style, label=label)
        an.plot(lw.real, -lw.imag, style, color=an.lines[-1].get_color(), lw=0.6)
    am.axhline(0, color="k", lw=0.7)
    am.set(xlabel="frequency [Hz]", ylabel="|L| [dB]", title="Open-loop gain")
    ap.set(xlabel="frequency [Hz]", ylabel="phase of L [deg]", title="Open-loop phase")
    t = np.linspace(0, 2 * np.pi, 200)
    an.plot(np.cos(t), np.sin(t), color="0.6", lw=0.7)
    an.plot([-1], [0], "r+", ms=12, mew=2)
    an.set(xlim=(-3, 1.5), ylim=(-2.5, 2.0), xlabel="Re L", ylabel="Im L", title="Nyquist near -1", aspect="equal")
    for ax in (am, ap, an):
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize="x-small")
    bind = "stability: the least stable point" if which == "max_pole_real" else FIGURES[which][0]
    text = para(f"The controller designed at q0 = {st.show(st.q0)} runs unchanged at {st.q.size} operating points "
                f"from {st.show(st.q.min())} to {st.show(st.q.max())}; {int(np.sum(~st.stable))} of them are "
                f"unstable. The binding point (smallest slack against the requirements, here on the {bind}) is "
                f"q = {st.show(q_bind)}; its loop is drawn beside the loop at q0.")
    body = table(("figure", "worst over the stroke", "at", "at q0", "required"), rows, table_id="stroke-table")
    return Section("Margins along the stroke", text + body,
                   (FigureSpec(fig, "Gain margin, phase margin, Ms and bandwidth along the stroke."),
                    FigureSpec(fig2, "Open loop at q0 and at the binding point of the stroke.")), key="stroke")
