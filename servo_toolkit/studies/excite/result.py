"""The result of :func:`servo_toolkit.studies.excite.excite`: the excitation, why it is as
large as it is, and the model's response to it; the file a rig plays and ``frf`` reads."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ...core.output_units import OutputUnit
from ...core.spectra import LINES_KEY, PERIOD_KEY, RESOLUTION_PREFIX, SETTLE_KEY
from ...display.cards import RichDisplay, card, facts, num, svg
from .drive import COLUMNS, UNITS
from .plan import ExcitationPlan
from .signals import crest_factor

_WHAT = {"current": "added to the drive's current reference (the position loop holds the operating point)",
         "speed": "the drive's motor-speed reference (its speed loop, no position loop)"}
#: the run's plant response departs from the linear plant's beyond these (a note says so)
DEPARTS_DB = 1.0
DEPARTS_DEG = 10.0
_SIGNAL = {"multisine": "multisine (equal lines, low-crest-factor phases)", "prbs": "PRBS (maximum-length sequence)",
           "chirp": "periodic linear chirp"}


@dataclass(frozen=True, repr=False, eq=False)
class ExcitationResult(RichDisplay):
    """An excitation for a rig's drive and the model's run of it.

    Attributes
    ----------
    scene : str
    input : {"current", "speed"}
        What the drive takes (:mod:`.drive`).
    plan : ExcitationPlan
        The signal, its band, sample time, period, lines and periods (:mod:`.plan`).
    shape : numpy.ndarray
        One period of the signal, peak 1.
    amplitude : float
        The excitation's peak (A, or motor rad/s).
    amplitude_source : {"chosen", "given"}
    binding : str
        The limit that set a chosen amplitude (``current``, ``voltage`` or ``stroke``).
    bounds : tuple of Bound
        Each limit's largest amplitude (:mod:`.levels`).
    operating_current_A : float
        The current holding the load at the operating point.
    linear_peak_current_A, linear_peak_voltage_V : float
        Peaks of |i| and |v| of the linear loop's periodic response.
    run_peak_current_A, run_peak_voltage_V : float
        Peaks of |i| (every step) and |v| (every sample) in the model's run, settling included.
    run_excursion : float
        Largest |output - q0| in the run (rad, or m).
    current_limit_A, voltage_limit_V : float
    breakaway_current_A, current_swing_A : float
        The holding band's current and the predicted swing of the current about its operating value.
    half_play, motion_amplitude, backlash_amplitude : float
        The play's half at the output, the motor side's motion amplitude there, and the
        amplitude the play's describing function needs (rad, or m).
    linear_plant, run_plant, coherence : numpy.ndarray
        At the lines: omega_m / i of the linear plant and of the model's run (H1, the
        rectangular window on each averaged period), and its coherence.
    log : dict
        The file's columns (``time_s`` first): the excitation and the model's response.
    controller : str
    notes : tuple of str
    output_unit : {"rad", "m"}
    steps : dict of str to float
        The step the rig's sensors round each logged column to (the scene's encoders: the
        motor angle's count, the output's), in the column's unit; the model's run is not
        rounded.
    wall_s : float
    """

    scene: str
    input: str
    plan: ExcitationPlan
    shape: np.ndarray
    amplitude: float
    amplitude_source: str
    binding: str
    bounds: tuple
    operating_current_A: float
    linear_peak_current_A: float
    linear_peak_voltage_V: float
    run_peak_current_A: float
    run_peak_voltage_V: float
    run_excursion: float
    current_limit_A: float
    voltage_limit_V: float
    breakaway_current_A: float
    current_swing_A: float
    half_play: float
    motion_amplitude: float
    backlash_amplitude: float
    linear_plant: np.ndarray
    run_plant: np.ndarray
    coherence: np.ndarray
    log: dict
    controller: str = ""
    notes: tuple = ()
    output_unit: str = "rad"
    wall_s: float = 0.0
    steps: dict = field(default_factory=dict)

    @property
    def unit(self) -> str:
        """The excitation's unit: ``"A"`` or ``"rad/s"``."""
        return UNITS[self.input]

    @property
    def column(self) -> str:
        """The excitation's column in the file."""
        return COLUMNS[self.input]

    @property
    def frequency_hz(self) -> np.ndarray:
        """The excited lines within the band (Hz)."""
        return self.plan.frequency_hz

    @property
    def crest_factor(self) -> float:
        """Peak over rms of the signal."""
        return crest_factor(self.shape)

    @property
    def rms(self) -> float:
        """The excitation's rms (A or rad/s)."""
        return self.amplitude / self.crest_factor

    def deviation(self) -> tuple[float, float]:
        """Largest |gain difference| (dB) and |phase difference| (deg) of the run's plant
        response from the linear plant's, over the lines (NaN without an estimate)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = self.run_plant / self.linear_plant
        if not np.isfinite(ratio).any():
            return math.nan, math.nan
        return (float(np.nanmax(np.abs(20 * np.log10(np.abs(ratio))))),
                float(np.nanmax(np.abs(np.degrees(np.angle(ratio))))))

    def csv(self) -> str:
        """The file: comment lines recording the period (``# period_samples: N``), the
        settling periods and the excited bins of the period's DFT, then ``time_s``, the excitation and the model's response at every
        sample (what ``frf`` reads; its defaults take ``current_A`` to ``motor_angle_rad``)."""
        names = list(self.log)
        plan = self.plan
        head = [f"# servo-toolkit excite: {plan.signal} {_WHAT[self.input]}, scene {self.scene}",
                f"# {PERIOD_KEY}: {plan.period_samples}", f"# {SETTLE_KEY}: {plan.settle}",
                f"# {LINES_KEY}: {plan.lines[0]}:{plan.lines[-1]}", f"# sample_time_s: {plan.sample_time:.12g}",
                *(["# the steps the rig's encoders log the angles in (the model's run below is not rounded to "
                   "them)"] if self.steps else []),
                *(f"# {RESOLUTION_PREFIX}{name}: {step!r}" for name, step in self.steps.items()),
                "# columns after the excitation: the model's predicted response (current_A, voltage_V, motor "
                "angle from the start, motor speed, output position)",
                ",".join(names)]
        data = np.column_stack([self.log[n] for n in names])
        body = ["{:.9g},".format(row[0]) + ",".join(f"{v:.12g}" for v in row[1:]) for row in data]
        return "\n".join(head + body) + "\n"

    def notes_on_levels(self) -> list:
        """Where the amplitude is below the breakaway or the backlash level, in words."""
        out = []
        if self.breakaway_current_A > 0 and self.current_swing_A < 2.0 * self.breakaway_current_A:
            out.append(f"below the breakaway level: the current swings {self.current_swing_A:.3g} A about its "
                       f"operating value, under twice the {self.breakaway_current_A:.3g} A that friction holds at "
                       "rest; friction that holds sticks the drive for part of each period or all of it, and the "
                       "response there is friction's, not the linear plant's")
        if self.half_play > 0 and self.motion_amplitude < self.backlash_amplitude:
            u = OutputUnit(self.output_unit)
            out.append(f"below the backlash level: the motor side moves {u.text(self.motion_amplitude, 3)} at the "
                       f"output, under the {u.text(self.backlash_amplitude, 3)} at which the play "
                       f"({u.text(2 * self.half_play, 3)}) keeps 90 % of the gain")
        return out

    def notes_on_response(self) -> list:
        """Where the run's plant response departs from the linear plant's by more than
        :data:`DEPARTS_DB` or :data:`DEPARTS_DEG`, in words."""
        dg, dp = self.deviation()
        if not (dg > DEPARTS_DB or dp > DEPARTS_DEG):
            return []
        with np.errstate(divide="ignore", invalid="ignore"):
            worst = float(self.frequency_hz[int(np.nanargmax(np.abs(np.log(self.run_plant / self.linear_plant))))])
        return [f"the model's run departs from the linear plant by up to {dg:.3g} dB and {dp:.3g} deg (most at "
                f"{worst:.4g} Hz): at this amplitude the response carries what the linear plant leaves out (the "
                "loss that switches with the power flow, friction, the play); expect the run's response, the file's"]

    def to_dict(self) -> dict:
        """JSON-ready figures (SI, with units in the keys), the lines with both plant responses."""
        lin, run = self.linear_plant, self.run_plant
        with np.errstate(divide="ignore"):
            points = [{"frequency_hz": float(f), "linear_gain_db": float(20 * np.log10(abs(a))),
                       "linear_phase_deg": float(np.degrees(np.angle(a))), "run_gain_db": float(20 * np.log10(abs(b))),
                       "run_phase_deg": float(np.degrees(np.angle(b))), "coherence": float(c)}
                      for f, a, b, c in zip(self.frequency_hz, lin, run, self.coherence)]
        u = OutputUnit(self.output_unit)
        dg, dp = self.deviation()
        plan = self.plan
        return {"scene": self.scene, "signal": plan.signal, "input": self.input, "unit": self.unit,
                "column": self.column, "band_hz": list(plan.band), "lines": int(plan.lines.size),
                "resolution_hz": plan.resolution_hz, "sample_time_s": plan.sample_time,
                "period_samples": plan.period_samples, "period_s": plan.period_s, "settle_periods": plan.settle,
                "periods": plan.periods, "duration_s": plan.duration_s, "amplitude": self.amplitude,
                "rms": self.rms, "crest_factor": self.crest_factor, "amplitude_source": self.amplitude_source,
                "binding_limit": self.binding,
                "bounds": [{"limit": b.name, "largest_amplitude": b.amplitude, "per_unit": b.per_unit,
                            "operating": b.operating, "limit_value": b.limit} for b in self.bounds],
                "operating_current_A": self.operating_current_A,
                "current_limit_A": self.current_limit_A, "voltage_limit_V": self.voltage_limit_V,
                "linear_peak_current_A": self.linear_peak_current_A,
                "linear_peak_voltage_V": self.linear_peak_voltage_V,
                "run_peak_current_A": self.run_peak_current_A, "run_peak_voltage_V": self.run_peak_voltage_V,
                u.key("run_excursion"): float(u.show(self.run_excursion)),
                "breakaway_current_A": self.breakaway_current_A, "current_swing_A": self.current_swing_A,
                u.key("play"): float(u.show(2 * self.half_play)),
                u.key("motion_amplitude"): float(u.show(self.motion_amplitude)),
                u.key("backlash_amplitude"): float(u.show(self.backlash_amplitude)),
                "points": points, "max_gain_difference_dB": dg, "max_phase_difference_deg": dp,
                "controller": self.controller, "notes": list(self.notes), "wall_s": self.wall_s,
                "encoder_steps": [{"column": k, "step": v, "unit": k.rsplit("_", 1)[-1]} for k, v in self.steps.items()]}

    def table(self) -> str:
        """The summary, units throughout."""
        u, plan = OutputUnit(self.output_unit), self.plan
        f = plan.frequency_hz
        lines = [f"Excitation for {self.scene}: {_SIGNAL[plan.signal]}, {_WHAT[self.input]}",
                 f"  band {plan.band[0]:.4g}-{plan.band[1]:.4g} Hz: {f.size} lines {f[0]:.4g}-{f[-1]:.4g} Hz, "
                 f"resolution {plan.resolution_hz:.4g} Hz",
                 f"  period {plan.period_s:.4g} s ({plan.period_samples} samples at {1 / plan.sample_time:.4g} Hz), "
                 f"{plan.settle} settling + {plan.periods} averaged periods, length {plan.duration_s:.4g} s",
                 f"  amplitude {self.amplitude:.4g} {self.unit} peak, {self.rms:.4g} {self.unit} rms, crest factor "
                 f"{self.crest_factor:.3f}; " + (f"chosen within {self.binding} limit's headroom" if
                                                 self.amplitude_source == "chosen" else "as given"),
                 f"  operating point: {self.operating_current_A:.4g} A holds the load",
                 f"  predicted peaks (model's run): current {self.run_peak_current_A:.4g} A of "
                 f"{_limit(self.current_limit_A, 'A')}, voltage {self.run_peak_voltage_V:.4g} V of "
                 f"{_limit(self.voltage_limit_V, 'V')}, "
                 f"output {u.text(self.run_excursion, 3)} from the operating point; linear loop "
                 f"{self.linear_peak_current_A:.4g} A, {self.linear_peak_voltage_V:.4g} V",
                 f"  levels: breakaway {self.breakaway_current_A:.3g} A (current swing {self.current_swing_A:.3g} A), "
                 f"play {u.text(2 * self.half_play, 3)} (motor-side motion {u.text(self.motion_amplitude, 3)})"]
        dg, dp = self.deviation()
        lines.append(f"  plant response (motor speed / current) of the run against the linear plant: largest "
                     f"difference {dg:.3g} dB, {dp:.3g} deg over the lines")
        lines += [f"  note: {n}" for n in self.notes]
        return "\n".join(lines)

    def plot(self, axes=None):
        """The excitation over one period, and the plant's gain at the lines (linear and the
        run's). Returns the two Axes."""
        import matplotlib.pyplot as plt
        if axes is None:
            _, axes = plt.subplots(2, 1, figsize=(7, 6))
        at, ag = axes
        t = np.arange(self.plan.period_samples) * self.plan.sample_time
        at.plot(t, self.amplitude * self.shape, lw=0.8)
        at.set_xlabel("time in the period [s]")
        at.set_ylabel(f"{self.input} excitation [{self.unit}]")
        at.set_title(f"{self.scene}: {self.plan.signal}, crest factor {self.crest_factor:.2f}")
        with np.errstate(divide="ignore"):
            ag.semilogx(self.frequency_hz, 20 * np.log10(np.abs(self.linear_plant)), "k-", lw=1, label="linear plant")
            ag.semilogx(self.frequency_hz, 20 * np.log10(np.abs(self.run_plant)), "o", ms=3, label="model's run (H1)")
        ag.set_xlabel("frequency [Hz]")
        ag.set_ylabel("motor speed per current [dB re 1 rad/s per A]")
        for ax in axes:
            ax.grid(True, which="both", alpha=0.3)
        ag.legend(fontsize="small")
        return axes

    def _repr_line(self) -> str:
        plan = self.plan
        return (f"{self.scene}: {plan.signal} on the {self.input} reference, {plan.lines.size} lines "
                f"{plan.band[0]:.3g}-{plan.band[1]:.3g} Hz, {self.amplitude:.3g} {self.unit} peak (crest factor "
                f"{self.crest_factor:.2f}), run peaks {self.run_peak_current_A:.3g} A / {self.run_peak_voltage_V:.3g} V")

    def _repr_card(self) -> str:
        plan = self.plan
        pairs = [("signal", _SIGNAL[plan.signal]), ("input", _WHAT[self.input]),
                 ("band", f"{plan.band[0]:.4g}-{plan.band[1]:.4g} Hz, {plan.lines.size} lines"),
                 ("resolution", f"{num(plan.resolution_hz)} Hz"),
                 ("periods", f"{plan.settle} settling + {plan.periods} averaged, {num(plan.duration_s)} s"),
                 ("amplitude", f"{num(self.amplitude)} {self.unit} peak, crest factor {num(self.crest_factor, 3)}"),
                 ("peaks in the model's run", f"{num(self.run_peak_current_A)} A of {num(self.current_limit_A)} A, "
                                              f"{num(self.run_peak_voltage_V)} V of {num(self.voltage_limit_V)} V")]
        return card(f"Excitation for {self.scene}", parts=[facts(pairs), svg(self.plot, size=(7.0, 6.0), rows=2)],
                    notes=self.notes)


def _limit(value: float, unit: str) -> str:
    """A limit as text: ``"60 A"``, or ``"no limit"`` where the scene sets none."""
    return f"{value:.4g} {unit}" if math.isfinite(value) else "no limit"


__all__ = ["ExcitationResult"]
