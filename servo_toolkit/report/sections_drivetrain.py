"""Sections that need only the scene and its drivetrain: summary, stiffness, ratio and inertia."""

from __future__ import annotations

import math

import numpy as np

from . import figures
from .references import NEGLECT_CRITERION, REFERENCES, SERIES_STIFFNESS
from .section import FigureSpec, Section, esc, fmt, para, table
from ..display.html import column
from ..display.units import DIMENSIONLESS, DisplayUnits
from ..core.angles import DEG_PER_RAD
from ..studies.stiffness import stiffness_study
from .units_table import LINEAR_LOAD, rows as unit_rows

TABLE_ANGLES_DEG = (-30.0, 0.0, 10.0, 30.0)


def _q_label(drive) -> str:
    if getattr(drive, "output_is_linear", False):
        return "output travel"
    return "cam angle" if drive.ends_in_cam else "output angle"


def _param_table(obj, units=None) -> str:
    return table(("parameter", "value", "unit"), unit_rows(obj, units), cls="params")


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
        linear = scene.drivetrain.output_is_linear
        parts.append("<h3>Load</h3>" + _param_table(scene.load, LINEAR_LOAD if linear else None))
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


def _output_units(drive, display: DisplayUnits | None = None):
    """(coordinate unit shown, factor SI -> shown, stiffness unit shown, factor) of the
    output; the stiffness in the scene's ``[display]`` unit (SI by default)."""
    display = display or DisplayUnits()
    linear = bool(getattr(drive, "output_is_linear", False))
    qu, qf = ("mm", 1e3) if linear else ("deg", DEG_PER_RAD)
    return qu, qf, display.stiffness_unit(linear), display.factor("stiffness", linear)


def _stiffness_at(scene, values, linear: bool):
    """The stiffness study at output points given in deg, or in mm for a linear output."""
    return stiffness_study(scene, positions_mm=values) if linear else stiffness_study(scene, angles_deg=values)


def two_mass_stiffness(scene, p, linear: bool) -> tuple:
    """(rows, sentence) on the design plant's K beside the chain's series stiffness at its q0:
    the two-mass model keeps the chain's total inertia J, lowest resonance w_r and lowest
    anti-resonance w_a (motor held), J1 = J (w_a / w_r)^2, J2 = J - J1, K = w_a^2 J2; K is the
    springs' series stiffness only when the load side is the inertia beyond one compliance."""
    shown = scene.display
    unit = shown.stiffness_unit(linear)
    series = float(scene.drivetrain.stiffness([p.q0]).total[0])
    rows = [("two-mass model's stiffness K = w_a^2 J2", fmt(shown.show("stiffness", p.K, linear)), unit),
            ("chain's series stiffness (stiffness chain)", fmt(shown.show("stiffness", series, linear)), unit)]
    text = ("The two-mass model keeps the chain's total inertia J, its lowest resonance w_r and its lowest "
            "anti-resonance w_a (motor held): J1 = J (w_a/w_r)^2, J2 = J - J1 and K = w_a^2 J2, the stiffness "
            "that with these inertias puts the model's resonance and anti-resonance where the chain's are. ")
    if not (math.isfinite(p.K) and math.isfinite(series)):
        return rows[:1], ""
    ratio = p.K / series
    if abs(ratio - 1.0) <= 0.01:
        return rows, text + ("Here K is the chain's series stiffness within 1 % (exactly so for a chain with one "
                             "compliance).")
    beyond = float(scene.drivetrain.chain.node_split([p.q0], driving=True).load_side[0])
    j_unit = shown.inertia_unit(linear)
    return rows, text + (
        f"K is the springs' series stiffness only when the inertia beyond one compliance alone swings in the "
        f"lowest modes (a chain with one compliance); here it is {ratio:.3g} times it "
        f"({fmt(shown.show('stiffness', p.K, linear))} against {fmt(shown.show('stiffness', series, linear))} "
        f"{unit}): the members between the compliances take part in the chain's lowest modes and shift w_a "
        f"against w_r, so the model's load side J2 = J (1 - (w_a/w_r)^2) = "
        f"{fmt(shown.show('inertia', p.J2, linear))} {j_unit} is not the inertia beyond the most compliant "
        f"spring ({fmt(shown.show('inertia', beyond, linear))} {j_unit}), and K = w_a^2 J2 follows it. The "
        f"design and the two-mass simulation use K; the series stiffness is the chain's static stiffness at "
        f"the output.")


def _along_stroke(low: str, high: str, unit: str, at_low: str, at_high: str) -> str:
    """The sentence on the series stiffness along the stroke: its range, or its one value
    when the lowest and the highest read the same to the digits shown."""
    if low == high:
        return f"Along the stroke the series stiffness is constant at {low} {unit}."
    return f"Along the stroke the series stiffness runs from {low} {unit} at {at_low} to {high} {unit} at {at_high}."


def ratio_row(linear: bool) -> tuple[str, str]:
    """(quantity, unit) of the ratio N in a table: motor rad per output m (rad/m) for an
    output travel, per output rad (dimensionless: no unit cell) for an output angle."""
    return (f"ratio N (motor rad per output {'m' if linear else 'rad'})", "rad/m" if linear else DIMENSIONLESS)


def stiffness_chain(ctx) -> Section:
    """Each stage's stiffness at the output, compliance shares, the front-stage criterion
    (:data:`~servo_toolkit.report.references.NEGLECT_CRITERION`), all from
    :func:`~servo_toolkit.studies.stiffness.stiffness_study`: at the table's points and,
    for the criterion and the figures, along the stroke."""
    ctx.require_drivetrain("the stiffness chain")
    drive = ctx.scene.drivetrain
    qu, qf, ku, kf = _output_units(drive, ctx.scene.display)
    linear = qu == "mm"
    lo, hi = np.asarray(drive.stroke) * qf
    points = [a for a in TABLE_ANGLES_DEG if qu == "deg" and lo - 1e-9 <= a <= hi + 1e-9] or [drive.mid_stroke * qf]
    chain = _stiffness_at(ctx.scene, points, linear)
    if not chain.names:
        return Section("Stiffness chain", para(
            "No stage of this drivetrain declares a stiffness: the chain is modelled as rigid, so "
            "there is no drivetrain resonance to report."), key="stiffness")
    qs = figures.stroke_grid(drive)
    along = _stiffness_at(ctx.scene, qs * qf, linear)
    crit = along.criterion
    header = ["stage"] + [f"{a:+.4g} {qu}: k [{ku}]" for a in points] + [f"{a:+.4g} {qu}: share" for a in points] \
        + ["max share over stroke", "ratio to later stages (min)", "own stiffness / later (max)",
           f"may be neglected ({REFERENCES[1].cite})"]
    body = []
    # one number format for every stiffness of the table (a column never mixes plain and engineering)
    cells = np.asarray(column(np.vstack([chain.stage_stiffness, chain.total]).ravel() * kf, 6),
                       dtype=object).reshape(len(chain.names) + 1, -1)
    for i, name in enumerate(chain.names):
        later = crit.later_ratio[i]
        body.append([name] + list(cells[i])
                    + [f"{s:.3%}" for s in chain.shares[i]]
                    + [f"{along.shares[i].max():.3%}", fmt(np.nanmin(later), 3) if np.isfinite(later).any() else "-",
                       fmt(crit.stiffness_to_later[i], 3) if np.isfinite(crit.stiffness_to_later[i]) else "-",
                       "yes" if crit.negligible[i] else "no"])
    body.append(["series total"] + list(cells[-1]) + [""] * len(points) + ["", "", "", ""])
    imin = int(np.argmin(along.total))
    imax = int(np.argmax(along.total))
    text = [
        f"Every stage's stiffness is reflected to the {_q_label(drive)} through the square of its ratio to the "
        f"output, by the {SERIES_STIFFNESS}, its eq 8; compliances in series add.",
        _along_stroke(fmt(along.total[imin] * kf), fmt(along.total[imax] * kf), ku,
                      f"{qs[imin] * qf:+.4g} {qu}", f"{qs[imax] * qf:+.4g} {qu}"),
        f"The {NEGLECT_CRITERION}: a front stage may be left out when the ratio between it and every later stage "
        f"is large (at least {crit.min_ratio:g} over the whole stroke) and its own stiffness is within an order of "
        f"magnitude of some later stage's (at least 1/{crit.within:g} of it); its compliance is then at most "
        f"{crit.within / crit.min_ratio ** 2:g} times that of the comparable later stage.",
    ]
    names = [n for n, neg in zip(along.names, crit.negligible) if neg]
    text.append(f"It holds for: {', '.join(names)}." if names else "It holds for no stage of this chain.")
    fig1, ax1 = figures.new_figure()
    figures.shares_along_stroke(along, qs, ax1, linear)
    ax1.set_xlabel(f"{_q_label(drive)} [{qu}]")
    fig2, ax2 = figures.new_figure()
    figures.stiffness_along_stroke(along, qs, ax2, linear, ctx.scene.display)
    ax2.set_xlabel(f"{_q_label(drive)} [{qu}]")
    return Section("Stiffness chain and compliance shares", para(*text) + table(header, body, table_id="stiffness-table"),
                   (FigureSpec(fig1, "Compliance shares along the stroke."),
                    FigureSpec(fig2, "Stage stiffness at the output and the series total.")), key="stiffness")


def rotor_share(drive, q) -> np.ndarray:
    """The motor rotor's share of the inertia at the output at each ``q``: its inertia
    reflected through the ratio, J_rotor N(q)^2, over the total J(q) at the same point."""
    n, _ = drive.ratio(q)
    j, _ = drive.inertia(q)
    return drive.motor.rotor_inertia * n**2 / j


def ratio_and_inertia(ctx) -> Section:
    """Kinematic ratio and reflected inertia along the stroke."""
    ctx.require_drivetrain("the ratio and inertia analysis")
    drive = ctx.scene.drivetrain
    q = figures.stroke_grid(drive)
    n, _ = drive.ratio(q)
    j, _ = drive.inertia(q)
    jm = j / n**2
    lash = drive.backlash(np.array([drive.mid_stroke]))[0]
    qu, qf, _, _ = _output_units(drive)
    linear = qu == "mm"
    display = ctx.scene.display
    j_unit, jf = display.inertia_unit(linear), display.factor("inertia", linear)
    label, n_unit = ratio_row(linear)
    rows = [
        (label, fmt(n.min()), fmt(n.max()), fmt(n.max() / n.min()), n_unit),
        ("mass at the output" if linear else "inertia at the output J", fmt(j.min() * jf), fmt(j.max() * jf),
         fmt(j.max() / j.min()), j_unit),
        ("inertia at the motor J / N^2", fmt(jm.min()), fmt(jm.max()), fmt(jm.max() / jm.min()), "kg*m^2"),
    ]
    load = drive.load.inertia
    share = rotor_share(drive, q)
    text = [
        f"Over the stroke ({drive.stroke[0] * qf:+.4g} to {drive.stroke[1] * qf:+.4g} {qu}) the ratio "
        f"varies by a factor {n.max() / n.min():.3g} and the reflected inertia by {j.max() / j.min():.3g}.",
        f"The motor rotor contributes {share.min():.1%} to {share.max():.1%} of the inertia at the output along "
        f"the stroke (rotor inertia times N(q)^2 over J(q) at each point); the load "
        f"{'mass' if linear else 'inertia'} is {fmt(load * jf)} {j_unit}.",
        (f"Lost motion at mid-stroke, all lashes reflected to the output: {lash * 1e6:.3g} um. " if linear else
         f"Lost motion at mid-stroke, all lashes reflected to the output: {math.degrees(lash) * 60:.3g} arcmin. ")
        + f"Drivetrain efficiency (product of the stages): {drive.efficiency:.3g}.",
    ]
    fig, axes = figures.new_figure(1, 2, size=(9.0, 3.4))
    figures.ratio_inertia_along_stroke(drive, q, axes, display)
    for ax in axes:
        ax.set_xlabel(f"{_q_label(drive)} [{qu}]")
    return Section("Reflected inertia and ratio along the stroke",
                   para(*text) + table(("quantity", "min", "max", "max/min", "unit"), rows),
                   (FigureSpec(fig, "Ratio N(q) with dN/dq, and reflected inertia J(q) at the output and at the motor."),),
                   key="inertia")
