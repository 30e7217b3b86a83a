"""Sections that need only the scene and its drivetrain: summary, stiffness, ratio and inertia."""

from __future__ import annotations

import math

import numpy as np

from . import figures
from .section import FigureSpec, Section, esc, fmt, para, table
from .units_table import rows as unit_rows

DEG = 180.0 / math.pi
TABLE_ANGLES_DEG = (-30.0, 0.0, 10.0, 30.0)


def _q_label(dt) -> str:
    return "cam angle" if dt.ends_in_cam else "output angle"


def _param_table(obj) -> str:
    return table(("parameter", "value", "unit"), unit_rows(obj), cls="params")


def scene_summary(ctx) -> Section:
    """What the scene describes, every parameter in engineering units."""
    scene = ctx.scene
    parts = [para(scene.description or "(no description)"),
             f"<p>Source: <code>{esc(scene.source or 'built-in')}</code></p>"]
    if scene.motor is not None:
        parts.append("<h3>Motor</h3>" + _param_table(scene.motor))
    for i, stage in enumerate(scene.stages):
        parts.append(f"<h3>Stage {i + 1}: {esc(stage.name)} ({esc(type(stage).__name__)})</h3>"
                     + _param_table(stage))
    if scene.stages:
        parts.append("<h3>Load</h3>" + _param_table(scene.load))
    if scene.mechanism is not None:
        parts.append(f"<h3>Mechanism ({esc(type(scene.mechanism).__name__)})</h3>" + _param_table(scene.mechanism))
    for i, stage in enumerate(scene.roller_screw):
        parts.append(f"<h3>Roller-screw stage {i + 1}</h3>" + _param_table(stage))
    if scene.operating is not None:
        parts.append("<h3>Operating point</h3>" + _param_table(scene.operating))
    if scene.stages:
        parts.append("<h3>Sensors</h3>" + _param_table(scene.sensors))
    req = unit_rows(scene.requirements)
    if req:
        parts.append("<h3>Requirements</h3>" + table(("requirement", "value", "unit"), req, cls="params"))
    if scene.studies:
        study_rows = [(s.name, s.kind, ", ".join(sorted(s.params))) for s in scene.studies.values()]
        parts.append("<h3>Studies</h3>" + table(("study", "kind", "parameters"), study_rows))
    return Section("Scene summary", "".join(parts), key="scene")


def stiffness_chain(ctx) -> Section:
    """Each stage's stiffness at the output, compliance shares, seed 001's neglect criterion."""
    ctx.require_drivetrain("the stiffness chain")
    dt = ctx.scene.drivetrain
    lo, hi = np.degrees(dt.stroke)
    angles = [a for a in TABLE_ANGLES_DEG if lo - 1e-9 <= a <= hi + 1e-9] or [math.degrees(dt.mid_stroke)]
    q = np.radians(angles)
    chain = dt.stiffness(q)
    if not chain.names:
        return Section("Stiffness chain", para(
            "No stage of this drivetrain declares a stiffness: the chain is modelled as rigid, so "
            "there is no drivetrain resonance to report."), key="stiffness")
    qs = figures.stroke_grid(dt)
    along = dt.stiffness(qs)
    negligible = along.negligible()
    header = ["stage"] + [f"{a:+.0f} deg: k [N*m/deg]" for a in angles] + [f"{a:+.0f} deg: share" for a in angles] \
        + ["max share over stroke", "may be neglected"]
    body = []
    for i, name in enumerate(chain.names):
        body.append([name] + [fmt(k / DEG, 6) for k in chain.stage_stiffness[i]]
                    + [f"{s:.3%}" for s in chain.shares[i]]
                    + [f"{along.shares[i].max():.3%}", "yes" if negligible[i] else "no"])
    body.append(["series total"] + [fmt(t / DEG, 6) for t in chain.total] + [""] * len(angles) + ["", ""])
    imin = int(np.argmin(along.total))
    imax = int(np.argmax(along.total))
    text = [
        f"Every stage's stiffness is reflected to the {_q_label(dt)} through the square of its ratio to the "
        "output (seed 001, eq 8); compliances in series add.",
        f"Along the stroke the series stiffness runs from {along.total[imin] / DEG:.4g} N*m/deg at "
        f"{math.degrees(qs[imin]):+.1f} deg to {along.total[imax] / DEG:.4g} N*m/deg at "
        f"{math.degrees(qs[imax]):+.1f} deg.",
    ]
    names = [n for n, neg in zip(along.names, negligible) if neg]
    if names:
        text.append("Seed 001's criterion (a stage behind a large ratio whose compliance share stays below "
                    f"0.1 % over the whole stroke may be left out) holds for: {', '.join(names)}.")
    else:
        text.append("No stage meets seed 001's neglect criterion (share below 0.1 % over the whole stroke).")
    fig1, ax1 = figures.new_figure()
    figures.shares_along_stroke(along, qs, ax1)
    ax1.set_xlabel(f"{_q_label(dt)} [deg]")
    fig2, ax2 = figures.new_figure()
    figures.stiffness_along_stroke(along, qs, ax2)
    ax2.set_xlabel(f"{_q_label(dt)} [deg]")
    return Section("Stiffness chain and compliance shares", para(*text) + table(header, body, table_id="stiffness-table"),
                   (FigureSpec(fig1, "Compliance shares along the stroke."),
                    FigureSpec(fig2, "Stage stiffness at the output and the series total.")), key="stiffness")


def ratio_and_inertia(ctx) -> Section:
    """Kinematic ratio and reflected inertia along the stroke."""
    ctx.require_drivetrain("the ratio and inertia analysis")
    dt = ctx.scene.drivetrain
    q = figures.stroke_grid(dt)
    n, _ = dt.ratio(q)
    j, _ = dt.inertia(q)
    jm = j / n**2
    lash = dt.backlash(np.array([dt.mid_stroke]))[0]
    rows = [
        ("ratio N (motor rad per output rad)", fmt(n.min()), fmt(n.max()), fmt(n.max() / n.min()), "-"),
        ("inertia at the output J", fmt(j.min()), fmt(j.max()), fmt(j.max() / j.min()), "kg*m^2"),
        ("inertia at the motor J / N^2", fmt(jm.min()), fmt(jm.max()), fmt(jm.max() / jm.min()), "kg*m^2"),
    ]
    load = dt.load.inertia
    motor_j = dt.motor.rotor_inertia * n**2
    text = [
        f"Over the stroke ({math.degrees(dt.stroke[0]):+.1f} to {math.degrees(dt.stroke[1]):+.1f} deg) the ratio "
        f"varies by a factor {n.max() / n.min():.3g} and the reflected inertia by {j.max() / j.min():.3g}.",
        f"The motor rotor contributes {motor_j.min() / j.max():.1%} to {motor_j.max() / j.min():.1%} of the inertia "
        f"at the output; the load inertia is {load:.4g} kg*m^2.",
        f"Lost motion at mid-stroke, all lashes reflected to the output: {math.degrees(lash) * 60:.3g} arcmin. "
        f"Drivetrain efficiency (product of the stages): {dt.efficiency:.3g}.",
    ]
    fig, axes = figures.new_figure(1, 2, size=(9.0, 3.4))
    figures.ratio_inertia_along_stroke(dt, q, axes)
    for ax in axes:
        ax.set_xlabel(f"{_q_label(dt)} [deg]")
    return Section("Reflected inertia and ratio along the stroke",
                   para(*text) + table(("quantity", "min", "max", "max/min", "unit"), rows),
                   (FigureSpec(fig, "Ratio N(q) with dN/dq, and reflected inertia J(q) at the output and at the motor."),),
                   key="inertia")
