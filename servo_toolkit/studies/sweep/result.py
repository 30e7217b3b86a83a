"""The result of a sine-dwell sweep (:func:`servo_toolkit.studies.sweep.compute.sweep`): the nonlinear
loop's response per amplitude and frequency against the linear loop, with each point's flags.

The phase of the nonlinear loop is its difference from the linear loop's unwrapped phase,
unwrapped along frequency (starting within 180 deg of the linear loop at the lowest frequency
that ran), so neither the phase nor the difference jumps by a turn between rows. The largest
difference from the linear loop is taken over the points valid for that comparison: those
that ran, stayed within the current and voltage limits and settled; the others are counted
and named by their flag.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np

from ...core.output_units import OutputUnit
from ...display.cards import RichDisplay, card, num, svg, table
from ...display.html import esc
from ..model_setup import model_line
from ..sine_dwell import DwellPlan

#: relative change of the estimate between the window's halves above which a point is unsettled
UNSETTLED = 0.01


def phase_along_frequency(response, linear_phase):
    """(n_a, n_f) phase (rad) of ``response`` (n_a, n_f complex): its difference from the
    unwrapped ``linear_phase`` (n_f, rad) unwrapped along frequency, the first point that ran
    within 180 deg of the linear loop; NaN where the response is (points that did not run are
    skipped by the unwrapping)."""
    dev = np.angle(response) - np.asarray(linear_phase)[None, :]
    out = np.full(dev.shape, np.nan)
    for a, row in enumerate(dev):
        ran = np.isfinite(row)
        if ran.any():
            d = np.unwrap(row[ran])
            out[a, ran] = d + ((d[0] + np.pi) % (2 * np.pi) - np.pi - d[0])
    return np.asarray(linear_phase)[None, :] + out


@dataclass(frozen=True, repr=False)
class SweepResult(RichDisplay):
    """Sine-dwell frequency response of the nonlinear loop and the linear loop.

    Attributes
    ----------
    scene : str
    study : str or None
    frequencies_hz : numpy.ndarray
        (n_f,)
    amplitudes_rad : numpy.ndarray
        (n_a,) command amplitudes in SI: rad, or m for an output travel (see
        ``output_unit``).
    response : numpy.ndarray
        (n_a, n_f) complex output/command fundamental ratio (NaN where a run failed).
    linear_response : numpy.ndarray
        (n_f,) complex linear closed loop theta/theta_ref.
    linear_grid_hz, linear_grid_response : numpy.ndarray
        Dense grid and response of the linear loop (plot lines).
    settling_change : numpy.ndarray
        (n_a, n_f) relative change of the estimate between the halves of the window.
    saturated : numpy.ndarray
        (n_a, n_f) bool: the current or voltage limit was reached in the window (a failed
        run: before it failed; see :attr:`failed`).
    peak_current_A, peak_voltage_V : numpy.ndarray
        (n_a, n_f) peaks of |i_ref| and |v| in the window (a failed run: up to the failure).
    errors : tuple
        (n_a * n_f) row-major: None, or why the run failed.
    reduced : bool
        The reduced model ran (False: the full model or given options).
    left_out : tuple of str
        What the reduced model leaves out, with the a-priori reason.
    options : dict
        The model options that ran.
    plan : DwellPlan
    decay_rate : float
        Slowest decay rate of the linear closed loop (1/s) used for the settling time.
    controller : str
    method : str
    wall_s : float
    output_unit : {"rad", "m"}
        Unit of the output coordinate; amplitudes are shown in deg or mm after it.
    """

    scene: str
    study: str | None
    frequencies_hz: np.ndarray
    amplitudes_rad: np.ndarray
    response: np.ndarray
    linear_response: np.ndarray
    linear_grid_hz: np.ndarray
    linear_grid_response: np.ndarray
    settling_change: np.ndarray
    saturated: np.ndarray
    peak_current_A: np.ndarray
    peak_voltage_V: np.ndarray
    errors: tuple
    reduced: bool
    left_out: tuple
    options: dict
    plan: DwellPlan
    decay_rate: float
    controller: str = ""
    method: str = "rk4"
    wall_s: float = 0.0
    notes: tuple = field(default_factory=tuple)
    output_unit: str = "rad"

    @property
    def unit(self) -> OutputUnit:
        """The output coordinate's units (deg or mm shown)."""
        return OutputUnit(self.output_unit)

    @property
    def failed(self) -> np.ndarray:
        """(n_a, n_f) bool: the run failed (see ``errors``); ``saturated`` then tells whether
        it reached a limit before failing."""
        return np.array([e is not None for e in self.errors], dtype=bool).reshape(self.response.shape)

    @property
    def linear_phase(self) -> np.ndarray:
        """Unwrapped phase (rad) of the linear loop at the sweep frequencies."""
        grid = np.unwrap(np.angle(self.linear_grid_response))
        return np.interp(self.frequencies_hz, self.linear_grid_hz, grid)

    @property
    def gain_db(self) -> np.ndarray:
        """(n_a, n_f) gain of the nonlinear loop (dB)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return 20 * np.log10(np.abs(self.response))

    @property
    def phase_deg(self) -> np.ndarray:
        """(n_a, n_f) phase (deg): the difference from the linear loop's unwrapped phase,
        unwrapped along frequency (:func:`phase_along_frequency`), so no row jumps by a turn."""
        return np.degrees(phase_along_frequency(self.response, self.linear_phase))

    @property
    def unsettled(self) -> np.ndarray:
        """(n_a, n_f) bool: the estimate changed by more than :data:`UNSETTLED` between the
        halves of the window (a point that ran)."""
        with np.errstate(invalid="ignore"):
            return (self.settling_change > UNSETTLED) & ~self.failed

    @property
    def valid(self) -> np.ndarray:
        """(n_a, n_f) bool: the point is valid for the comparison with the linear loop: it
        ran, stayed within the current and voltage limits and settled."""
        return ~self.failed & ~self.saturated & ~self.unsettled & np.isfinite(self.response)

    @property
    def linear_gain_db(self) -> np.ndarray:
        """(n_f,) gain of the linear loop (dB)."""
        return 20 * np.log10(np.abs(self.linear_response))

    @property
    def linear_phase_deg(self) -> np.ndarray:
        """(n_f,) unwrapped phase of the linear loop (deg)."""
        return np.degrees(self.linear_phase)

    def deviation(self) -> dict:
        """Largest |gain difference| (dB) and |phase difference| (deg) from the linear loop,
        per amplitude (lists; NaN: no valid point), over the points valid for the comparison
        (:attr:`valid`), and per amplitude the number of points compared and of those left
        out: failed, saturated (reached a limit) and, of the rest, unsettled."""
        dg = np.abs(self.gain_db - self.linear_gain_db[None, :])
        dp = np.abs(self.phase_deg - self.linear_phase_deg[None, :])
        ok = self.valid
        sat = self.saturated & ~self.failed
        with warnings.catch_warnings():  # an amplitude without a valid point gives NaN
            warnings.simplefilter("ignore", RuntimeWarning)
            return {"max_gain_difference_dB": np.nanmax(np.where(ok, dg, np.nan), axis=1).tolist() if dg.size else [],
                    "max_phase_difference_deg": np.nanmax(np.where(ok, dp, np.nan), axis=1).tolist()
                    if dp.size else [],
                    "points_compared": ok.sum(axis=1).tolist(),
                    "points_failed": self.failed.sum(axis=1).tolist(),
                    "points_saturated": sat.sum(axis=1).tolist(),
                    "points_unsettled": (self.unsettled & ~sat).sum(axis=1).tolist(),
                    "over": "points that ran, stayed within the current and voltage limits and settled "
                            f"(estimate change <= {UNSETTLED:.0%})"}

    def _summary(self, a: int, dev: dict) -> str:
        """One amplitude's largest difference and what it is over."""
        n = self.frequencies_hz.size
        left = [f"{dev[key][a]} {word}" for key, word in (("points_saturated", "saturated"),
                                                          ("points_unsettled", "unsettled"),
                                                          ("points_failed", "failed")) if dev[key][a]]
        out = f" (excluded: {', '.join(left)})" if left else ""
        amp = self.unit.text(self.amplitudes_rad[a], 3)
        if not dev["points_compared"][a]:
            return f"{amp}: no valid point of {n}{out}"
        return (f"{amp}: {dev['max_gain_difference_dB'][a]:.3f} dB / {dev['max_phase_difference_deg'][a]:.2f} deg "
                f"over {dev['points_compared'][a]} of {n} points{out}")

    def to_dict(self) -> dict:
        """JSON-ready: ``points`` [{frequency_hz, gain_db, phase_deg, linear_gain_db,
        linear_phase_deg, ...}] (+ ``amplitude_deg``, or ``amplitude_mm`` for an output
        travel, when several amplitudes ran)."""
        u = self.unit
        several = self.amplitudes_rad.size > 1
        g, p, lg, lp = self.gain_db, self.phase_deg, self.linear_gain_db, self.linear_phase_deg
        points = []
        for a, amp in enumerate(self.amplitudes_rad):
            for k, f in enumerate(self.frequencies_hz):
                pt = {"frequency_hz": float(f), "gain_db": float(g[a, k]), "phase_deg": float(p[a, k]),
                      "linear_gain_db": float(lg[k]), "linear_phase_deg": float(lp[k])}
                if several:
                    pt[u.key("amplitude")] = float(u.show(amp))
                pt.update({"settling_change": float(self.settling_change[a, k]),
                           "saturated": bool(self.saturated[a, k]),
                           "unsettled": bool(self.unsettled[a, k]),
                           "failed": bool(self.failed[a, k]),
                           "peak_current_A": float(self.peak_current_A[a, k]),
                           "peak_voltage_V": float(self.peak_voltage_V[a, k]),
                           "error": self.errors[a * self.frequencies_hz.size + k]})
                points.append(pt)
        return {"scene": self.scene, "study": self.study,
                u.key("amplitudes"): u.show(self.amplitudes_rad).tolist(),
                "points": points, "deviation_from_linear": self.deviation(),
                "model": {"reduced": self.reduced, "left_out": list(self.left_out),
                          "options": self.options, "controller": self.controller, "method": self.method},
                "plan": dict(self.plan.to_dict(), slowest_decay_rate_per_s=self.decay_rate),
                "wall_s": self.wall_s, "notes": list(self.notes)}

    def table(self) -> str:
        """Plain-text table, one block per amplitude."""
        lines = [f"Sine-dwell sweep of {self.scene}" + (f", study {self.study}" if self.study else "")]
        lines.append(model_line(self.reduced, self.left_out, self.options))
        lines += [f"note: {n}" for n in self.notes]
        g, p, lg, lp = self.gain_db, self.phase_deg, self.linear_gain_db, self.linear_phase_deg
        for a, amp in enumerate(self.amplitudes_rad):
            lines.append(f"\namplitude {self.unit.text(amp)}")
            lines.append(f"{'f [Hz]':>9} {'gain [dB]':>10} {'phase [deg]':>12} {'linear dB':>10} "
                         f"{'linear deg':>11} {'dG [dB]':>8} {'dP [deg]':>9}  flags")
            for k, f in enumerate(self.frequencies_hz):
                err = self.errors[a * self.frequencies_hz.size + k]
                sat = ("saturated before failing " if err else "saturated ") if self.saturated[a, k] else ""
                flags = sat + \
                        (f"unsettled ({self.settling_change[a, k]:.1%}) " if self.unsettled[a, k] else "") + \
                        (f"FAILED: {err}" if err else "")
                lines.append(f"{f:9.4g} {g[a, k]:10.3f} {p[a, k]:12.2f} {lg[k]:10.3f} {lp[k]:11.2f} "
                             f"{g[a, k] - lg[k]:8.3f} {p[a, k] - lp[k]:9.2f}  {flags}".rstrip())
        dev = self.deviation()
        lines.append("\nlargest difference from the linear loop, over the points that ran within the limits and "
                     "settled: " + "; ".join(self._summary(a, dev) for a in range(self.amplitudes_rad.size)))
        return "\n".join(lines)

    def plot(self, axes=None):
        """Bode plot: linear loop as lines, sine-dwell points as markers (one series per
        amplitude; saturated points hollow). Returns the two Axes."""
        import matplotlib.pyplot as plt
        if axes is None:
            _, axes = plt.subplots(2, 1, sharex=True, figsize=(7, 6))
        ag, ap = axes
        grid_phase = np.degrees(np.unwrap(np.angle(self.linear_grid_response)))
        ag.semilogx(self.linear_grid_hz, 20 * np.log10(np.abs(self.linear_grid_response)), "k-", lw=1,
                    label="linear loop")
        ap.semilogx(self.linear_grid_hz, grid_phase, "k-", lw=1)
        g, p = self.gain_db, self.phase_deg
        for a, amp in enumerate(self.amplitudes_rad):
            sat = self.saturated[a]
            line, = ag.semilogx(self.frequencies_hz[~sat], g[a, ~sat], "o", ms=5,
                                label=f"sine dwell {self.unit.text(amp, 3)}")
            col = line.get_color()
            ap.semilogx(self.frequencies_hz[~sat], p[a, ~sat], "o", ms=5, color=col)
            if sat.any():
                ag.semilogx(self.frequencies_hz[sat], g[a, sat], "o", ms=6, mfc="none", color=col)
                ap.semilogx(self.frequencies_hz[sat], p[a, sat], "o", ms=6, mfc="none", color=col)
        ag.set_ylabel("gain [dB]")
        ap.set_ylabel("phase [deg]")
        ap.set_xlabel("frequency [Hz]")
        ag.set_title(f"{self.scene}: closed loop theta/theta_ref"
                     + (" (reduced model)" if self.reduced else ""))
        ag.grid(True, which="both", alpha=0.3)
        ap.grid(True, which="both", alpha=0.3)
        ag.legend(fontsize="small")
        return axes

    def _repr_line(self) -> str:
        return _card_line(self)

    def _repr_card(self) -> str:
        return _card_html(self)


def _card_line(s) -> str:
    """The one-line repr of a result of this module."""
    dev = s.deviation()
    amps = ", ".join(s.unit.text(a, 3) for a in s.amplitudes_rad)
    gains = [g for g in dev["max_gain_difference_dB"] if not math.isnan(g)]
    worst = max(gains) if gains else math.nan
    return (f"{s.scene}: {s.frequencies_hz.size} frequencies x {s.amplitudes_rad.size} amplitude(s) ({amps}), "
            f"largest |dG| {num(worst, 3)} dB from the linear loop over {sum(dev['points_compared'])} valid "
            f"point(s), {sum(dev['points_saturated'])} saturated, {sum(dev['points_unsettled'])} unsettled, "
            f"{int(s.failed.sum())} failed")


def _card_html(s) -> str:
    """The Jupyter card (HTML) of a result of this module."""
    dev = s.deviation()
    rows = [(s.unit.text(a, 3), f"{num(g, 3)} dB", f"{num(p, 3)} deg", dev["points_compared"][i],
             dev["points_saturated"][i], dev["points_unsettled"][i], dev["points_failed"][i])
            for i, (a, g, p) in enumerate(zip(s.amplitudes_rad, dev["max_gain_difference_dB"],
                                              dev["max_phase_difference_deg"]))]
    model = esc(model_line(s.reduced, s.left_out, s.options))
    parts = [table(("amplitude", "largest |dG|", "largest |dP|", "valid points", "saturated", "unsettled", "failed"),
                   rows),
             f'<p class="st-note">{model}</p>', svg(s.plot, size=(7.0, 4.6), rows=2, sharex=True)]
    return card(f"Sine-dwell sweep of {s.scene}" + (f", study {s.study}" if s.study else ""), parts=parts,
                notes=s.notes)


__all__ = ["UNSETTLED", "SweepResult", "phase_along_frequency"]
