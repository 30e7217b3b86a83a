"""A run's result from its records: the auxiliary traces at the records, the non-finite
check of the implicit solver's records, the notes of the time at the motor's limits, and the
:class:`~.result.SimulationResult` itself (:func:`~.engine.run`)."""

from __future__ import annotations

import math

import numpy as np

from ..core.output_units import OutputUnit
from ..errors import SimulationError
from . import layout as lo
from .kernel import hermite, reference as ref_at, rhs
from .result import SimulationResult, shown_name


def speed_and_reference(model, P, times, states):
    """Motor speed (rad/s) and the reference at the records."""
    n = len(times)
    speed, refs = np.empty(n), np.empty(n)
    for k in range(n):
        speed[k] = hermite(model.T, lo.T_N, P, states[k, 0])[0] * states[k, 1]
        refs[k] = ref_at(times[k], P) if model.closed_loop else P[lo.REF_OFF]
    return speed, refs


def aux_traces(model, P, times, states, irefs):
    """Current, voltage, i_ref, torque (the right-hand side's auxiliary outputs), motor speed
    and reference at the records (a fixed-step loop records the auxiliary outputs itself:
    :func:`speed_and_reference` serves it)."""
    aux = np.empty((len(times), lo.NAUX))
    dx, a = np.empty(model.nx), np.empty(lo.NAUX)
    for k in range(len(times)):
        rhs(times[k], states[k], P, model.T, irefs[k], dx, a)
        aux[k] = a
    return (aux, *speed_and_reference(model, P, times, states))


def check_finite(model, times, states):
    bad = ~np.all(np.isfinite(states), axis=1)
    if bad.any():
        k = int(np.argmax(bad))
        names = [model.state_names[j] for j in np.flatnonzero(~np.isfinite(states[k]))]
        raise SimulationError(f"non-finite state {', '.join(names)} at t = {times[k]:.6g} s")


def make_result(model, times, states, aux, speed, refs, max_tau, wall, method, dt, steps, requested,
            choice, probe, reference, notes, peaks=None):
    stab = {k: v for k, v in probe.items()}
    if dt is not None:
        stab["abs_lambda_dt"] = probe["max_abs_lambda"] * dt
    notes = [*notes, *limit_notes(model, times, aux), *play_note(model, method, states)]
    return SimulationResult(times=times, states=states, state_names=model.state_names,
                            reference_angle=refs, motor_speed=speed, motor_current=aux[:, lo.AUX_I],
                            motor_voltage=aux[:, lo.AUX_V], current_reference=aux[:, lo.AUX_IREF],
                            motor_torque=aux[:, lo.AUX_TAU], max_abs_motor_torque=float(max_tau),
                            wall_s=wall, method=method, dt_s=dt, steps=steps, requested=requested,
                            choice=choice, stability=stab, reference=reference.to_dict(),
                            controller=model.controller, notes=tuple(notes),
                            output_unit=getattr(model, "output_unit", "rad"), peaks=peaks or {})


def play_note(model, method: str, states) -> list:
    """What the recorded play state is where the run held it: the cam paper's play operator's
    output, an absolute position at the output (the backlash's load side, like the output's
    own coordinate), which only the paper scheme moves; every other method leaves it at its
    start value (the elasto-backlash law needs no state)."""
    if method == "paper" or len(states) == 0:
        return []
    unit = getattr(model, "output_unit", "rad")
    shown = OutputUnit(unit)
    return [f"{shown_name('play_state_rad', unit)} is the paper scheme's play-operator output, a position at the "
            f"output like {shown_name('output_angle_rad', unit)} (not a deflection): method {method!r} holds it "
            f"at its start, {shown.show(states[0, 6]):.4g} {shown.shown}"]


def limit_notes(model, times, aux) -> list:
    """A note of the time the motor spent at its voltage and current limits over the
    recorded samples (within 1e-3 of the limit, as the large-signal check counts it; the
    current or the loop's clamped current command), so a saturated run says so; none for a
    run that never reached a limit."""
    if times.size == 0:
        return []
    dt = np.diff(times, append=times[-1])
    parts = []
    current = np.maximum(np.abs(aux[:, lo.AUX_I]), np.abs(aux[:, lo.AUX_IREF]))  # the command clamped, or the current
    for what, level, lim, unit in (("voltage", np.abs(aux[:, lo.AUX_V]), model.P[lo.VLIM], "V"),
                                   ("current", current, model.P[lo.ILIM], "A")):
        if math.isfinite(lim):
            at = level >= lim * (1.0 - 1e-3)
            if at.any():
                parts.append(f"its {what} limit {lim:.4g} {unit} for {float(np.sum(dt[at])) * 1e3:.4g} ms")
    if not parts:
        return []
    tail = ": the loop was saturated there, not linear" if model.closed_loop else ""
    return [f"the motor was at {' and at '.join(parts)} of the {float(times[-1] - times[0]) * 1e3:.4g} ms run "
            f"(recorded samples){tail}"]


__all__ = ["aux_traces", "check_finite", "limit_notes", "make_result", "play_note", "speed_and_reference"]
