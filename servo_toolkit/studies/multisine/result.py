"""The result of a multisine sweep (:func:`servo_toolkit.studies.multisine.run.multisine_sweep`):
the loop's response at the excited lines with its coherence, against the linear model; the
CSV ``fit`` reads and the time log ``frf`` reads."""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np

from ...core.output_units import OutputUnit
from ...core.spectra import response_csv
from ...display.cards import RichDisplay, card, num, svg, table
from ..model_setup import model_line
from ..sweep.result import phase_along_frequency

_LABELS = {"closed_loop": ("position command -> output position", "gain [dB]"),
           "plant": ("motor current -> motor speed", "gain [dB re 1 (rad/s)/A]")}


@dataclass(frozen=True, repr=False, eq=False)
class MultisineResult(RichDisplay):
    """The loop's response to a periodic multisine command, per amplitude.

    Attributes
    ----------
    scene : str
    study : str or None
    response_kind : {"closed_loop", "plant"}
    frequency_hz : numpy.ndarray
        (n_l,) the excited lines.
    amplitudes : numpy.ndarray
        (n_a,) peak command amplitudes in SI (rad, or m for an output travel).
    response, coherence : numpy.ndarray
        (n_a, n_l) H1 estimate (complex; NaN where the run failed) and its coherence.
    linear_response : numpy.ndarray
        (n_l,) the linear model's response at the lines.
    distortion_db : numpy.ndarray
        (n_a,) output power at the lines not excited (up to the highest) over that at the
        excited lines (dB; -inf for a linear loop).
    saturated : numpy.ndarray
        (n_a,) bool: the current or voltage limit was reached in the estimation periods.
    peak_current_A, peak_voltage_V : numpy.ndarray
        (n_a,) peaks of |i_ref| and |v| in the estimation periods.
    errors : tuple
        (n_a,) None, or why the run failed.
    logs : tuple
        (n_a,) the run's records ``(time_s, input, output)`` (None where it failed): what a
        rig's log would hold, settling periods included.
    periods, settle : int
        Periods estimated from, and run first.
    period_s : float
    lines_asked : int
    reduced, left_out, options, controller, method, wall_s, notes, output_unit
        As :class:`servo_toolkit.studies.sweep.compute.SweepResult`.
    """

    scene: str
    study: str | None
    response_kind: str
    frequency_hz: np.ndarray
    amplitudes: np.ndarray
    response: np.ndarray
    coherence: np.ndarray
    linear_response: np.ndarray
    distortion_db: np.ndarray
    saturated: np.ndarray
    peak_current_A: np.ndarray
    peak_voltage_V: np.ndarray
    errors: tuple
    logs: tuple
    periods: int
    settle: int
    period_s: float
    lines_asked: int
    reduced: bool = False
    left_out: tuple = ()
    options: dict = field(default_factory=dict)
    controller: str = ""
    method: str = "rk4"
    wall_s: float = 0.0
    notes: tuple = ()
    output_unit: str = "rad"

    @property
    def unit(self) -> OutputUnit:
        """The output coordinate's units."""
        return OutputUnit(self.output_unit)

    @property
    def linear_gain_db(self) -> np.ndarray:
        """(n_l,) gain of the linear model (dB)."""
        return 20 * np.log10(np.abs(self.linear_response))

    @property
    def linear_phase_deg(self) -> np.ndarray:
        """(n_l,) unwrapped phase of the linear model (deg)."""
        return np.degrees(np.unwrap(np.angle(self.linear_response)))

    @property
    def gain_db(self) -> np.ndarray:
        """(n_a, n_l) gain of the loop (dB)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return 20 * np.log10(np.abs(self.response))

    @property
    def phase_deg(self) -> np.ndarray:
        """(n_a, n_l) phase (deg): the difference from the linear model's unwrapped phase,
        unwrapped along frequency (:func:`.sweep.result.phase_along_frequency`), so no line
        jumps by a turn."""
        return np.degrees(phase_along_frequency(self.response, np.radians(self.linear_phase_deg)))

    def deviation(self) -> dict:
        """Largest |gain difference| (dB) and |phase difference| (deg) from the linear model
        per amplitude (lists)."""
        dg = np.abs(self.gain_db - self.linear_gain_db[None, :])
        dp = np.abs(self.phase_deg - self.linear_phase_deg[None, :])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            return {"max_gain_difference_dB": np.nanmax(dg, axis=1).tolist(),
                    "max_phase_difference_deg": np.nanmax(dp, axis=1).tolist()}

    def csv(self, amplitude: int = 0) -> str:
        """The response at one amplitude as the CSV ``fit`` reads
        (``frequency_hz,gain_db,phase_deg,coherence,averages``; ``--response`` is
        :attr:`response_kind`)."""
        h = self.response[amplitude]
        return response_csv(self.frequency_hz, 20 * np.log10(np.abs(h)), np.degrees(np.unwrap(np.angle(h))),
                            self.coherence[amplitude], self.periods)

    @property
    def log_columns(self) -> tuple:
        """The names of the log's input and output columns."""
        if self.response_kind == "plant":
            return "current_A", "motor_speed_rad_s"
        u = self.output_unit
        return f"command_{u}", f"output_{u}"

    def log_csv(self, amplitude: int = 0) -> str:
        """The run's records at one amplitude as a log ``frf`` reads (deviations from the
        operating point): ``time_s,INPUT,OUTPUT``."""
        t, u, y = self.logs[amplitude]
        lines = ["time_s," + ",".join(self.log_columns)]
        lines += [f"{a:.12g},{b:.17g},{c:.17g}" for a, b, c in zip(t, u, y)]
        return "\n".join(lines) + "\n"

    def to_dict(self) -> dict:
        """JSON-ready: per amplitude, ``points`` [{frequency_hz, gain_db, phase_deg,
        coherence, linear_gain_db, linear_phase_deg}] and the run's figures."""
        u = self.unit
        g, p, lg, lp = self.gain_db, self.phase_deg, self.linear_gain_db, self.linear_phase_deg
        runs = []
        for a, amp in enumerate(self.amplitudes):
            points = [{"frequency_hz": float(f), "gain_db": float(g[a, k]), "phase_deg": float(p[a, k]),
                       "coherence": float(self.coherence[a, k]), "linear_gain_db": float(lg[k]),
                       "linear_phase_deg": float(lp[k])} for k, f in enumerate(self.frequency_hz)]
            runs.append({u.key("amplitude"): float(u.show(amp)), "points": points,
                         "distortion_dB": float(self.distortion_db[a]), "saturated": bool(self.saturated[a]),
                         "peak_current_A": float(self.peak_current_A[a]),
                         "peak_voltage_V": float(self.peak_voltage_V[a]), "error": self.errors[a]})
        return {"scene": self.scene, "study": self.study, "method": "multisine", "response": self.response_kind,
                "lines": int(self.frequency_hz.size), "lines_asked": self.lines_asked,
                "period_s": self.period_s, "periods": self.periods, "settle_periods": self.settle,
                "window": "periodic", "runs": runs, "deviation_from_linear": self.deviation(),
                "model": {"reduced": self.reduced, "left_out": list(self.left_out), "options": self.options,
                          "controller": self.controller, "method": self.method},
                "wall_s": self.wall_s, "notes": list(self.notes)}

    def table(self) -> str:
        """Plain-text table, one block per amplitude."""
        what, _ = _LABELS[self.response_kind]
        lines = [f"Multisine sweep of {self.scene}" + (f", study {self.study}" if self.study else "")
                 + f": {what}",
                 f"{self.frequency_hz.size} lines {self.frequency_hz[0]:.4g}-{self.frequency_hz[-1]:.4g} Hz "
                 f"(Schroeder phases), period {self.period_s:.4g} s, {self.settle} settling + {self.periods} "
                 "estimation periods, rectangular window on each period (H1)"]
        lines.append(model_line(self.reduced, self.left_out, self.options))
        lines += [f"note: {n}" for n in self.notes]
        g, p, lg, lp = self.gain_db, self.phase_deg, self.linear_gain_db, self.linear_phase_deg
        for a, amp in enumerate(self.amplitudes):
            lines.append(f"\npeak amplitude {self.unit.text(amp)}")
            if self.errors[a]:
                lines.append(f"  FAILED: {self.errors[a]}")
                continue
            lines.append(f"{'f [Hz]':>9} {'gain [dB]':>10} {'phase [deg]':>12} {'coherence':>10} {'linear dB':>10} "
                         f"{'linear deg':>11} {'dG [dB]':>8} {'dP [deg]':>9}")
            for k, f in enumerate(self.frequency_hz):
                lines.append(f"{f:9.4g} {g[a, k]:10.3f} {p[a, k]:12.2f} {self.coherence[a, k]:10.6f} {lg[k]:10.3f} "
                             f"{lp[k]:11.2f} {g[a, k] - lg[k]:8.3f} {p[a, k] - lp[k]:9.2f}")
            sat = "; current or voltage limit reached" if self.saturated[a] else ""
            lines.append(f"  distortion at the lines not excited: {self.distortion_db[a]:.1f} dB{sat}")
        dev = self.deviation()
        lines.append("\nlargest difference from the linear model: " + "; ".join(
            f"{self.unit.text(a, 3)}: " + ("FAILED, no estimate" if err else
                                          f"{dg:.3f} dB / {dp:.2f} deg" + (" (saturated: the current or voltage "
                                                                            "limit was reached)" if sat else ""))
            for a, dg, dp, sat, err in zip(self.amplitudes, dev["max_gain_difference_dB"],
                                           dev["max_phase_difference_deg"], self.saturated, self.errors)))
        return "\n".join(lines)

    def plot(self, axes=None):
        """Gain, phase and coherence against frequency: the linear model as a line, the
        estimate at each amplitude as markers. Returns the three Axes."""
        import matplotlib.pyplot as plt
        if axes is None:
            _, axes = plt.subplots(3, 1, sharex=True, figsize=(7, 7.5))
        ag, ap, ac = axes
        f = self.frequency_hz
        ag.semilogx(f, self.linear_gain_db, "k-", lw=1, label="linear model")
        ap.semilogx(f, self.linear_phase_deg, "k-", lw=1)
        for a, amp in enumerate(self.amplitudes):
            line, = ag.semilogx(f, self.gain_db[a], "o", ms=4, label=f"multisine {self.unit.text(amp, 3)} peak")
            ap.semilogx(f, self.phase_deg[a], "o", ms=4, color=line.get_color())
            ac.semilogx(f, self.coherence[a], "o-", ms=3, lw=0.8, color=line.get_color())
        ag.set_ylabel(_LABELS[self.response_kind][1])
        ap.set_ylabel("phase [deg]")
        ac.set_ylabel("coherence [-]")
        ac.set_xlabel("frequency [Hz]")
        ac.set_ylim(min(0.9, float(np.nanmin(self.coherence)) - 0.01) if np.isfinite(self.coherence).any() else 0,
                    1.005)
        ag.set_title(f"{self.scene}: {_LABELS[self.response_kind][0]}" + (" (reduced model)" if self.reduced else ""))
        for ax in axes:
            ax.grid(True, which="both", alpha=0.3)
        ag.legend(fontsize="small")
        return axes

    def _repr_line(self) -> str:
        dev = self.deviation()
        worst = max(dev["max_gain_difference_dB"] or [math.nan])
        return (f"{self.scene}: multisine {self.response_kind}, {self.frequency_hz.size} lines "
                f"{self.frequency_hz[0]:.3g}-{self.frequency_hz[-1]:.3g} Hz x {self.amplitudes.size} amplitude(s), "
                f"largest |dG| {num(worst, 3)} dB from the linear model, {sum(e is not None for e in self.errors)} failed")

    def _repr_card(self) -> str:
        dev = self.deviation()
        rows = [(self.unit.text(a, 3), f"{num(g, 3)} dB", f"{num(p, 3)} deg", f"{num(d, 3)} dB",
                 f"{num(float(np.nanmin(c)), 4)}")
                for a, g, p, d, c in zip(self.amplitudes, dev["max_gain_difference_dB"],
                                         dev["max_phase_difference_deg"], self.distortion_db, self.coherence)]
        parts = [table(("peak amplitude", "largest |dG|", "largest |dP|", "distortion", "least coherence"), rows),
                 svg(self.plot, size=(7.0, 6.0), rows=3, sharex=True)]
        return card(f"Multisine sweep of {self.scene}: {_LABELS[self.response_kind][0]}", parts=parts,
                    notes=self.notes)


__all__ = ["MultisineResult"]
