"""Sections on the studies: nonlinear sweep, Kv, reduction, solver accuracy."""

from __future__ import annotations

from .context import api
from .section import NotAvailable, Section


def sweep(ctx) -> Section:
    """Nonlinear sine-dwell sweep against the linear closed loop."""
    ctx.require_drivetrain("the frequency sweep")
    api("servo_toolkit.studies.sweep", "sweep")
    raise NotAvailable("sweep not wired yet")


def kv_tables(ctx) -> Section:
    """Kv tables of the scene's kv studies (seed 000)."""
    ctx.require_drivetrain("the Kv study")
    api("servo_toolkit.studies.kv", "kv_study")
    raise NotAvailable("Kv not wired yet")


def leaves_out(ctx) -> Section:
    """What the model leaves out, and why."""
    api("servo_toolkit.studies.reduce", "reduce")
    raise NotAvailable("reduction not wired yet")


def accuracy(ctx) -> Section:
    """Solver error against run time."""
    ctx.require_drivetrain("the solver accuracy study")
    api("servo_toolkit.sim", "accuracy")
    raise NotAvailable("accuracy not wired yet")
