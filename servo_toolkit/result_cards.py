"""The HTML cards and one-line reprs of the toolkit's results (see :mod:`servo_toolkit.display`).

One function per result type; the result classes call them from ``_repr_card`` /
``_repr_line``, so the classes stay small and the cards share one look.
"""

from __future__ import annotations

import math

import numpy as np

from .display import badge, card, facts, num, svg, table


def requirement_rows(checks):
    """Rows (name, required, achieved, badge, shortfall) of requirement checks."""
    return [(c.name, f"{c.sense} {num(c.required)} {c.unit}", f"{num(c.achieved)} {c.unit}",
             badge(c.passed), "" if c.passed else f"{num(c.shortfall, 3)} {c.unit}") for c in checks]


def requirements_table(checks) -> str:
    """HTML requirement table with PASS/FAIL badges."""
    return table(("requirement", "required", "achieved", "", "short by"), requirement_rows(checks),
                 raw_columns=(3,))


# --- loop design ---------------------------------------------------------------------------

def design_line(d) -> str:
    m = d.margins
    return (f"{d.scene_name} at q0 = {d.unit.text(d.q0)}: "
            f"{'requirements met' if d.passed else f'{len(d.failures)} requirement(s) NOT met'}, "
            f"GM {num(m.gain_margin_db, 3)} dB, PM {num(m.phase_margin_deg, 3)} deg, "
            f"bandwidth {num(m.bandwidth_hz, 3)} Hz")


def design_card(d) -> str:
    m = d.margins
    margins = facts((("closed loop stable", "yes" if m.closed_loop_stable else "NO"),
                     ("gain margin", f"{num(m.gain_margin_db)} dB"),
                     ("phase margin", f"{num(m.phase_margin_deg)} deg"),
                     ("delay margin", f"{num(m.delay_margin_s * 1e3)} ms"),
                     ("disk margin", num(m.disk_margin)),
                     ("sensitivity peak Ms", f"{num(m.sensitivity_peak_db)} dB"),
                     ("bandwidth (-3 dB)", f"{num(m.bandwidth_hz)} Hz"),
                     (f"phase at {m.phase_at_hz:g} Hz", f"{num(m.phase_at_freq_deg)} deg"),
                     ("controller", d.controller.description)))
    parts = [requirements_table(d.requirements), margins]
    if d.stroke is not None:
        parts.append(f'<p class="st-note">{"<br>".join(_esc_lines(d.stroke.summary()))}</p>')
    if d.robustness is not None:
        parts.append(robustness_summary(d.robustness))
    parts.append(svg(d.plot, size=(7.0, 4.6), rows=2, sharex=True))
    return card(f"Loop design of {d.scene_name} at q0 = {d.unit.text(d.q0)}", status=d.passed,
                parts=parts, notes=d.notes)


def _esc_lines(text):
    from .display import esc
    return [esc(line.strip()) for line in text.splitlines() if line.strip()]


# --- robustness ----------------------------------------------------------------------------

def robustness_summary(r) -> str:
    return requirements_table(r.requirements)


def robustness_line(r) -> str:
    return (f"{r.scene_name}: {r.count} variants, {r.unstable_count} unstable, "
            f"{'requirements met' if r.passed else 'requirements NOT met'}")


def robustness_card(r) -> str:
    ranges = ", ".join(f"{k} {np.min(v):.3g}..{np.max(v):.3g}" for k, v in r.values.items())
    parts = [facts((("variants", r.count), ("unstable variants", r.unstable_count), ("ranges", ranges))),
             requirements_table(r.requirements)]
    if hasattr(r, "plot"):
        parts.append(svg(lambda ax: r.plot(ax), size=(7.0, 3.6)))
    return card(f"Robustness of {r.scene_name}", status=r.passed, parts=parts)


# --- simulation ----------------------------------------------------------------------------

def simulation_line(s) -> str:
    d = s.to_dict()
    key = s.unit.key("max_abs_tracking_error")
    return (f"{s.method}, {d['t_final_s']:.4g} s, peak current {d['max_abs_current_A']:.4g} A, "
            f"peak |error| {d[key]:.4g} {s.unit.shown}")


def simulation_card(s) -> str:
    d = s.to_dict()
    key = s.unit.key("max_abs_tracking_error")
    rows = (("method", f"{s.method} (asked {s.requested or 'auto'})"),
            ("step", "adaptive" if s.dt_s is None else f"{num(s.dt_s)} s"), ("duration", f"{num(d['t_final_s'])} s"),
            ("peak |tracking error|", f"{num(d[key])} {s.unit.shown}"),
            ("peak current", f"{num(d['max_abs_current_A'])} A"), ("peak voltage", f"{num(d['max_abs_voltage_V'])} V"),
            ("peak motor torque", f"{num(d['max_abs_motor_torque_Nm'])} N*m"),
            ("integration wall time", f"{num(s.wall_s * 1e3)} ms"), ("controller", s.controller))
    return card("Simulation", parts=[facts(rows), svg(s.plot, size=(7.0, 5.2), rows=3, sharex=True)],
                notes=(s.choice, *s.notes))


# --- sweep and reduction -------------------------------------------------------------------

def sweep_line(s) -> str:
    dev = s.deviation()
    amps = ", ".join(s.unit.text(a, 3) for a in s.amplitudes_rad)
    worst = max(dev["max_gain_difference_dB"] or [math.nan])
    return (f"{s.scene}: {s.frequencies_hz.size} frequencies x {s.amplitudes_rad.size} amplitude(s) ({amps}), "
            f"largest |dG| {num(worst, 3)} dB from the linear loop, {int(s.failed.sum())} failed")


def sweep_card(s) -> str:
    dev = s.deviation()
    rows = [(s.unit.text(a, 3), f"{num(g, 3)} dB", f"{num(p, 3)} deg", int(s.saturated[i].sum()), int(s.failed[i].sum()))
            for i, (a, g, p) in enumerate(zip(s.amplitudes_rad, dev["max_gain_difference_dB"],
                                              dev["max_phase_difference_deg"]))]
    model = ("full model" if not s.reduced else "reduced: left out " + ("; ".join(s.left_out) or "nothing"))
    parts = [table(("amplitude", "largest |dG|", "largest |dP|", "saturated", "failed"), rows),
             f'<p class="st-note">{model}</p>', svg(s.plot, size=(7.0, 4.6), rows=2, sharex=True)]
    return card(f"Sine-dwell sweep of {s.scene}" + (f", study {s.study}" if s.study else ""), parts=parts,
                notes=s.notes)


def reduction_line(r) -> str:
    left = ", ".join(e.effect for e in r.plan.omitted) or "nothing"
    return f"{r.scene}: left out {left}; measured {num(r.measured, 3)} vs bound {num(r.bound, 3)} ({r.verdict})"


def reduction_card(r) -> str:
    rows = [(e.effect, num(e.estimate, 3), "left out" if e.omitted else "kept", e.reason) for e in r.plan.effects]
    parts = [table(("effect", "estimate (relative)", "decision", "why"), rows),
             facts((("a-priori bound", num(r.bound, 3)), ("measured difference", num(r.measured, 3)),
                    ("verdict", r.verdict), ("wall time full / reduced",
                                             f"{num(r.full_wall_s, 3)} s / {num(r.reduced_wall_s, 3)} s"))),
             svg(lambda ax: r.plot(ax), size=(7.0, 3.4))]
    return card(f"Reduction of {r.scene}", status=r.within_bound if r.within_bound is not None else None,
                parts=parts, notes=r.notes)


# --- stiffness and Kv ----------------------------------------------------------------------

def stiffness_line(s) -> str:
    return f"{len(s.names)} compliant stage(s) at {len(s.total)} point(s); series total {num(np.min(s.total), 4)} (SI) at its lowest"


def stiffness_card(s) -> str:
    return card("Stiffness chain", parts=[f"<pre>{_pre(s.table())}</pre>"])


def kv_line(k) -> str:
    top = max((c.kv_motor for c in k.cases), default=math.nan)
    return f"{k.scene}, study {k.study}: {len(k.cases)} cases, largest Kv of the motor torque {num(top, 4)}"


def kv_card(k) -> str:
    u = k.unit
    rows = [(u.text(c.amplitude), num(c.load_inertia), num(c.peak_motor_torque), num(c.kv_motor, 4),
             num(c.peak_screw_thrust) if c.peak_screw_thrust is not None else "-",
             num(c.kv_screw, 4) if c.kv_screw is not None else "-") for c in k.cases]
    load = "load mass [kg]" if u.linear else "load inertia [kg*m^2]"
    parts = [f'<p class="st-note">{_pre(k.motion)}</p>',
             table(("amplitude", load, "motor torque [N*m]", "Kv motor", "screw thrust [N]", "Kv screw"), rows),
             svg(lambda ax: k.plot(ax), size=(6.0, 3.4))]
    return card(f"Kv of {k.scene}, study {k.study}", parts=parts, notes=k.notes)


def _pre(text) -> str:
    from .display import esc
    return esc(text)


__all__ = ["design_card", "design_line", "kv_card", "kv_line", "reduction_card", "reduction_line",
           "requirements_table", "robustness_card", "robustness_line", "simulation_card", "simulation_line",
           "stiffness_card", "stiffness_line", "sweep_card", "sweep_line"]
