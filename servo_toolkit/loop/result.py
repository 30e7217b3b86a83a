"""The result of a loop design: plant, controller, loop, margins and requirement checks."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from .margins import Margins
from ..lti.lazy import ControlSystem, block_of
from .requirements import telling_digits
from ..display.cards import RichDisplay
from ..core.output_units import OutputUnit
from ..display.cards import card, esc_lines, facts, num, svg
from ..display.cards import requirements_table as requirements_html
from ..display.units import DisplayUnits
from ..errors import SceneError


@dataclass(frozen=True, repr=False)
class DesignResult(RichDisplay):
    """A designed (or evaluated) loop.

    Attributes
    ----------
    scene_name : str
    q0 : float
        Operating point (rad).
    parameters : PlantParameters
        Lumped plant parameters at q0.
    plant : control.StateSpace
        Voltage-driven plant (inputs ``u``, ``tau_ext``; outputs ``theta``, ``omega_m``,
        ``i``, ``omega``), see :mod:`servo_toolkit.plant.linear`.
    controller : CascadeController
        What the simulation engine runs.
    loop : control.StateSpace
        Open loop broken at the position error (``theta_error`` -> ``theta``).
    closed_loop : control.StateSpace
        ``theta_ref`` -> ``theta``.

        ``plant``, ``loop``, ``closed_loop`` and ``closed_loop_full`` read as python-control
        systems, made on first read; :meth:`block` gives the toolkit's own state-space form of
        each, which needs no python-control.
    margins : Margins
    requirements : list of Check
        One per requirement, and, when the loop was checked along the stroke,
        ``stable_over_stroke`` and the worst-case margins over the stroke
        (``gain_margin_over_stroke``, ``phase_margin_over_stroke``,
        ``sensitivity_peak_over_stroke``, with the point requirements' values); the stability
        flag at q0 is ``margins.closed_loop_stable``.
    motion : Motion or None
        Structure and gains of the motion controller, when designed here.
    notes : tuple of str
        Defaults and assumptions used (e.g. requirements the scene does not set).
    closed_loop_full : control.StateSpace
        ``theta_ref``, ``tau_ext`` -> ``theta``, ``i``, ``omega_m``, ``u``, ``omega``.
    robustness : RobustnessResult or None
        Worst cases over the parameter variants, for a robust design
        (``design(scene, robust=...)``, or a scene with ``[robustness]``).
    stroke : StrokeCheck or None
        The same controller on the plant linearized along the stroke
        (:mod:`servo_toolkit.loop.stroke`).
    output_unit : {"rad", "m"}
        The output coordinate's SI unit: q0, the plant's inertias and stiffness are per rad
        of an output angle or per m of an output travel (shown in deg or mm).
    display : DisplayUnits
        Units :meth:`table` shows the plant's inertias and stiffness in (the scene's
        ``[display]``; default SI); :meth:`to_dict` stays SI.
    chain_margins : ChainMargins or None
        The same controller on the n-mass plant of the drivetrain chain (every mode,
        :mod:`servo_toolkit.loop.chain_margins`); None for a chain with one mode.
    actuator : ActuatorBounds or None
        What the play and the motor encoder allow the speed loop
        (:mod:`servo_toolkit.loop.actuator_bounds`); None for a structure without a speed
        loop or a controller evaluated, not designed.
    """

    scene_name: str
    q0: float
    parameters: object
    plant: object = ControlSystem()
    controller: object
    loop: object = ControlSystem()
    closed_loop: object = ControlSystem()
    margins: Margins
    requirements: list
    motion: object = None
    notes: tuple = ()
    closed_loop_full: object = ControlSystem(None)
    robustness: object = None
    stroke: object = None
    output_unit: str = "rad"
    display: DisplayUnits = DisplayUnits()
    chain_margins: object = None
    actuator: object = None

    def require_scene(self, scene, key: str = "design") -> None:
        """One SceneError naming ``key`` unless ``scene`` is the one this design was made for
        (its name and its output's unit; a variant made with ``dataclasses.replace`` keeps
        both): a controller of one actuator exported or judged with another's limits,
        sensors and stroke would mix the two."""
        if scene.name == self.scene_name and scene.drivetrain.output_unit == self.output_unit:
            return
        raise SceneError(key, f"was designed for the scene {self.scene_name!r} (output in {self.output_unit}), not "
                              f"{scene.name!r} (output in {scene.drivetrain.output_unit}): pass the scene it was "
                              "designed for, or design this one")

    def block(self, name: str):
        """The linear block in field ``name`` (``"plant"``, ``"loop"``, ``"closed_loop"``,
        ``"closed_loop_full"``) as a :class:`servo_toolkit.lti.system.StateSpace`: the
        toolkit's own form, read without python-control."""
        return block_of(self, name)

    @property
    def unit(self) -> OutputUnit:
        """The output's units (:class:`~servo_toolkit.core.output_units.OutputUnit`)."""
        return OutputUnit(self.output_unit)

    @property
    def passed(self) -> bool:
        """Every requirement met and the closed loop stable (and, for a robust design, every
        robustness requirement met)."""
        return (self.margins.closed_loop_stable and all(c.passed for c in self.requirements)
                and (self.robustness is None or self.robustness.passed))

    @property
    def failures(self) -> list:
        """Checks that are not met (robustness checks named ``robust_<name>``)."""
        robust = [] if self.robustness is None else [replace(c, name=f"robust_{c.name}")
                                                      for c in self.robustness.failures]
        return [c for c in self.requirements if not c.passed] + robust

    def to_dict(self) -> dict:
        """JSON-ready summary (strict JSON); the margin figures are at the top level. A figure
        that is not finite is None (JSON null), as in :meth:`Margins.to_dict`: an unbounded
        margin, a rigid plant's stiffness and resonances, a requirement's figure on an
        unstable loop."""
        from ..core.json_text import nulls
        return nulls(self._dict())

    def _dict(self) -> dict:
        p = self.parameters
        m = self.margins.to_dict()
        top = {k: m[k] for k in ("gain_margin_db", "phase_margin_deg", "delay_margin_s", "disk_margin",
                                 "sensitivity_peak_db", "bandwidth_hz", "phase_at_8hz_deg",
                                 "closed_loop_stable", "unstable_reason") if k in m}
        reqs = {c.name: c.to_dict() for c in self.requirements}
        reqs["closed_loop_stable"] = {"required": True, "achieved": self.margins.closed_loop_stable,
                                      "passed": self.margins.closed_loop_stable, "unit": "",
                                      "sense": "==", "source": "always", "shortfall": 0.0,
                                      "reason": self.margins.unstable_reason or None}
        u = self.unit
        inertia, stiffness = ("kg", "n_per_m") if u.linear else ("kg_m2", "n_m_per_rad")
        return {"scene": self.scene_name, u.key("q0"): float(u.show(self.q0)), **top,
                "requirements_met": self.passed, "requirements": reqs, "margins": m,
                "plant": {"model": "rigid" if p.rigid else "two_mass",
                          f"motor_side_inertia_{inertia}": p.J1, f"load_side_inertia_{inertia}": p.J2,
                          f"stiffness_{stiffness}": p.K, "ratio": p.N, "efficiency": p.eta,
                          "resonance_hz": p.resonance_hz, "antiresonance_hz": p.antiresonance_hz},
                "controller": {"description": self.controller.description,
                               "current_kp_v_per_a": self.controller.current_kp,
                               "current_ki_v_per_a_s": self.controller.current_ki,
                               "sample_time_s": self.controller.sample_time,
                               "structure": getattr(self.motion, "structure", None),
                               "gains": dict(getattr(self.motion, "gains", {}) or {}),
                               "filter": getattr(self.motion, "filter", None),
                               "filter_params": dict(getattr(self.motion, "filter_params", {}) or {}),
                               **command_fields(self.controller)},
                "notes": list(self.notes), "display_units": self.display.to_dict(u.linear),
                **({"robustness": self.robustness.to_dict()} if self.robustness is not None else {}),
                **({"stroke": self.stroke.to_dict()} if self.stroke is not None else {}),
                **({"n_mass_plant": self.chain_margins.to_dict()} if self.chain_margins is not None else {}),
                **({"actuator_bounds": self.actuator.to_dict()} if self.actuator is not None else {})}

    def _lag_at_required(self) -> str:
        """``"; phase lag at the required bandwidth F Hz L deg"`` where the rows judge the lag at a
        required bandwidth other than the frequency of the headline's phase, else ``""``."""
        rows = {c.name: c for c in self.requirements}
        f_req, lag = rows.get("bandwidth"), rows.get("phase_lag_at_bandwidth")
        if f_req is None or lag is None or f_req.required == self.margins.phase_at_hz or not math.isfinite(lag.achieved):
            return ""
        return f"; phase lag at the required bandwidth {f_req.required:g} Hz {lag.achieved:.1f} deg"

    def table(self) -> str:
        """Requirements and margins as text."""
        m = self.margins
        p = self.parameters
        u = self.unit

        def show(quantity, value):
            return self.display.show(quantity, value, u.linear)
        lines = [f"Loop design of {self.scene_name} at q0 = {u.text(self.q0)}",
                 f"  plant: {'rigid' if p.rigid else 'two-mass'}, J1 = {num(show('inertia', p.J1))}, "
                 f"J2 = {num(show('inertia', p.J2))} {self.display.inertia_unit(u.linear)}, "
                 f"K = {num(show('stiffness', p.K))} {self.display.stiffness_unit(u.linear)}, resonance {p.resonance_hz:.3g} Hz, anti-resonance "
                 f"{p.antiresonance_hz:.3g} Hz",
                 f"  controller: {self.controller.description}",
                 (f"  closed loop stable: yes; bandwidth {m.bandwidth_hz:.3g} Hz; phase at {m.phase_at_hz:g} Hz "
                  f"{m.phase_at_freq_deg:.1f} deg{self._lag_at_required()}" if m.closed_loop_stable else
                  f"  closed loop stable: NO, {m.instability}"),
                 f"  {m.headline()}",
                 m.table(), "", requirements_table(self.requirements)]
        if self.robustness is not None:
            lines.append(self.robustness.table())
        if self.stroke is not None:
            lines.append(self.stroke.summary())
        if self.actuator is not None:
            lines.append(self.actuator.table())
        lines += [f"  note: {n}" for n in self.notes]
        return "\n".join(lines)

    def plot(self, axes=None):
        """Bode of the open loop and the closed loop, and |S|; returns the axes."""
        import matplotlib.pyplot as plt
        if axes is None:
            _, axes = plt.subplots(2, 1, sharex=True, figsize=(7, 6))
        w = 2 * np.pi * np.logspace(-1, 3, 800)
        for sys, label in ((self.block("loop"), "open loop L"), (self.block("closed_loop"), "closed loop T")):
            r = sys(1j * w)
            axes[0].semilogx(w / (2 * np.pi), 20 * np.log10(np.abs(r)), label=label)
            axes[1].semilogx(w / (2 * np.pi), np.degrees(np.unwrap(np.angle(r))), label=label)
        lw = self.block("loop")(1j * w)
        axes[0].semilogx(w / (2 * np.pi), 20 * np.log10(np.abs(1 / (1 + lw))), "--", label="sensitivity S")
        axes[0].axhline(-3, color="0.6", lw=0.8)
        axes[1].axhline(-180, color="0.6", lw=0.8)
        axes[0].set_ylabel("magnitude [dB]")
        axes[1].set_ylabel("phase [deg]")
        axes[1].set_xlabel("frequency [Hz]")
        axes[0].legend()
        axes[0].set_title(f"{self.scene_name}: {'requirements met' if self.passed else 'requirements NOT met'}")
        return axes

    def _repr_line(self) -> str:
        return _card_line(self)

    def _repr_card(self) -> str:
        return _card_html(self)


def command_fields(controller) -> dict:
    """The controller's feedforward, gain schedule and command shaper as JSON fields (None
    where it has none)."""
    return {name: (None if getattr(controller, name, None) is None else getattr(controller, name).to_dict())
            for name in ("feedforward", "schedule", "shaper")}


def requirements_table(checks, stable=None) -> str:
    """Text table: requirement, required, achieved, pass/fail and shortfall; ``stable`` (a
    bool) adds the closed loop's stability as a row of the same columns."""
    width = max([24] + [len(c.name) + 2 for c in checks])
    rows = [f"  {'requirement':<{width}}{'required':>14}{'achieved':>12}  {'':6}{'short by':>10}"]
    reasons = {}
    for c in checks:
        reason = getattr(c, "reason", "")
        short = "" if c.passed or reason else f"{c.shortfall:.3g} {c.unit}"
        d = telling_digits(c.achieved, c.required, 3)
        achieved = f"{'unstable':>13}" if reason else f"{c.achieved:>9.{d}g} {c.unit:<3}"
        rows.append(f"  {c.name:<{width}}{c.sense + ' ' + f'{c.required:g} {c.unit}':>14}"
                    f"{achieved}  {'ok' if c.passed else 'FAIL':6}{short:>10}"
                    + ("  (default)" if c.source == "default" else "  (override)" if c.source == "override" else ""))
        if reason:
            reasons.setdefault(reason, []).append(c.name)
    if stable is not None:
        rows.append(f"  {'closed_loop_stable':<{width}}{'yes':>14}{'yes' if stable else 'no':>9}{'':4}  "
                    f"{'ok' if stable else 'FAIL'}")
    rows += [f"  FAIL {', '.join(names)}: {reason}" for reason, names in reasons.items()]
    return "\n".join(rows)


def _card_line(d) -> str:
    """The one-line repr of a result of this module."""
    m = d.margins
    return (f"{d.scene_name} at q0 = {d.unit.text(d.q0)}: "
            f"{'requirements met' if d.passed else f'{len(d.failures)} requirement(s) NOT met'}, "
            + (f"GM {num(m.gain_margin_db, 3)} dB, PM {num(m.phase_margin_deg, 3)} deg, "
               f"bandwidth {num(m.bandwidth_hz, 3)} Hz" if m.closed_loop_stable else m.unstable_reason))


def _card_html(d) -> str:
    """The Jupyter card (HTML) of a result of this module."""
    m = d.margins
    margins = facts((("closed loop stable", "yes" if m.closed_loop_stable else f"NO, {m.instability}"),
                     ("gain margin", f"{num(m.gain_margin_db)} dB"),
                     ("phase margin", f"{num(m.phase_margin_deg)} deg"),
                     ("delay margin", f"{num(m.delay_margin_s * 1e3)} ms"),
                     ("disk margin", num(m.disk_margin)),
                     ("sensitivity peak Ms", f"{num(m.sensitivity_peak_db)} dB"),
                     ("bandwidth (-3 dB)", f"{num(m.bandwidth_hz)} Hz"),
                     (f"phase at {m.phase_at_hz:g} Hz", f"{num(m.phase_at_freq_deg)} deg"),
                     ("controller", d.controller.description)))
    parts = [requirements_html(d.requirements), margins]
    if d.stroke is not None:
        parts.append(f'<p class="st-note">{"<br>".join(esc_lines(d.stroke.summary()))}</p>')
    if d.robustness is not None:
        parts.append(requirements_html(d.robustness.requirements))
    parts.append(svg(d.plot, size=(7.0, 4.6), rows=2, sharex=True))
    return card(f"Loop design of {d.scene_name} at q0 = {d.unit.text(d.q0)}", status=d.passed,
                parts=parts, notes=d.notes)
