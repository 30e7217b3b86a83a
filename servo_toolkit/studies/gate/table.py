"""The requirement table of a design: one row per requirement, with a stable ID, shared by
``servo-toolkit check`` (its table and JUnit testcases) and the report.

The rows come from the checks the design, its large-signal run, the actuator's nonlinear
step and requirement sine (:mod:`.actuator`: full model, friction that holds), its robustness study and
the Monte Carlo time runs produce (:class:`servo_toolkit.loop.requirements.Check`), and, for
a scene with a ``[duty_cycle]``, from the margins of its sizing
(:func:`servo_toolkit.studies.sizing.size`: the motor's envelope, the winding's thermal
margin and the L10 lives against ``required_life``) and, for a scene that requires a yield
(``min_yield``), from its tolerance study (:mod:`.tolerances`: ``yield`` and
``yield_<requirement>``, judged on the lower end of the yield's interval); the ID
of a row is the name of its JUnit testcase (``bandwidth``, ``large_signal_gain``,
``closed_loop_stable``, ``step_overshoot``, ``current_ripple``, ``robust_gain_margin``,
``robust_tracking_error``, ...), so a row
of the report is found by the same name in a CI log.

Examples
--------
>>> from servo_toolkit import load_scene
>>> from servo_toolkit.loop import design
>>> from servo_toolkit.studies.gate import gate
>>> scene = load_scene()
>>> g = gate(scene, design(scene, progress=False))      # doctest: +SKIP
>>> [(r.id, r.status) for r in g.rows][:2]               # doctest: +SKIP
[('bandwidth', 'pass'), ('phase_lag_at_bandwidth', 'pass')]
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

from ...core.yields import Yield
from ...display.cards import badge, card, table
from ...display.html import fmt
from ...loop.requirements import telling_digits

#: check name -> words of the requirement (``{f}``: the frequency the figure is taken at)
LABELS = {
    "bandwidth": "closed-loop bandwidth (-3 dB)",
    "phase_lag_at_bandwidth": "closed-loop phase lag at the required bandwidth, {f}",
    "gain_margin": "gain margin",
    "phase_margin": "phase margin",
    "sensitivity_peak": "sensitivity peak Ms",
    "stable_over_stroke": "closed loop stable over the stroke (fraction of points)",
    "gain_margin_over_stroke": "gain margin, worst over the stroke",
    "phase_margin_over_stroke": "phase margin, worst over the stroke",
    "sensitivity_peak_over_stroke": "sensitivity peak Ms, worst over the stroke",
    "large_signal_gain": "large signal: |gain difference| from the linear loop, {f} sine",
    "large_signal_phase": "large signal: |phase difference| from the linear loop, {f} sine",
    "large_signal_within_stroke": "large signal: time within the stroke, {f} sine",
    "closed_loop_stable": "closed loop stable",
    "stable_fraction": "stable variants (fraction)",
    "tracking_error": "worst tracking error",
    "peak_current": "worst peak current",
}
#: yield row name -> words (``yield_<name>``: the fraction of the tolerance variants meeting it)
YIELD_LABELS = {"all": "every requirement", "stable": "closed loop stable", "gain_margin": "gain margin",
                "phase_margin": "phase margin", "sensitivity_peak": "sensitivity peak Ms",
                "bandwidth": "closed-loop bandwidth", "phase_lag_at_bandwidth": "phase lag at the bandwidth",
                "tracking_error": "tracking error", "peak_current": "peak current"}
#: sizing margin name -> (row ID, words of the requirement); L10 rows are ``life_<part>``
SIZING_ROWS = {
    "peak torque": ("envelope_peak_torque", "motor envelope: peak torque along the duty cycle"),
    "RMS torque": ("envelope_rms_torque", "motor envelope: RMS torque against the continuous torque"),
    "peak current": ("envelope_peak_current", "motor envelope: peak current along the duty cycle"),
    "peak voltage": ("envelope_peak_voltage", "motor envelope: peak voltage (back-EMF, hot winding)"),
    "winding temperature": ("thermal_margin", "thermal margin: winding temperature, steady periodic peak"),
}
#: the row statuses: met, not met, or no verdict (the figure could not be computed)
STATUSES = ("pass", "fail", "unavailable")


@dataclass(frozen=True)
class RequirementRow:
    """One requirement against what the design achieves.

    Attributes
    ----------
    id : str
        Stable identifier: the JUnit testcase name of ``check``.
    requirement : str
        What is required, in words.
    required, achieved, shortfall : str
        Formatted with their unit (``">= 8 Hz"``, ``"7.9 Hz"``, ``"0.104 Hz"``; shortfall ""
        when met).
    status : str
        One of :data:`STATUSES`.
    detail : str
        Where the figure comes from (the worst variant, the source of a default), or why
        there is no verdict.
    """

    id: str
    requirement: str
    required: str
    achieved: str
    shortfall: str
    status: str
    detail: str = ""

    @property
    def passed(self) -> bool:
        """True when the requirement is met."""
        return self.status == "pass"

    def message(self) -> str:
        """One line for a JUnit testcase: required, achieved, shortfall and detail."""
        if self.status == "unavailable":
            return f"{self.requirement}: not evaluated: {self.detail}"
        text = f"{self.requirement}: required {self.required}, achieved {self.achieved}"
        text += "" if self.passed or not self.shortfall else f", short by {self.shortfall}"
        return text + (f"; {self.detail}" if self.detail else "")

    def to_dict(self) -> dict:
        """JSON-ready."""
        return {"id": self.id, "requirement": self.requirement, "required": self.required,
                "achieved": self.achieved, "shortfall": self.shortfall, "status": self.status,
                "detail": self.detail}

    def cells(self) -> tuple:
        """(id, requirement, required, achieved, shortfall, status) for a table."""
        return (self.id, self.requirement, self.required, self.achieved, self.shortfall, self.status)


def _value(value, unit: str, digits: int = 4) -> str:
    return f"{fmt(value, digits)} {unit}".rstrip()


def check_row(c, prefix: str = "", label_prefix: str = "", detail: str = "", frequency=None) -> RequirementRow:
    """The row of one :class:`~servo_toolkit.loop.requirements.Check` (ID ``prefix + name``)."""
    label = LABELS.get(c.name, c.name.replace("_", " "))
    label = label.format(f=f"{fmt(frequency)} Hz" if frequency is not None else "the required bandwidth")
    reason = getattr(c, "reason", "")
    if c.source in ("default", "override"):
        detail = "; ".join(x for x in (f"{c.source} value", detail) if x)
    if reason:  # no figure: the closed loop is unstable, the row fails with why
        detail = "; ".join(x for x in (reason, detail) if x)
    digits = telling_digits(c.achieved, c.required, 4)  # a figure shown apart from its requirement
    return RequirementRow(prefix + c.name, label_prefix + label, f"{c.sense} {_value(c.required, c.unit)}",
                          "unstable" if reason else _value(c.achieved, c.unit, digits),
                          "" if c.passed or reason else _value(c.shortfall, c.unit),
                          "pass" if c.passed else "fail", detail)


def design_rows(result, large_signal_hz=None) -> list[RequirementRow]:
    """Rows of a DesignResult's checks (the large-signal ones included when present, their
    sine at ``large_signal_hz``) and of the stability of its closed loop."""
    f_req = next((c.required for c in result.requirements if c.name == "bandwidth"), None)
    rows = [check_row(c, frequency=large_signal_hz if c.name.startswith("large_signal") and large_signal_hz
                      else f_req) for c in result.requirements]
    m = result.margins
    stable = bool(m.closed_loop_stable)
    pole = m.max_closed_loop_pole_real
    rows.append(RequirementRow("closed_loop_stable", LABELS["closed_loop_stable"], "yes", "yes" if stable else "no",
                               "" if stable else f"pole at Re = {fmt(pole)} 1/s", "pass" if stable else "fail",
                               getattr(m, "instability", "")))
    return rows


def robust_rows(robust) -> list[RequirementRow]:
    """Rows of a RobustnessResult's checks (ID ``robust_<name>``, the worst variant named)."""
    rows = []
    for c in robust.requirements:
        at = robust.variant_text(robust.worst.get(c.name, {}))
        detail = f"worst case over {robust.count} variants ({robust.unstable_count} unstable)" + (f", at {at}" if at else "")
        rows.append(check_row(c, "robust_", "robust: ", detail))
    return rows


def montecarlo_rows(checks, result) -> list[RequirementRow]:
    """Rows of the Monte Carlo checks (ID ``robust_<name>``) over the nonlinear time runs of
    ``result`` (a MonteCarloResult)."""
    rows = []
    for c in checks:
        i = result.worst_index(c.name)
        at = "" if i is None else ", at " + result.variant_text(i)
        rows.append(check_row(c, "robust_", "robust: ", f"worst case over {result.count} nonlinear time runs{at}"))
    return rows


def yield_rows(tolerances) -> list[RequirementRow]:
    """Rows of a ToleranceResult's yields against the scene's ``min_yield``: ``yield`` (every
    requirement at once) and ``yield_<name>`` per requirement, each met when the lower end
    of its Clopper-Pearson interval reaches ``min_yield`` (none when the scene requires no
    yield)."""
    required = tolerances.tolerances.min_yield
    if required is None:
        return []
    rows = []
    for y in (tolerances.overall, *tolerances.yields[:-1]):
        met = y.low >= required
        why = "" if met else "; " + Yield.of(y.name, y.label, y.passed, y.total, y.confidence, required).shortfall()
        words = YIELD_LABELS.get(y.name, y.name.replace("_", " "))
        detail = (f"{100 * y.confidence:g} % Clopper-Pearson interval {fmt(100 * y.low, 4)}..{fmt(100 * y.high, 4)} %, "
                  f"{y.passed} of {y.total} variants ({tolerances.settings.get('method', '')}) of the [tolerances]"
                  + why)
        rows.append(RequirementRow("yield" if y.name == "all" else f"yield_{y.name}",
                                   f"yield: built actuators meeting {words} (lower end of the interval)",
                                   f">= {fmt(100 * required)} %", f"{fmt(100 * y.low, 4)} %",
                                   "" if met else f"{fmt(100 * (required - y.low), 3)} %", "pass" if met else "fail",
                                   detail))
    return rows


def _sizing_id(name: str) -> tuple:
    """(row ID, words) of a sizing margin's name."""
    if name in SIZING_ROWS:
        return SIZING_ROWS[name]
    for head, rid, words in (("L10 ", "life", "L10 life: {}"),
                             ("static load ", "static_load", "static load rating: peak thrust on {}")):
        if name.startswith(head):
            part = name[len(head):]
            return f"{rid}_{re.sub(r'[^0-9a-z]+', '_', part.lower()).strip('_')}", words.format(part)
    return "sizing_" + re.sub(r"[^0-9a-z]+", "_", name.lower()).strip("_"), name


def sizing_rows(sizing) -> list[RequirementRow]:
    """Rows of a :class:`~servo_toolkit.studies.sizing.SizingResult`'s margins: the motor's
    envelope (``envelope_*``), the winding's thermal margin (``thermal_margin``), a roller
    screw's peak thrust against its static rating (``static_load_<screw>``) and the L10 lives
    (``life_<part>``, only when the duty cycle sets ``required_life``)."""
    rows = []
    how = sizing.method.replace("_", " ")
    for m in sizing.margins:
        rid, label = _sizing_id(m.name)
        sense = ">=" if m.name.startswith("L10 ") else "<="
        short = abs(m.value - m.limit) if math.isfinite(m.value) else math.inf
        of = "the allowed rise over the ambient" if m.name == "winding temperature" else "the limit"
        # the screw's thrust is the inverse dynamics' in both modes
        source = "inverse dynamics" if m.name.startswith(("L10 ", "static load ")) else how
        detail = f"margin {fmt(100 * m.margin, 3)} % of {of}; {source} along the [duty_cycle]"
        if m.name == "winding temperature" and sizing.thermal is not None and sizing.thermal.runaway:
            detail = f"thermal runaway: the winding heats without bound; {how} along the [duty_cycle]"
        rows.append(RequirementRow(rid, label, f"{sense} {_value(m.limit, m.unit)}", _value(m.value, m.unit),
                                   "" if m.passed else _value(short, m.unit), "pass" if m.passed else "fail",
                                   detail))
    return rows


def unavailable_rows(ids_labels, why: str) -> list[RequirementRow]:
    """Rows without a verdict: ``(id, requirement)`` pairs and the reason."""
    return [RequirementRow(i, label, "", "not evaluated", "", "unavailable", why) for i, label in ids_labels]


@dataclass(frozen=True)
class Gate:
    """What ``check`` judges a design on.

    Attributes
    ----------
    result : DesignResult
        The design, its large-signal checks added (unless linear only).
    large_signal : LargeSignal or None
    robustness : RobustnessResult or None
    montecarlo : MonteCarloResult or None
    rows : tuple of RequirementRow
    montecarlo_checks : tuple of Check
        The Monte Carlo requirements' checks (empty when the scene sets none).
    sizing : SizingResult or None
        The sizing along the scene's ``[duty_cycle]`` (None without one).
    tolerances : ToleranceResult or None
        The yield over the scene's ``[tolerances]`` (None when it requires no yield).
    actuator : ActuatorCheck or None
        The nonlinear closed loop's step and requirement sine with the full model and
        friction that holds (:mod:`.actuator`; None when linear only or the linear closed
        loop is unstable).
    """

    result: object
    large_signal: object
    robustness: object
    montecarlo: object
    rows: tuple
    montecarlo_checks: tuple = ()
    sizing: object = None
    tolerances: object = None
    actuator: object = None

    @property
    def passed(self) -> bool:
        """Every row met."""
        return all(r.passed for r in self.rows)

    def to_dict(self) -> dict:
        """JSON-ready rows."""
        return {"passed": self.passed, "rows": [r.to_dict() for r in self.rows]}

    def __repr__(self) -> str:
        failed = sum(not r.passed for r in self.rows)
        return f"<Gate of {self.result.scene_name}: {len(self.rows)} requirements, {failed} not met>"

    def _repr_html_(self) -> str:
        """The requirement table as a card: one row per requirement, its badge (a row without a
        verdict is marked so and not counted as met)."""
        rows = [(r.id, r.requirement, r.required, r.achieved, r.shortfall,
                 badge(r.passed, "n/a" if r.status == "unavailable" else None), r.detail) for r in self.rows]
        failed = sum(not r.passed for r in self.rows)
        return card(f"Requirement table of {self.result.scene_name}: {len(self.rows)} requirements, {failed} not met",
                    status=self.passed, parts=[table(("ID", "requirement", "required", "achieved", "short by", "",
                                                      "detail"), rows, raw_columns=(5,))])


def gate(scene, result, spec=None, *, linear_only: bool = False, montecarlo=None, sizing=None,
         executor=None, tolerances=None, actuator=None) -> Gate:
    """Judge ``result`` (a DesignResult of ``scene``) as ``servo-toolkit check`` does.

    Parameters
    ----------
    scene : Scene
    result : DesignResult
    spec : Robustness, optional
        The variants to check (default: the scene's ``[robustness]``); a robust design
        carries its own robustness result.
    linear_only : bool
        Skip the nonlinear runs: the large-signal sine and the actuator's step and sine
        (``check --linear-only``).
    montecarlo : (checks, MonteCarloResult), optional
        Monte Carlo checks already computed (the report's); else they are run when ``spec``
        sets Monte Carlo requirements.
    sizing : SizingResult or Exception, optional
        The sizing of the scene's ``[duty_cycle]`` already computed (the report's), or the
        error it raised (its rows are then without a verdict); else it is computed (inverse
        dynamics, no ratio sweep) when the scene has a duty cycle.
    executor : concurrent.futures.Executor, optional
        Runs the chunks of the variants (robustness and Monte Carlo), e.g. a dask
        ``Client.get_executor()``; the rows do not depend on it.
    tolerances : ToleranceResult, optional
        The tolerance study already computed (the report's); else it runs when the scene
        requires a yield (``min_yield`` in ``[tolerances]`` or ``[robustness]``).
    actuator : ActuatorCheck, optional
        The nonlinear step and sine already run (the report's); else they run unless
        ``linear_only`` or the linear closed loop is unstable (its rows are then the
        ``closed_loop_stable`` failure's); False when the caller did not make them (no rows).

    Returns
    -------
    Gate

    Raises
    ------
    SimulationError
        A nonlinear run the rows need could not be carried out (no verdict), or the inverse
        dynamics of the duty cycle left its validity domain.
    """
    from .large_signal import with_large_signal
    from ..montecarlo import montecarlo_checks
    spec = scene.robustness if spec is None else spec
    ls = None
    if actuator is None and not linear_only and result.margins.closed_loop_stable:
        from ..actuator import actuator_check
        actuator = actuator_check(scene, result)
    actuator = actuator or None  # False: the caller says the runs were not made
    if not linear_only:
        result, ls = with_large_signal(scene, result, actuator)
    robust = result.robustness
    if robust is None and spec is not None:
        from ...loop.robustness import robustness
        robust = robustness(scene, result, spec=spec, progress=False, executor=executor)
    rows = design_rows(result, None if ls is None else ls.frequency_hz)
    if actuator is not None:
        rows += actuator.rows()
    if robust is not None:
        rows += robust_rows(robust)
    if montecarlo is None:
        montecarlo = montecarlo_checks(scene, spec, result.controller, executor=executor)
    checks, mc = montecarlo
    if mc is not None:
        rows += montecarlo_rows(checks, mc)
    if sizing is None and getattr(scene, "duty_cycle", None) is not None:
        from ..sizing import size
        sizing = size(scene, sweep=False)
    if isinstance(sizing, Exception):
        rows += unavailable_rows([("sizing", "sizing along the duty cycle")], str(sizing))
        sizing = None
    elif sizing is not None:
        rows += sizing_rows(sizing)
    tol = getattr(scene, "tolerances", None)
    if tolerances is None and tol is not None and tol.min_yield is not None:
        from ..tolerances import tolerance_study
        tolerances = tolerance_study(scene, result, executor=executor, progress=False)
    if tolerances is not None:
        rows += yield_rows(tolerances)
    return Gate(result, ls, robust, mc, tuple(rows), tuple(checks), sizing, tolerances, actuator)


def failed_count(rows) -> int:
    """Rows not met (failed or without a verdict)."""
    return sum(not r.passed for r in rows)


__all__ = ["Gate", "LABELS", "RequirementRow", "SIZING_ROWS", "STATUSES", "YIELD_LABELS", "check_row", "design_rows",
           "failed_count", "gate", "montecarlo_rows", "robust_rows", "sizing_rows", "unavailable_rows", "yield_rows"]
