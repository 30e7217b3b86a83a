"""Sections on the studies: nonlinear sweep, Kv, reduction, solver accuracy."""

from __future__ import annotations

import math

from . import figures
from .context import api
from .section import FigureSpec, NotApplicable, NotAvailable, Section, esc, fmt, para, table


def sweep(ctx) -> Section:
    """Nonlinear sine-dwell sweep against the linear closed loop."""
    ctx.require_drivetrain("the frequency sweep")
    api("servo_toolkit.studies.sweep", "sweep")
    raise NotAvailable("sweep not wired yet")


def kv_tables(ctx) -> Section:
    """Kv tables of the scene's kv studies (seed 000): inverse dynamics along the motion."""
    ctx.require_drivetrain("the Kv study")
    kv_studies = api("servo_toolkit.studies.kv", "kv_studies")
    if not ctx.scene.studies_of_kind("kv"):
        raise NotApplicable("the scene defines no [studies.NAME] of kind \"kv\"")
    results = kv_studies(ctx.scene, samples_per_period=400 if ctx.light else 2000,
                         executor=ctx.executor, progress=False)
    parts = [para("Kv, the dynamic-load factor: the peak load of a motion with the external inertia over the "
                  "peak of the same motion at zero external inertia (seed 000), from inverse dynamics with "
                  "the reflected mass matrix and Jacobians (equivalent-element method).")]
    figs = []
    head = ("amplitude [deg]", "frequency [Hz]", "load inertia [kg*m^2]", "peak motor torque [N*m]", "Kv motor",
            "peak screw thrust [N]", "Kv screw", "peak rod force [N]", "Kv rod")
    for res in results:
        rows = [(fmt(math.degrees(c.amplitude)), fmt(c.frequency), fmt(c.load_inertia), fmt(c.peak_motor_torque),
                 fmt(c.kv_motor, 3), fmt(c.peak_screw_thrust), fmt(c.kv_screw, 3), fmt(c.peak_rod_force),
                 fmt(c.kv_rod, 3)) for c in res.cases]
        parts.append(f"<h3>{esc(res.study)}: {esc(res.motion)}</h3>")
        parts.append(para(f"Amplitudes at the {res.amplitude_at}; stage losses: {res.losses}.", *res.notes))
        parts.append(table(head, rows, cls="kv"))
        fig, ax = figures.new_figure(size=(6.5, 3.4))
        res.plot(ax=ax)
        figs.append(FigureSpec(fig, f"Kv against the external inertia, study {res.study}."))
    return Section("Dynamic-load factor Kv", "".join(parts), tuple(figs), key="kv")


def leaves_out(ctx) -> Section:
    """What the model leaves out, and why."""
    api("servo_toolkit.studies.reduce", "reduce")
    raise NotAvailable("reduction not wired yet")


def accuracy(ctx) -> Section:
    """Solver error against run time."""
    ctx.require_drivetrain("the solver accuracy study")
    api("servo_toolkit.sim", "accuracy")
    raise NotAvailable("accuracy not wired yet")
