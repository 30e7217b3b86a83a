"""What an external load does to the closed loop: the response to a step of disturbance
torque (force, for an output travel) at the output, and the dynamic stiffness along the
stroke, the loop designed at q0 closed on the plant linearized at each point."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..display.units import label
from . import figures
from .section import FigureSpec, NotApplicable, Section, fmt, para, table

F_MIN, F_MAX = 0.1, 1000.0
#: operating points of the dynamic-stiffness curves along the stroke (q0 is added)
STROKE_CURVES = 5


@dataclass(frozen=True)
class DisturbanceStep:
    """The output's response to a step of external load at t = 0.

    Attributes
    ----------
    t : ndarray
        Time (s).
    deflection : ndarray
        Output deflection (rad or m, SI).
    amplitude : float
        The step (N*m or N).
    static : float
        Final deflection from the closed loop's static gain (0 with integral action).
    """

    t: np.ndarray
    deflection: np.ndarray
    amplitude: float
    static: float

    @property
    def peak(self) -> float:
        """The largest |deflection| (SI)."""
        return float(np.max(np.abs(self.deflection)))

    @property
    def peak_time(self) -> float:
        """When the peak deflection occurs (s)."""
        return float(self.t[int(np.argmax(np.abs(self.deflection)))])

    def recovery_time(self, band: float = 0.1) -> float:
        """Time (s) after which the deflection stays within ``band`` of the peak around its
        final value; nan when it has not recovered by the end of the run."""
        err = np.abs(self.deflection - self.static)
        outside = np.nonzero(err > band * self.peak)[0]
        if not outside.size:
            return 0.0
        k = int(outside[-1])
        return math.nan if k >= self.t.size - 1 else float(self.t[k + 1])


def static_gain(sys) -> float:
    """The static gain D - C A^-1 B of a single-input single-output state-space system."""
    import control as ct
    return float(np.real(np.asarray(ct.dcgain(sys))).reshape(-1)[0])


def step_amplitude(scene) -> float:
    """The disturbance step: the load's hinge moment (force) when it sets one, else 1 (SI)."""
    h = float(getattr(scene.load, "hinge_moment", 0.0) or 0.0) if scene.load is not None else 0.0
    return abs(h) if math.isfinite(h) and h != 0 else 1.0


def disturbance_step(design, amplitude: float, t_end: float | None = None) -> DisturbanceStep:
    """Linear response of the output to a step of ``amplitude`` on ``tau_ext``."""
    import control as ct
    sys = design.closed_loop_full["theta", "tau_ext"]
    bw = design.margins.bandwidth_hz
    if t_end is None:
        t_end = min(5.0, max(0.1, 15.0 / bw)) if math.isfinite(bw) and bw > 0 else 1.0
    t = np.linspace(0.0, t_end, 3001)
    _, y = ct.step_response(sys, t)
    return DisturbanceStep(t, amplitude * np.asarray(y, float).reshape(-1), amplitude,
                           amplitude * static_gain(sys))


def stroke_points(design, drivetrain, n: int = STROKE_CURVES) -> np.ndarray:
    """``n`` operating points evenly over the stroke, and q0, sorted."""
    lo, hi = (float(v) for v in drivetrain.stroke)
    return np.unique(np.concatenate([np.linspace(lo, hi, n), [design.q0]]))


def dynamic_stiffness_at(scene, design, q, f) -> np.ndarray:
    """|tau_ext / theta| (SI) at ``f`` (Hz) of the design's controller closed on the plant
    linearized at ``q`` (the model kind of the design)."""
    import control as ct
    from ..loop.closed_loop import linear_closed_loop
    model = "rigid" if design.parameters.rigid else "two_mass"
    sys = linear_closed_loop(scene, design.controller, q, model=model)["theta", "tau_ext"]
    resp = np.asarray(ct.frequency_response(sys, 2 * np.pi * np.asarray(f, float)).complex).reshape(-1)
    with np.errstate(divide="ignore"):
        return 1.0 / np.abs(resp)


def _show(drivetrain, display):
    """(coordinate factor, its unit, load unit, stiffness unit, stiffness factor, inertia
    unit, inertia factor) of the output; stiffness and inertia in ``display``'s units."""
    linear = bool(getattr(drivetrain, "output_is_linear", False))
    shown = (display.stiffness_unit(linear), display.factor("stiffness", linear),
             display.inertia_unit(linear), display.factor("inertia", linear))
    return ((1e3, "mm", "N") if linear else (180 / math.pi, "deg", "N*m")) + shown


def disturbance(ctx) -> Section:
    """Disturbance step at q0 and dynamic stiffness along the stroke."""
    d = ctx.design()
    if d.closed_loop_full is None:
        raise NotApplicable("the design carries no closed loop with the external load input")
    drive = ctx.scene.drivetrain
    af, au, load_unit, k_unit, kf, inertia, jf = _show(drive, ctx.scene.display)
    step = disturbance_step(d, step_amplitude(ctx.scene))
    fig1, ax1 = figures.new_figure(size=(7.5, 3.6))
    ax1.plot(step.t * 1e3, step.deflection * af, "C0", label="output deflection")
    ax1.axhline(step.static * af, color="C1", lw=0.9, ls="--", label="static deflection (static gain)")
    ax1.plot(step.peak_time * 1e3, step.deflection[int(np.argmax(np.abs(step.deflection)))] * af, "C3o",
             label=f"peak {fmt(step.peak * af)} {au}")
    ax1.set(xlabel=label("time", "ms"), ylabel=label("output deflection", au),
            title=f"Step of {fmt(step.amplitude)} {load_unit} of external load at the output")
    ax1.grid(True, alpha=0.3)
    ax1.legend(fontsize="small", loc="upper left", bbox_to_anchor=(1.02, 1.0))
    f = np.logspace(math.log10(F_MIN), math.log10(F_MAX), 600)
    qs = stroke_points(d, drive)
    fig2, ax2 = figures.new_figure(size=(7.5, 4.0))
    rows = []
    for j, q in enumerate(qs):
        k = dynamic_stiffness_at(ctx.scene, d, q, f) * kf
        at_q0 = abs(q - d.q0) < 1e-12
        ax2.loglog(f, k, color="k" if at_q0 else f"C{j % 10}", lw=2.0 if at_q0 else 1.1,
                   label=f"q = {fmt(q * af, 3)} {au}" + (" (q0)" if at_q0 else ""))
        kmin = int(np.argmin(k))
        rows.append((f"{fmt(q * af, 4)}" + (" (q0)" if at_q0 else ""), fmt(k[0]), fmt(k[kmin]), fmt(f[kmin]),
                     fmt(k[-1] / kf / (2 * math.pi * f[-1]) ** 2 * jf)))
    ax2.set(xlabel=label("frequency", "Hz"), ylabel=label("dynamic stiffness", k_unit),
            title="Dynamic stiffness along the stroke (controller designed at q0)")
    ax2.grid(True, which="both", alpha=0.3)
    ax2.legend(fontsize="small", loc="upper left", bbox_to_anchor=(1.02, 1.0))
    rec = step.recovery_time()
    held = abs(step.static) <= 1e-9 * max(step.peak, 1e-300)
    static_shown = 0.0 if held else step.static * af
    recovery = (f"it is back within 10 % of the peak after {fmt(rec * 1e3)} ms" if math.isfinite(rec) else
                f"it has not recovered to within 10 % of the peak after {fmt(step.t[-1] * 1e3)} ms")
    text = [f"A step of {fmt(step.amplitude)} {load_unit} of external load "
            f"({'the load hinge moment' if step.amplitude != 1.0 else 'a unit load'}) at q0 deflects the output "
            f"by at most {fmt(step.peak * af)} {au} after {fmt(step.peak_time * 1e3)} ms; {recovery}. The final "
            f"deflection, from the closed loop's static gain, is {fmt(static_shown)} {au}"
            + (" (integral action holds the output)." if held else "."),
            "The dynamic stiffness is the external load per unit of output motion it causes, at each frequency, "
            "with the controller designed at q0 closed on the plant linearized along the stroke; its minimum is "
            "where a load disturbance moves the output most. Linear: limits, friction and backlash left out."]
    step_rows = [("step of external load", fmt(step.amplitude), load_unit),
                 ("peak deflection", fmt(step.peak * af), au), ("at", fmt(step.peak_time * 1e3), "ms"),
                 ("final deflection (static gain)", fmt(static_shown), au),
                 ("recovery to 10 % of the peak", fmt(rec * 1e3) if math.isfinite(rec) else "not recovered", "ms")]
    body = (table(("figure", "value", "unit"), step_rows, table_id="disturbance-table")
            + table((f"q [{au}]", f"at {fmt(F_MIN)} Hz [{k_unit}]", f"minimum [{k_unit}]", "at [Hz]",
                     f"stiffness / w^2 at {fmt(F_MAX)} Hz [{inertia}]"), rows, table_id="dynamic-stiffness-table"))
    return Section("Disturbance step and dynamic stiffness along the stroke", para(*text) + body,
                   (FigureSpec(fig1, "Output deflection after a step of external load at q0 (linear closed loop)."),
                    FigureSpec(fig2, "Dynamic stiffness of the closed loop at points along the stroke.")),
                   key="disturbance")
