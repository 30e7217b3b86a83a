"""The result of a sizing: loads along the cycle, envelope, thermal, life, margins, sweep."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...display.cards import RichDisplay, badge, card, facts, num, svg, table


#: 0 degC in K
KELVIN = 273.15


def _margin_text(margin: float) -> str:
    """A margin as a percentage; an unbounded one (a life without a revolution, a thermal
    runaway) as inf or -inf."""
    return f"{margin:.1%}" if math.isfinite(margin) else ("inf" if margin > 0 else "-inf")


def _fin(x):
    return float(x) if x is not None and math.isfinite(x) else None


@dataclass(frozen=True, repr=False)
class SizingResult(RichDisplay):
    """The motor and the screw along a duty cycle, against their limits.

    Attributes
    ----------
    scene : str
    output_unit : str
        ``"rad"`` or ``"m"``: the unit of the motion's position.
    method : str
        ``"inverse_dynamics"`` or ``"closed_loop"``.
    motion : CycleMotion
        The sampled cycle.
    motor_torque, motor_speed, current, voltage : numpy.ndarray
        N*m, rad/s, A and V (hot winding) at each sample.
    electrical_power, mechanical_power : numpy.ndarray
        u i and T w (W); negative electrical power is regenerated.
    envelope : Envelope
    rms_torque, rms_current : float
        Over one cycle (N*m, A).
    peak_power : float
        Largest |T w| (W).
    peak_electrical_power : float
        Largest u i drawn from the supply (W).
    regenerated_energy : float
        Energy the motor returns to the supply per cycle (J), the winding at the ambient
        temperature (cold: the most it returns; the hot winding's loss returns less).
    thermal : ThermalResult or None
        None when the motor has no thermal network.
    lives : tuple of Life
        Screw and bearing L10 (rated parts only).
    margins : tuple of Margin
    sweep : RatioSweep or None
    screw_thrust : numpy.ndarray or None
        N at each sample, from the inverse dynamics of the prescribed motion (in both
        modes); None without a screw.
    notes : tuple of str
        What the figures rest on (closed loop: the winding, the segments run as sampled
        commands, the time at the supply's voltage, the tracking error).
    voltage_clamp_time : float or None
        Closed loop: time per cycle the voltage sat at the supply's limit (s).
    """

    scene: str
    output_unit: str
    method: str
    motion: object
    motor_torque: np.ndarray
    motor_speed: np.ndarray
    current: np.ndarray
    voltage: np.ndarray
    electrical_power: np.ndarray
    mechanical_power: np.ndarray
    envelope: object
    rms_torque: float
    rms_current: float
    peak_power: float
    peak_electrical_power: float
    regenerated_energy: float
    thermal: object
    lives: tuple
    margins: tuple
    sweep: object
    screw_thrust: np.ndarray | None = None
    notes: tuple = ()
    voltage_clamp_time: float | None = None

    @property
    def passed(self) -> bool:
        """True when every margin holds."""
        return all(m.passed for m in self.margins)

    @property
    def worst(self):
        """The margin closest to (or furthest beyond) its limit, or None."""
        return min(self.margins, key=lambda m: m.margin) if self.margins else None

    def to_dict(self, traces: bool = False) -> dict:
        """JSON-ready dictionary; ``traces`` adds the time series of the cycle."""
        out = {"scene": self.scene, "method": self.method, "passed": self.passed,
               "cycle_duration_s": self.motion.duration,
               "rms_torque_Nm": self.rms_torque, "rms_current_A": self.rms_current,
               "peak_torque_Nm": float(np.abs(self.motor_torque).max()),
               "peak_speed_rad_s": float(np.abs(self.motor_speed).max()),
               "peak_power_W": self.peak_power, "peak_electrical_power_W": self.peak_electrical_power,
               "regenerated_energy_J": self.regenerated_energy, "envelope": self.envelope.to_dict(),
               "peak_winding_temperature_degC": None if self.thermal is None else _fin(self.thermal.peak_winding - KELVIN),
               "thermal_runaway": None if self.thermal is None else self.thermal.runaway,
               "lives": [life.to_dict() for life in self.lives],
               "margins": [m.to_dict() for m in self.margins],
               "voltage_clamp_time_s": self.voltage_clamp_time, "notes": list(self.notes),
               "sweep": None if self.sweep is None else self.sweep.to_dict()}
        if traces:
            out["traces"] = {"t_s": self.motion.t.tolist(), "q": self.motion.q.tolist(),
                             "motor_torque_Nm": self.motor_torque.tolist(),
                             "motor_speed_rad_s": self.motor_speed.tolist(), "current_A": self.current.tolist(),
                             "voltage_V": self.voltage.tolist()}
        return out

    def table(self) -> str:
        """Plain-text summary for a terminal."""
        lines = [f"Sizing of {self.scene} along its duty cycle ({self.motion.duration:.4g} s, "
                 f"{self.method.replace('_', ' ')})",
                 f"  RMS torque {self.rms_torque:.4g} N*m, RMS current {self.rms_current:.4g} A, "
                 f"peak power {self.peak_power:.4g} W, regenerated {self.regenerated_energy:.4g} J per cycle",
                 f"  {'quantity':<34}{'value':>12}{'limit':>12}  unit   margin"]
        for m in self.margins:
            margin = f"{_margin_text(m.margin):>7}"
            runaway = m.name == "winding temperature" and self.thermal is not None and self.thermal.runaway
            lines.append(f"  {m.name:<34}{m.value:>12.4g}{m.limit:>12.4g}  {m.unit:<6}{margin}  "
                         f"{'ok' if m.passed else 'EXCEEDED'}" + ("  (thermal runaway: no steady state)" * runaway))
        if self.sweep is not None:
            sw = self.sweep
            unit = sw.ratio_unit
            for i, name in enumerate(sw.motors):
                rng = sw.feasible_range(i)
                text = "none" if rng is None else f"{rng[0]:.4g} .. {rng[1]:.4g} {unit} ({sw.limits_text(i)})"
                lines.append(f"  {name}: feasible overall ratio {text}; RMS-optimal ratio "
                             f"{sw.rms_optimal_ratio[i]:.4g} {unit}")
        lines += [f"  note: {n}" for n in self.notes]
        return "\n".join(lines)

    def _repr_line(self) -> str:
        worst = self.worst
        tail = "" if worst is None else f", worst margin {worst.name} {worst.margin:.0%}"
        return (f"{self.scene}: {'PASS' if self.passed else 'FAIL'}, RMS {self.rms_current:.3g} A, "
                f"peak {float(np.abs(self.motor_torque).max()):.3g} N*m{tail}")

    def _repr_card(self) -> str:
        rows = [(m.name, f"{num(m.value)} {m.unit}", f"{num(m.limit)} {m.unit}", _margin_text(m.margin),
                 badge(m.passed)) for m in self.margins]
        parts = [facts([("RMS torque", f"{num(self.rms_torque)} N*m"), ("RMS current", f"{num(self.rms_current)} A"),
                        ("peak power", f"{num(self.peak_power)} W"),
                        ("regenerated per cycle", f"{num(self.regenerated_energy)} J")]),
                 table(("quantity", "value", "limit", "margin", ""), rows, raw_columns=(4,)),
                 svg(lambda ax: self.plot(ax.ravel()), size=(9, 6.5), rows=2, cols=2)]
        return card(f"Sizing of {self.scene}", status=self.passed, parts=parts)

    def plot(self, axes=None):
        """Torque-speed points on the envelope, the thermal trace, the ratio sweep's RMS
        current (the whole sweep: :meth:`plot_sweep`) and the torque over the cycle; returns
        the 4 axes."""
        if axes is None:
            import matplotlib.pyplot as plt
            _, axes = plt.subplots(2, 2, figsize=(10, 7.5))
            axes = np.ravel(axes)
        self.plot_torque_speed(axes[0])
        self.plot_thermal(axes[1])
        if self.sweep is None:
            axes[2].text(0.5, 0.5, "no ratio sweep", ha="center", transform=axes[2].transAxes)
        else:
            from .sweep_plot import plot_rms_panel
            plot_rms_panel(self.sweep, axes[2])
        axes[3].plot(self.motion.t, self.motor_torque, lw=1)
        axes[3].set_xlabel("time [s]")
        axes[3].set_ylabel("motor torque [N*m]")
        axes[3].grid(True, alpha=0.3)
        return axes

    def plot_torque_speed(self, ax):
        """Torque-speed points of the cycle against the envelope."""
        env = self.envelope
        top = max(float(np.abs(self.motor_speed).max()) * 1.2, 1e-9)
        if math.isfinite(env.no_load_speed):
            top = max(top, env.no_load_speed * 1.05)
        w, motoring, braking = env.curve(top)
        ax.plot(self.motor_speed, self.motor_torque, ".", ms=2, label="cycle")
        for sign in (1, -1):   # motoring in the 1st and 3rd quadrants, braking in the 2nd and 4th
            ax.plot(sign * w, sign * motoring, "k-", lw=1, label="peak / voltage" if sign > 0 else None)
            ax.plot(sign * w, -sign * braking, "k-", lw=1)
            if env.continuous_torque is not None:
                ax.axhline(sign * env.continuous_torque, color="C1", ls="--", lw=1,
                           label="continuous" if sign > 0 else None)
        ax.set_xlabel("motor speed [rad/s]")
        ax.set_ylabel("motor torque [N*m]")
        ax.grid(True, alpha=0.3)
        # in a row above the axes: the envelope's lines cross every quadrant, no corner is free
        ax.legend(fontsize="small", loc="lower center", bbox_to_anchor=(0.5, 1.0), ncol=3, frameon=False)
        return ax

    def plot_thermal(self, ax):
        """Winding temperature at the end of each cycle from a cold start."""
        th = self.thermal
        if th is None or th.runaway:
            ax.text(0.5, 0.5, "no thermal network" if th is None else "thermal runaway", ha="center",
                    transform=ax.transAxes)
            return ax
        ax.plot(th.cycles * self.motion.duration / 60, th.winding_at_cycle_end - KELVIN, label="winding, cycle ends")
        ax.axhline(th.peak_winding - KELVIN, color="C1", ls="--", lw=1, label="steady periodic peak")
        ax.set_xlabel("time from cold [min]")
        ax.set_ylabel("winding temperature [degC]")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize="small")
        return ax

    def plot_sweep(self, axes=None):
        """The ratio choice on one figure (:meth:`RatioSweep.plot`: RMS current, peak torque and
        speed, winding temperature, bandwidth estimate, output stiffness and a swept lead's
        lives over the overall ratio, the limits, feasible ratios and the scene's ratio);
        returns the axes."""
        if self.sweep is None:
            raise ValueError("no ratio sweep: size(scene, sweep=True) computes it")
        return self.sweep.plot(axes)


__all__ = ["SizingResult"]
