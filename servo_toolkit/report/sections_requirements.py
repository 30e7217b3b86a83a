"""The requirements section: the pass/fail table shown at the top of the report, with the
same rows, IDs and verdicts as ``servo-toolkit check`` (the linear loop's, the large-signal
run's, the actuator's time runs', the Monte Carlo's, the sizing's, the tolerance study's and
the measured plant's), and rows without a verdict, saying why, where a run could not be made.
"""

from __future__ import annotations

from .section import NotAvailable, Section, badge, esc, para, table
from .plain_text import plain

_REQ_TEXT = {
    "bandwidth": ("bandwidth", "closed-loop bandwidth (-3 dB)"),
    "max_phase_lag_at_bandwidth": ("phase_lag_at_bandwidth", "closed-loop phase lag at the required bandwidth"),
    "min_gain_margin": ("gain_margin", "gain margin"),
    "min_phase_margin": ("phase_margin", "phase margin"),
    "max_sensitivity_peak": ("sensitivity_peak", "sensitivity peak Ms"),
}


def requirement_rows(ctx):
    """The rows (:class:`servo_toolkit.studies.gate.RequirementRow`) of the requirements
    table: the same rows, IDs and verdicts as ``servo-toolkit check`` (its large-signal,
    robustness and Monte Carlo rows included)."""
    return ctx.result("requirement_rows", lambda: _requirement_rows(ctx))[0]


def _notes(ctx):
    """The design's notes (the large-signal one included) behind the requirement rows."""
    return ctx.result("requirement_rows", lambda: _requirement_rows(ctx))[1]


def _montecarlo(ctx):
    """(checks, MonteCarloResult) of the scene's Monte Carlo requirements, ((), None) when
    it sets none; the error when its runs failed."""
    spec = ctx.scene.robustness
    if spec is None or (spec.max_tracking_error is None and spec.max_peak_current is None):
        return ((), None), None
    from .sections_montecarlo import montecarlo_results
    try:
        result, checks = montecarlo_results(ctx)
    except Exception as exc:  # noqa: BLE001 - no verdict: the rows say why
        return ((), None), exc
    return (tuple(checks), result), None


def _tolerances(ctx):
    """(ToleranceResult or None, error): the tolerance study when the scene requires a yield."""
    tol = getattr(ctx.scene, "tolerances", None)
    if tol is None or tol.min_yield is None:
        return None, None
    from .sections_tolerances import tolerance_results
    try:
        return tolerance_results(ctx), None
    except Exception as exc:  # noqa: BLE001 - no verdict: the rows say why
        return None, exc


def _requirement_rows(ctx):
    from ..studies.gate import gate, unavailable_rows
    try:
        design = ctx.design()
    except NotAvailable as exc:
        wanted = [(name, words) for attr, (name, words) in _REQ_TEXT.items()
                  if getattr(ctx.scene.requirements, attr, None) is not None]
        if not wanted:
            return (), ()
        return tuple(unavailable_rows(wanted + [("loop_design", "loop design")], str(exc))), ()
    mc, mc_error = _montecarlo(ctx)
    from ..errors import SceneError, SimulationError
    from .sections_sizing import sizing_for_gate
    sized = sizing_for_gate(ctx)   # shared with the sizing section; its error leaves its rows without a verdict
    tolerances, tol_error = _tolerances(ctx)
    if tol_error is not None:  # no tolerance study for the gate to run again
        from dataclasses import replace
        ctx_scene = replace(ctx.scene, tolerances=replace(ctx.scene.tolerances, min_yield=None))
    else:
        ctx_scene = ctx.scene
    try:
        act = ctx.actuator()
    except (SimulationError, SceneError) as exc:  # no verdict on runs that could not be made
        act, act_error = False, exc
    else:
        act_error = None
    try:
        g = gate(ctx_scene, design, montecarlo=mc, sizing=sized, tolerances=tolerances,
                 actuator=False if act is None else act)
        rows = list(g.rows)
    except SimulationError as exc:  # the large-signal run could not run: no verdict on its rows
        g = gate(ctx_scene, design, montecarlo=mc, linear_only=True, sizing=sized, tolerances=tolerances)
        rows = list(g.rows) + unavailable_rows(
            [("large_signal_gain", "large signal: |gain difference| from the linear loop"),
             ("large_signal_phase", "large signal: |phase difference| from the linear loop")], str(exc))
        rows += act.rows() if act else []
    if act_error is not None:
        from ..studies.actuator.result import LABELS as ACT_LABELS
        rows += unavailable_rows([(i, w.format(f="sine")) for i, w in ACT_LABELS.items()], str(act_error))
    if mc_error is not None:
        spec = ctx.scene.robustness
        ids = [(i, f"robust: worst {w}") for i, w, v in (
            ("robust_tracking_error", "tracking error", spec.max_tracking_error),
            ("robust_peak_current", "peak current", spec.max_peak_current)) if v is not None]
        rows += unavailable_rows(ids, f"the nonlinear time runs: {mc_error}")
    if tol_error is not None:
        rows += unavailable_rows([("yield", "yield: built actuators meeting every requirement")],
                                 f"the tolerance study: {tol_error}")
    rows += _measured_rows(ctx, design)
    return tuple(rows), tuple(g.result.notes)


def _measured_rows(ctx, design) -> list:
    """The rows of the loop on the measured plant response (none without one); without a
    verdict, saying why, when it cannot be closed on it."""
    if ctx.plant_frf is None:
        return []
    from ..errors import SceneError
    from ..studies.gate import unavailable_rows
    from ..studies.gate import measured_rows
    from .sections_measured import measured_result
    try:
        return measured_rows(measured_result(ctx), design.requirements)
    except SceneError as exc:
        return unavailable_rows([("measured_closed_loop_stable", "measured plant: closed loop stable")], str(exc))


def requirements(ctx) -> Section:
    """The pass/fail requirements table (shown at the top of the report)."""
    rows = requirement_rows(ctx)
    if not rows:
        return Section("Requirements", para("The scene sets no [requirements] and has no loop to design."),
                       status="n/a", reason="nothing to check for this scene", key="requirements")
    statuses = {r.status for r in rows}
    status = "fail" if "fail" in statuses else ("unavailable" if "unavailable" in statuses else "pass")
    body = table(("ID", "requirement", "required", "achieved", "shortfall", "status"),
                 [(*r.cells()[:5], badge(r.status)) for r in rows], table_id="requirements-table")
    verdict = {"pass": "Every requirement is met by the designed loop.",
               "fail": "Some requirements are not met; the table says which and by how much.",
               "unavailable": "Some requirements could not be evaluated."}[status]
    intro = ("The rows, their IDs and verdicts are those of servo-toolkit check (and its JUnit testcases): the "
             "linear loop at the operating point and along the stroke, the nonlinear closed loop on the "
             "requirement sine (large signal), and, with [robustness], the worst variant.")
    details = [f"{r.id}: {r.detail}" for r in rows if r.detail]
    reason = next((r.detail for r in rows if r.id == "loop_design"), "")
    notes = "".join(f"<p>Note: {esc(plain(n))}</p>" for n in _notes(ctx))
    return Section("Requirements", para(verdict, intro) + body
                   + ("<ul>" + "".join(f"<li>{esc(d)}</li>" for d in details) + "</ul>" if details else "") + notes,
                   status=status, reason=reason, key="requirements")
