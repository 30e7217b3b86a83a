"""Sections on the designed loop: requirements, plant, controller, margins, time responses."""

from __future__ import annotations

import math

from .context import api
from .section import NotAvailable, Section, badge, fmt, para, table
from .units_table import UNITS

DEG = 180.0 / math.pi
_REQ_TEXT = {
    "bandwidth": "closed-loop bandwidth (-3 dB) at least",
    "max_phase_lag_at_bandwidth": "phase lag at the bandwidth at most",
    "min_gain_margin": "gain margin at least",
    "min_phase_margin": "phase margin at least",
    "max_sensitivity_peak": "sensitivity peak Ms at most",
}


def _scene_requirements(scene):
    """(name, required value in display units, unit) for each requirement the scene sets."""
    out = []
    for name in _REQ_TEXT:
        value = getattr(scene.requirements, name, None)
        if value is not None:
            unit, factor = UNITS[name]
            out.append((name, value * factor, unit))
    return out


def requirement_rows(ctx):
    """Rows (requirement, required, achieved, status) of the requirements table."""
    return ctx.result("requirement_rows", lambda: _requirement_rows(ctx))


def _requirement_rows(ctx):
    wanted = _scene_requirements(ctx.scene)
    if not wanted:
        return ()
    try:
        design = ctx.design()
    except NotAvailable as exc:
        return tuple((f"{_REQ_TEXT[n]}", f"{fmt(v)} {u}", "not evaluated", "unavailable") for n, v, u in wanted) \
            + (("(loop design)", "", str(exc), "unavailable"),)
    return tuple(_design_rows(design, wanted))


def _design_rows(design, wanted):
    """Rows from a design result's requirement checks (``required``/``achieved``/``passed``)."""
    checks = design.to_dict().get("requirements", [])
    by_name = {}
    if isinstance(checks, dict):
        by_name = checks
    else:
        for c in checks:
            by_name[c.get("name") or c.get("requirement")] = c
    for name, value, unit in wanted:
        c = by_name.get(name)
        if c is None:
            yield (_REQ_TEXT[name], f"{fmt(value)} {unit}", "not reported by the design", "unavailable")
            continue
        achieved = c.get("achieved")
        yield (_REQ_TEXT[name], f"{fmt(value)} {unit}", f"{fmt(achieved)} {unit}",
               "pass" if c.get("passed") else "fail")


def requirements(ctx) -> Section:
    """The pass/fail requirements table (shown at the top of the report)."""
    rows = requirement_rows(ctx)
    if not rows:
        return Section("Requirements", para("The scene sets no [requirements]; nothing to check."),
                       status="n/a", reason="the scene sets no requirements", key="requirements")
    statuses = {r[3] for r in rows}
    status = "fail" if "fail" in statuses else ("unavailable" if "unavailable" in statuses else "pass")
    body = table(("requirement", "required", "achieved", "status"),
                 [(r[0], r[1], r[2], badge(r[3])) for r in rows], table_id="requirements-table")
    verdict = {"pass": "Every requirement is met.", "fail": "Some requirements are not met.",
               "unavailable": "Some requirements could not be evaluated."}[status]
    reason = next((r[2] for r in rows if r[0] == "(loop design)"), "")
    return Section("Requirements", para(verdict) + body, status=status,
                   reason=reason, key="requirements")


def plant_bode(ctx) -> Section:
    """Plant Bode plot with the drivetrain resonance marked."""
    design = ctx.design()
    raise NotAvailable(f"plant plot not wired for {type(design).__name__}")


def controller(ctx) -> Section:
    """The designed controller: structure, gains, filters."""
    design = ctx.design()
    raise NotAvailable(f"controller summary not wired for {type(design).__name__}")


def loop_margins(ctx) -> Section:
    """Open-loop Bode and Nyquist with every margin marked."""
    design = ctx.design()
    raise NotAvailable(f"loop plots not wired for {type(design).__name__}")


def time_responses(ctx) -> Section:
    """Step response and 8 Hz sine tracking of the nonlinear closed loop."""
    ctx.require_drivetrain("time simulation")
    api("servo_toolkit.sim", "simulate")
    raise NotAvailable("time responses not wired yet")
