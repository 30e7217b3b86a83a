"""Requirement rows of a loop closed on a measured plant response (``check --plant-frf``):
``measured_<requirement>`` for the scene's loop requirements and
``measured_closed_loop_stable``, beside the model's rows.

A row is decided by the points of good coherence only. A figure that rests on a point of
poor coherence (a crossing bracketed by one, the bandwidth or the phase lag read between
two points one of which is poor), or a poor point that alone would miss the requirement,
leaves the row without a verdict (``unavailable``, which ``check`` does not count as met):
poor data neither pass nor fail a requirement.

With the number of spectra averaged known, the gain margin, phase margin and Ms rows give
their 95 % interval (:mod:`servo_toolkit.loop.measured_interval`); a row that is met but whose
interval reaches past the required value keeps its verdict and says so in its detail: the
measurement does not show the margin with 95 % confidence.
"""

from __future__ import annotations

import math

from ...display.html import fmt
from ...loop.measured_interval import reaches
from .table import LABELS, RequirementRow

#: the loop requirements a measured response is judged on
NAMES = ("bandwidth", "phase_lag_at_bandwidth", "gain_margin", "phase_margin", "sensitivity_peak")


def _label(c, f_req=None) -> str:
    return "measured plant: " + LABELS[c.name].format(f=f"{fmt(f_req)} Hz" if f_req else "the required bandwidth")


def _row(c, achieved, detail, status=None, f_req=None, bounds=None) -> RequirementRow:
    """The row of requirement check ``c`` (its required value and sense) at ``achieved``, with
    its 95 % interval ``bounds`` when known."""
    label = _label(c, f_req)
    required = f"{c.sense} {fmt(c.required)} {c.unit}"
    if achieved is None or (isinstance(achieved, float) and math.isnan(achieved)):
        return RequirementRow(f"measured_{c.name}", label, required, "not evaluated", "", "unavailable", detail)
    met = achieved >= c.required if c.sense == ">=" else achieved <= c.required
    shortfall = "" if met else f"{fmt(abs(achieved - c.required), 4)} {c.unit}"
    text = f"{fmt(achieved, 4)} {c.unit}"
    if bounds is not None and math.isfinite(achieved):
        span = f"{fmt(bounds[0], 4)} .. {fmt(bounds[1], 4)} {c.unit}"
        text += f" (95 %: {span})"
        if met and reaches(bounds, c.required, c.sense):
            detail = (f"met, but its 95 % interval {span} reaches past the required {fmt(c.required)} {c.unit}: the "
                      "measurement does not show it with 95 % confidence (more averages or a stronger excitation "
                      f"narrow it); {detail}")
    return RequirementRow(f"measured_{c.name}", label, required, text, shortfall,
                          status or ("pass" if met else "fail"), detail)


def _margin_row(c, crossings, figure, bounds=None):
    """Gain or phase margin: the good crossings decide; a poor one that would miss the
    requirement leaves the row without a verdict."""
    good = [x for x in crossings if not x.poor]
    poor = [x for x in crossings if x.poor]
    value = figure(good)
    where = "; ".join(x.text() for x in crossings) or "no crossing"
    if not good and poor:
        return _row(c, None, f"every crossing has poor coherence: {where}")
    missing = [x for x in poor if not _meets(c, abs(x.margin) if c.name == "gain_margin" else x.margin)]
    if missing and _meets(c, value):
        return _row(c, value, f"a crossing of poor coherence would miss it, so no verdict: {where}", "unavailable",
                    bounds=bounds)
    return _row(c, value, where, bounds=bounds)


def _meets(c, value) -> bool:
    return value >= c.required if c.sense == ">=" else value <= c.required


def measured_rows(measured, checks) -> list[RequirementRow]:
    """Rows of ``measured`` (a :class:`~servo_toolkit.loop.measured_result.MeasuredLoop`)
    against the design's requirement ``checks`` (their required values and senses), and the
    closed loop's stability by the Nyquist count on the data."""
    z = measured.closed_loop_rhp_poles
    spans = measured.intervals()
    rows = [RequirementRow("measured_closed_loop_stable", "measured plant: closed loop stable", "yes",
                           "not evaluated" if z is None else "yes" if z == 0 else "no",
                           "" if not z else f"{z} right-half-plane pole(s)",
                           "unavailable" if z is None else "pass" if z == 0 else "fail", measured.nyquist_note)]
    for c in checks:
        if c.name not in NAMES:
            continue
        if z:
            rows.append(RequirementRow(f"measured_{c.name}", _label(c), f"{c.sense} {fmt(c.required)} {c.unit}",
                                       "unstable", "", "fail", "closed loop unstable on the measured response: no figure"))
            continue
        if c.name == "phase_margin":
            rows.append(_margin_row(c, measured.gain_crossings,
                                    lambda xs: min((x.margin for x in xs), default=math.inf), spans["phase margin"]))
        elif c.name == "gain_margin":
            gm = spans["gain margin"]
            if gm is not None and measured.gain_margin_db < 0:  # the row judges |GM|
                gm = (-gm[1], -gm[0])
            rows.append(_margin_row(c, measured.phase_crossings,
                                    lambda xs: min((abs(x.margin) for x in xs), default=math.inf), gm))
        elif c.name == "sensitivity_peak":
            ms, at = measured.sensitivity_peak
            peak, p_at = measured.poor_sensitivity_peak
            detail = f"at {fmt(at)} Hz, the largest over {int((~measured.poor).sum())} points of good coherence"
            if math.isfinite(peak) and not _meets(c, peak) and _meets(c, ms):
                rows.append(_row(c, ms, f"{detail}; a point of poor coherence shows {fmt(peak, 4)} dB at {fmt(p_at)} Hz, "
                                        "so no verdict", "unavailable", bounds=spans["sensitivity peak Ms"]))
            else:
                rows.append(_row(c, ms, detail, bounds=spans["sensitivity peak Ms"]))
        elif c.name == "bandwidth":
            bw, poor, where = measured.bandwidth
            if bw is not None and poor:
                rows.append(_row(c, None, f"the -3 dB point falls {where}, points of poor coherence"))
            else:
                rows.append(_row(c, bw, where if bw is not None else f"not within the measured band: {where}"))
        else:
            f_req = measured.required_bandwidth_hz if measured.required_bandwidth_hz is not None else c.required
            phase, poor = measured.closed_phase_at(f_req)
            if phase is None:
                rows.append(_row(c, None, f"{fmt(f_req)} Hz lies outside the measured band", f_req=f_req))
            elif poor:
                rows.append(_row(c, None, f"the points about {fmt(f_req)} Hz have poor coherence", f_req=f_req))
            else:
                rows.append(_row(c, -phase, f"closed-loop phase {fmt(phase, 4)} deg", f_req=f_req))
    return rows
