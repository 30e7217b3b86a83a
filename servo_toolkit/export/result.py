"""The result of an export: blocks, discrete motion controller, quantization and its cost."""

from __future__ import annotations

import html
import math
from dataclasses import dataclass, field

import control as ct
import numpy as np

SIGNALS = {"theta_ref": "rad", "theta": "rad", "omega_m": "rad/s (motor)", "motor_angle": "rad (motor encoder)",
           "i_ref": "A", "i": "A", "v": "V"}


def signals(output_unit: str = "rad") -> dict:
    """Each signal's unit (theta_ref and theta in the output's: rad or m)."""
    return {**SIGNALS, "theta_ref": output_unit, "theta": output_unit}


def motion_dict(sys_d, states=()) -> dict:
    """``A``, ``B``, ``C``, ``D``, ``sample_time_s``, ``inputs``, ``outputs`` of a discrete system."""
    return {"A": np.atleast_2d(sys_d.A).tolist(), "B": np.atleast_2d(sys_d.B).tolist(),
            "C": np.atleast_2d(sys_d.C).tolist(), "D": np.atleast_2d(sys_d.D).tolist(),
            "sample_time_s": float(sys_d.dt), "inputs": list(sys_d.input_labels),
            "outputs": list(sys_d.output_labels), "states": list(states)}


@dataclass(frozen=True)
class ExportResult:
    """An exported controller.

    Attributes
    ----------
    scene_name : str
    design : DesignResult
        The design that was exported.
    motion : control.StateSpace
        Tustin sampling of ``design.controller.motion`` (what the simulation runs).
    blocks : Blocks
        The same controller as biquads, speed PI, current PI and speed estimator.
    quantized : Quantized or None
        The fixed-point controller (``fixed_point`` given).
    quantized_design : DesignResult or None
        The quantized controller evaluated like the design (margins, requirements).
    filters : list of dict
        Natural-frequency shift of each quantized filter section.
    sensitivity : list of dict
        Each stored fixed-point coefficient (:func:`.sensitivity.coefficient_sensitivity`):
        its integer, Q format, and how far one LSB of it moves its section's poles or zeros.
    files : dict
        File name -> text (``controller.json``, ``servo_controller.h``, ``servo_controller.c``).
    directory : pathlib.Path or None
        Where the files were written (None: not written).
    failures : tuple of str
        First, in either format, the design's own closed loop when it is unstable; then the
        requirements the quantized controller's loop misses, each named with its figure
        and whether the design without quantization already misses it; and, in either
        format, each requirement the design itself misses (empty: the loop is stable and
        the design, and the quantized loop, meet every requirement of the scene).
    bound_horizon_s : float
        Horizon of the stated fixed-point rounding bound.
    position_count : PositionCount or None
        The fixed-point position count against the error at rest and the limit cycle that
        ``check`` requires (:mod:`.position_count`; None in floating point).
    command : CommandExport or None
        The controller's feedforward gains, gain schedule and command shaper as exported
        (:mod:`.command`; None when it has none).
    """

    scene_name: str
    design: object
    motion: ct.StateSpace
    blocks: object
    quantized: object = None
    quantized_design: object = None
    filters: list = field(default_factory=list)
    sensitivity: list = field(default_factory=list)
    files: dict = field(default_factory=dict)
    directory: object = None
    failures: tuple = ()
    bound_horizon_s: float = 0.1
    command: object = None
    position_count: object = None

    @property
    def passed(self) -> bool:
        """The designed loop is stable and meets the scene's requirements, and (with
        quantization) so does the quantized loop."""
        return not self.failures

    @property
    def error_bound(self) -> float:
        """Fixed-point rounding bound on i_ref (A) over ``bound_horizon_s`` (0 in floating point)."""
        if self.quantized is None:
            return 0.0
        return self.quantized.error_bound(max(1, round(self.bound_horizon_s / self.blocks.sample_time)))

    def controller_json(self) -> dict:
        """The content of ``controller.json``."""
        out = {"scene": self.scene_name, "generator": "servo_toolkit export",
               "format": "float64" if self.quantized is None else self.quantized.fmt,
               "signals": signals(self.blocks.output_unit), "motion": motion_dict(self.motion, self.motion.state_labels),
               "blocks": self.blocks.to_dict(), "design": self._design_dict(),
               "passed": self.passed, "failures": list(self.failures)}
        if self.command is not None:
            out["command"] = self.command.to_dict()
        if self.quantized is not None:
            qd = self.quantized_design
            m = qd.margins
            out["quantized"] = {**self.quantized.to_dict(), "filters": self.filters,
                                "coefficient_sensitivity": self.sensitivity,
                                "gain_margin_db": m.gain_margin_db, "phase_margin_deg": m.phase_margin_deg,
                                "closed_loop_stable": bool(m.closed_loop_stable),
                                "bandwidth_hz": m.bandwidth_hz,
                                "requirements": {c.name: c.to_dict() for c in qd.requirements},
                                "i_ref_error_bound_A": self.error_bound,
                                "position_count": self.position_count.to_dict(),
                                "bound_horizon_s": self.bound_horizon_s,
                                "passed": self.passed, "failures": list(self.failures)}
        return out

    def _design_dict(self) -> dict:
        m = self.design.margins
        return {"gain_margin_db": m.gain_margin_db, "phase_margin_deg": m.phase_margin_deg,
                "closed_loop_stable": bool(m.closed_loop_stable),
                "instability": None if m.closed_loop_stable else m.instability}

    def to_dict(self) -> dict:
        """JSON-ready summary (strict JSON: a figure that is not finite is None):
        ``controller.json`` plus where it was written and the verdict."""
        from ..core.json_text import nulls
        return nulls({**self.controller_json(), "directory": None if self.directory is None else str(self.directory),
                      "files": sorted(self.files)})

    def table(self) -> str:
        """Text summary for the command line."""
        fmt = "floating point" if self.quantized is None else f"fixed point {self.quantized.fmt}"
        lines = [f"Controller export of {self.scene_name} ({fmt}, {self.blocks.structure}, "
                 f"Ts = {self.blocks.sample_time:g} s, current loop {self.blocks.current.sample_time:g} s)"]
        if self.directory is not None:
            lines.append(f"  wrote {', '.join(sorted(self.files))} to {self.directory}")
        for s in self.blocks.sections():
            lines.append(f"  {s.name:<10} b = [{', '.join(f'{v:.8g}' for v in s.b)}]  "
                         f"a = [1, {', '.join(f'{v:.8g}' for v in s.a)}]  ({s.input_unit} -> {s.output_unit})")
        bc = self.blocks.back_calculation()
        lines.append(f"  clamp at {self.blocks.current_limit:g} A, " + ("no integrator: no anti-windup" if bc is None
                     else "anti-windup by " + bc.describe()))
        if self.quantized is not None:
            m, d = self.quantized_design.margins, self.design.margins
            loop = (f"GM {m.gain_margin_db:.2f} dB (design {d.gain_margin_db:.2f}), PM {m.phase_margin_deg:.1f} deg "
                    f"(design {d.phase_margin_deg:.1f}), closed loop stable" if m.closed_loop_stable else
                    f"closed loop UNSTABLE, {m.instability}: no margins")
            lines.append(f"  quantized: {loop}; i_ref rounding bound {self.error_bound:.3g} A over "
                         f"{self.bound_horizon_s:g} s")
            lines.append(f"  {self.position_count.describe()}")
            for f in self.filters:
                if math.isnan(f["quantized_hz"]):
                    lines.append(f"  {f['section']} {f['what']}s: {f['design_hz']:.4g} Hz -> real pair (filter lost)")
                    continue
                lines.append(f"  {f['section']} {f['what']}: {f['design_hz']:.4g} Hz -> {f['quantized_hz']:.4g} Hz "
                             f"({100 * f['shift_relative']:+.3g} %)")
            moving = [r for r in self.sensitivity if r["root_shift_relative_per_lsb"] is not None]
            if moving:
                worst = max(moving, key=lambda r: r["root_shift_relative_per_lsb"])
                lines.append(f"  most sensitive coefficient: {worst['section']} {worst['coefficient']} "
                             f"({worst['format']}), one LSB moves a root by "
                             f"{100 * worst['root_shift_relative_per_lsb']:.2g} %")
            elif self.sensitivity:
                lines.append("  coefficient sensitivity: no section has a pole or zero to move (pure gains)")
            lines += [f"  FAIL: {r}" for r in self.failures] or [
                f"  quantized loop within the requirements: the design's {len(self.quantized_design.requirements)} "
                "linear rows, and half a position count within the error at rest and the limit cycle (check's "
                "time rows run the floating-point controller)"]
        else:
            lines += [f"  FAIL: {r}" for r in self.failures]
        if self.command is not None:
            from .command import describe
            lines += describe(self.command)
        return "\n".join(lines)

    def __repr__(self) -> str:
        fmt = "float64" if self.quantized is None else self.quantized.fmt
        return (f"<ExportResult: {self.scene_name}, {fmt}, {len(self.blocks.sections())} sections, "
                f"{'passed' if self.passed else 'FAILED'}>")

    def _repr_html_(self) -> str:
        """The notebook card: the verdict, the coefficients and checks as the command prints
        them, the step and gain plot."""
        from ..display.cards import card, svg
        fmt = "floating point" if self.quantized is None else f"fixed point {self.quantized.fmt}"
        return card(f"Controller export of {self.scene_name} ({fmt})", status=bool(self.passed),
                    parts=["<pre>" + html.escape(self.table()) + "</pre>", svg(self.plot, size=(10.0, 3.8), cols=2)])

    def plot(self, axes=None, duration: float = 0.5):
        """Closed-loop step response (linear analysis) and the controller's gain from the
        position error to i_ref, design vs quantized; returns the axes."""
        import matplotlib.pyplot as plt
        if axes is None:
            _, axes = plt.subplots(1, 2, figsize=(10, 3.8))
        t = np.linspace(0, duration, 1000)
        cases = [("design", self.design, self.motion)]
        if self.quantized is not None:
            cases.append((f"quantized {self.quantized.fmt}", self.quantized_design,
                          self.quantized.blocks.state_space()))
        w = 2 * math.pi * np.logspace(-1, math.log10(0.5 / self.blocks.sample_time), 600)
        for label, d, sysd in cases:
            y = ct.step_response(d.closed_loop, t).outputs
            axes[0].plot(t, np.ravel(y), label=label)
            h = ct.frequency_response(sysd[0, 0], w).complex.ravel()
            axes[1].semilogx(w / (2 * math.pi), 20 * np.log10(np.abs(h)), label=label)
        axes[0].set_xlabel("time [s]")
        axes[0].set_ylabel("theta / theta_ref")
        axes[1].set_xlabel("frequency [Hz]")
        axes[1].set_ylabel("|i_ref / theta error| [dB A/rad]")
        for ax in axes:
            ax.legend()
            ax.grid(True, alpha=0.3)
        return axes
