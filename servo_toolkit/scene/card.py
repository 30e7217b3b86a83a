"""The Jupyter display of a scene: one line, and a card with the motor, the drivetrain
reflected at the operating point, the requirements and the studies."""

from __future__ import annotations

import math

from ..display.cards import card, facts, num, table
from ..errors import SceneError


def scene_line(scene) -> str:
    """``name: motor, N stages, output angle/travel, K studies``."""
    kind = "mechanism scene" if scene.motor is None or not scene.stages else (
        f"{len(scene.stages)} stage(s)")
    return f"{scene.name}: {kind}, {len(scene.studies)} studies" + (
        f" ({scene.source})" if scene.source else "")


def _stage_rows(scene):
    rows = []
    for i, s in enumerate(scene.stages):
        fields = {k: v for k, v in vars(s).items() if k != "name" and isinstance(v, (int, float))
                  and not isinstance(v, bool)}
        shown = ", ".join(f"{k} {num(v)}" for k, v in list(fields.items())[:5])
        rows.append((f"drivetrain[{i}]", type(s).__name__, s.name, shown))
    return rows


def scene_card(scene) -> str:
    """The scene's card (HTML)."""
    parts = []
    m = scene.motor
    if m is not None:
        parts.append(facts((("motor", f"R {num(m.resistance)} ohm, L {num(m.inductance * 1e3)} mH, Kt "
                                      f"{num(m.torque_constant)} N*m/A, Ke {num(m.back_emf_constant)} V*s/rad"),
                            ("rotor inertia", f"{num(m.rotor_inertia)} kg*m^2"),
                            ("limits", f"{num(m.voltage_limit)} V, {num(m.current_limit)} A"))))
    if scene.stages:
        parts.append(table(("key", "type", "name", "data (SI)"), _stage_rows(scene)))
        try:
            drive = scene.drivetrain
            from ..drivetrain.operating_point import operating_point, show_q
            q0, _ = operating_point(scene)
            n = float(drive.ratio([q0])[0][0])
            j = float(drive.inertia([q0])[0][0])
            lo, hi = drive.stroke
            u = drive.output_unit
            parts.append(facts((("stroke", f"{show_q(lo, u)} .. {show_q(hi, u)}"),
                                ("operating point q0", show_q(q0, u)),
                                ("ratio N(q0)", f"{num(n)} motor rad per output {u}"),
                                ("reflected inertia J(q0)", f"{num(scene.display.show('inertia', j, u == 'm'))} "
                                                            f"{scene.display.inertia_unit(u == 'm')}"),
                                ("efficiency", f"{num(drive.efficiency, 3)} driving, "
                                               f"{num(drive.backdrive_efficiency, 3)} back-driven"))))
        except SceneError as exc:
            parts.append(f'<p class="st-note">drivetrain: {exc}</p>')
    r = scene.requirements
    reqs = [(name, value) for name, value in (
        ("bandwidth", None if r.bandwidth is None else f">= {num(r.bandwidth)} Hz"),
        ("phase lag at bandwidth", None if r.max_phase_lag_at_bandwidth is None
         else f"<= {num(math.degrees(r.max_phase_lag_at_bandwidth))} deg"),
        ("gain margin", None if r.min_gain_margin is None else f">= {num(r.min_gain_margin)} dB"),
        ("phase margin", None if r.min_phase_margin is None else f">= {num(math.degrees(r.min_phase_margin))} deg"),
        ("sensitivity peak", None if r.max_sensitivity_peak is None else f"<= {num(r.max_sensitivity_peak)} dB"))
        if value is not None]
    if reqs:
        parts.append(facts(reqs))
    if scene.studies:
        parts.append(table(("study", "kind"), [(s.name, s.kind) for s in scene.studies.values()]))
    return card(f"Scene {scene.name}", parts=parts, notes=[scene.description] if scene.description else [])


__all__ = ["scene_card", "scene_line"]
