"""Frequency-response sweep of the nonlinear closed loop by sine dwell, against the linear loop.

At each frequency (and each amplitude) the compiled closed-loop model is driven by a sine
position command ``a sin(2 pi f t)`` about mid-stroke; after the settling time the output
angle's fundamental is estimated by correlation (:mod:`.sine_dwell`). The ratio to ``a`` is
the describing-function response of the loop, compared on one Bode plot with the design's
linear loop, :func:`servo_toolkit.loop.linear_closed_loop` with the same structural damping.
The linear loop scales the motor torque by the driving-mode drivetrain efficiency; the
nonlinear model's LossyGear-like loss (:mod:`servo_toolkit.sim.model`) passes eta where the
motor drives the load and 1/eta_b where the load drives the motor, so a free sine, whose
power flow reverses every quarter period, departs from the linear loop by what that
reversal changes (noted when the chain has losses).
Amplitude dependence (backlash, voltage and current limits) shows as one curve per
amplitude; points where a limit was reached are flagged.

By default the sweep runs the reduced model of :mod:`.reduce_estimates` (effects whose
a-priori influence on this study is below the tolerance are left out) and records what was
left out; ``full=True`` runs the full model.
"""

from __future__ import annotations

import math
import re
import time
import warnings
from dataclasses import dataclass, field

import numpy as np

from ..errors import SimulationError
from ..core.output_units import OutputUnit
from ..core.parallel import run_cases
from ..plant.linear import DEFAULT_STRUCTURAL_DAMPING
from .sine_dwell import DwellPlan, dwell_estimate
from .sweep_points import DEFAULT_AMPLITUDE, DEFAULT_FREQUENCY_HZ, study_points
from ..display.cards import RichDisplay
from ..display.cards import card, num, svg, table

def _dwell_case(case):
    """One sine dwell (module level so that executors can pickle it)."""
    from ..sim import Reference, run
    model, amp, freq, plan, decay, method, limits = case
    settle, est = plan.cycles(freq, decay)
    start = time.perf_counter()
    try:
        # a quarter cycle beyond the window, so that the records cover its end
        res = run(model, Reference.sine(amp, freq), (settle + est + 0.25) / freq, method)
    except SimulationError as exc:
        i_peak, v_peak = _peaks_before_failure(model, amp, freq, method, str(exc))
        sat = i_peak >= limits[0] * (1 - 1e-9) or v_peak >= limits[1] * (1 - 1e-9)
        return {"response": complex(math.nan, math.nan), "change": math.nan, "saturated": bool(sat),
                "peak_current_A": i_peak, "peak_voltage_V": v_peak, "error": str(exc),
                "wall_s": time.perf_counter() - start}
    y = res.output_angle - model.q0
    phasor, change = dwell_estimate(res.times, y, freq, settle, est)
    window = res.times >= settle / freq
    i_peak = float(np.max(np.abs(res.current_reference[window])))
    v_peak = float(np.max(np.abs(res.motor_voltage[window])))
    sat = i_peak >= limits[0] * (1 - 1e-9) or v_peak >= limits[1] * (1 - 1e-9)
    return {"response": phasor / amp, "change": change, "saturated": bool(sat), "peak_current_A": i_peak,
            "peak_voltage_V": v_peak, "error": None, "wall_s": time.perf_counter() - start}


def _peaks_before_failure(model, amp, freq, method, message):
    """Peaks of |i_ref| and |v| (NaN if unknown) of a failed dwell up to its failure.

    The run is repeated up to 99 % of the failure time named in the message ("at t = ... s"),
    so that a point that reached the current or voltage limit before failing is flagged.
    """
    from ..sim import Reference, run
    found = re.search(r"at t = ([0-9.eE+-]+) s", message)
    t_fail = float(found.group(1)) if found else 0.0
    if not t_fail > 0:
        return math.nan, math.nan
    try:
        res = run(model, Reference.sine(amp, freq), 0.99 * t_fail, method)
    except (SimulationError, ValueError):
        return math.nan, math.nan
    return float(np.max(np.abs(res.current_reference))), float(np.max(np.abs(res.motor_voltage)))


def _wrap_near(phase, ref):
    """``phase`` shifted by whole turns to lie within 180 deg of ``ref`` (radians)."""
    return ref + (phase - ref + np.pi) % (2 * np.pi) - np.pi


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
        """(n_a, n_f) phase (deg), on the branch nearest the linear loop's unwrapped phase."""
        return np.degrees(_wrap_near(np.angle(self.response), self.linear_phase[None, :]))

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
        per amplitude (lists), over the points that ran."""
        dg = np.abs(self.gain_db - self.linear_gain_db[None, :])
        dp = np.abs(self.phase_deg - self.linear_phase_deg[None, :])
        with warnings.catch_warnings():  # an amplitude whose every point failed gives NaN
            warnings.simplefilter("ignore", RuntimeWarning)
            return {"max_gain_difference_dB": np.nanmax(dg, axis=1).tolist() if dg.size else [],
                    "max_phase_difference_deg": np.nanmax(dp, axis=1).tolist() if dp.size else []}

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
        lines.append("model: " + ("reduced, left out: " + "; ".join(self.left_out) if self.reduced and self.left_out
                                  else "reduced: nothing left out" if self.reduced else "full model"))
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
                        (f"unsettled ({self.settling_change[a, k]:.1%}) " if self.settling_change[a, k] > 0.01 else "") + \
                        (f"FAILED: {err}" if err else "")
                lines.append(f"{f:9.4g} {g[a, k]:10.3f} {p[a, k]:12.2f} {lg[k]:10.3f} {lp[k]:11.2f} "
                             f"{g[a, k] - lg[k]:8.3f} {p[a, k] - lp[k]:9.2f}  {flags}".rstrip())
        dev = self.deviation()
        lines.append("\nlargest difference from the linear loop: " + ", ".join(
            f"{self.unit.text(a, 3)}: {dg:.3f} dB / {dp:.2f} deg" for a, dg, dp in
            zip(self.amplitudes_rad, dev["max_gain_difference_dB"], dev["max_phase_difference_deg"])))
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


def linear_response(scene, controller, frequencies_hz, structural_damping=DEFAULT_STRUCTURAL_DAMPING):
    """theta/theta_ref of :func:`servo_toolkit.loop.linear_closed_loop` at the design's
    operating point (where the simulation starts) at the frequencies (complex array) and the
    slowest decay rate of its poles (1/s)."""
    import control as ct

    from ..loop import linear_closed_loop
    from ..drivetrain.operating_point import operating_point
    cl = linear_closed_loop(scene, controller, q0=operating_point(scene)[0], structural_damping=structural_damping)
    sub = cl[cl.output_labels.index("theta"), cl.input_labels.index("theta_ref")]
    w = 2 * np.pi * np.asarray(frequencies_hz, dtype=float)
    resp = np.asarray(ct.frequency_response(sub, w).complex).reshape(-1)
    poles = cl.poles()
    decay = float(np.min(-poles.real)) if poles.size else math.inf
    if not decay > 0:
        worst = poles[np.argmax(poles.real)]
        raise SimulationError(
            f"the closed loop of this controller is not stable (its rightmost pole at {worst.real:.4g} "
            f"{worst.imag:+.4g}j 1/s): a physical verdict on the design, not a failure of the run; a sine dwell "
            "has no steady state to measure (servo-toolkit check fails the row closed_loop_stable, "
            "servo-toolkit design says why)")
    return resp, decay


def sweep(scene, study=None, *, frequencies=None, amplitudes=None, controller=None, options=None,
          full: bool = False, plan: DwellPlan | None = None, method: str = "rk4", executor=None,
          progress: bool = True) -> SweepResult:
    """Sine-dwell frequency response of the scene's closed loop.

    Every frequency must be one a dwell resolves (:func:`.sweep_points.check_sweep_frequencies`:
    at most a quarter of the controller's sample rate, and a dwell within one run's step
    budget), else SceneError naming ``frequencies`` (given) or ``studies.NAME.frequencies``.

    Parameters
    ----------
    scene : Scene
    study : str or Study, optional
        A ``frequency_sweep`` study (8 Hz is added to its frequencies); default the scene's
        first one (see :func:`study_points`).
    frequencies : sequence of float, optional
        Hz, replacing the study's.
    amplitudes : sequence of float, optional
        Command amplitudes (rad, or m for an output travel), replacing the study's; one
        curve each.
    controller : CascadeController, optional
        Default: the designed loop (:func:`servo_toolkit.sim.controller_for`).
    options : ModelOptions, optional
        Run exactly these model options (no reduction).
    full : bool
        Run the full model instead of the reduced one.
    plan : DwellPlan, optional
    method : str
        Integration method of :func:`servo_toolkit.sim.run`.
    executor : concurrent.futures.Executor, optional
        Runs the dwells in parallel (see :func:`servo_toolkit.core.parallel.run_cases`).
    progress : bool
        tqdm progress bar.

    Returns
    -------
    SweepResult
    """
    from ..sim import ModelOptions, build_model, controller_for
    from .reduce_estimates import plan_reduction

    start = time.perf_counter()
    name, freqs, amps = study_points(scene, study)
    if frequencies is not None:
        freqs = tuple(float(f) for f in np.atleast_1d(frequencies))
    if amplitudes is not None:
        amps = tuple(float(a) for a in np.atleast_1d(amplitudes))
    if not freqs or not amps or min(freqs) <= 0 or min(amps) <= 0:
        raise ValueError("frequencies and amplitudes must be non-empty and positive")
    freqs_arr = np.asarray(sorted(freqs))
    plan = plan or DwellPlan()
    from .sweep_points import check_sweep_frequencies
    check_sweep_frequencies(scene, freqs_arr, "frequencies" if frequencies is not None
                            else f"studies.{name}.frequencies" if name else "frequency", plan)
    notes = []
    if controller is None:
        controller, source = controller_for(scene)
        notes.append(f"controller from {source}")
    reduced, left_out = False, ()
    if options is None:
        options = ModelOptions(damping_ratio=DEFAULT_STRUCTURAL_DAMPING)
        if not full:
            red = plan_reduction(scene, controller, freqs_arr, amps, base=options)
            options, reduced = red.options, True
            left_out = tuple(f"{o.effect}: {o.reason}" for o in red.omitted)
            notes.append("reduced model (use full=True / --full for the full model)")
    model = build_model(scene, controller, options)
    notes += list(model.notes)
    lin, decay = linear_response(scene, controller, freqs_arr, options.damping_ratio)
    grid = np.unique(np.concatenate([np.geomspace(freqs_arr[0] / 1.5, freqs_arr[-1] * 1.5, 300), freqs_arr]))
    lin_grid, _ = linear_response(scene, controller, grid, options.damping_ratio)
    eta = scene.drivetrain.efficiency
    if eta < 1 and options.efficiency:
        notes.append(f"linear loop: the design's, with the driving-mode efficiency {eta:.3g} on the motor "
                     f"torque; the nonlinear model passes it while the motor drives the load and "
                     f"1/{scene.drivetrain.backdrive_efficiency:.3g} while the load drives the motor")
    limits = (scene.motor.current_limit, scene.motor.voltage_limit)
    cases = [(model, a, f, plan, decay, method, limits) for a in amps for f in freqs_arr]
    out = run_cases(_dwell_case, cases, executor=executor, progress=progress, description="sine dwell")
    shape = (len(amps), freqs_arr.size)

    def col(key, dtype=float):
        return np.array([o[key] for o in out], dtype=dtype).reshape(shape)

    opts = {k: v for k, v in options.__dict__.items()}
    return SweepResult(scene=scene.name, study=name, frequencies_hz=freqs_arr,
                       amplitudes_rad=np.asarray(amps, dtype=float), response=col("response", complex),
                       linear_response=lin, linear_grid_hz=grid, linear_grid_response=lin_grid,
                       settling_change=col("change"), saturated=col("saturated", bool),
                       peak_current_A=col("peak_current_A"), peak_voltage_V=col("peak_voltage_V"),
                       errors=tuple(o["error"] for o in out), reduced=reduced, left_out=left_out,
                       options=opts, plan=plan, decay_rate=decay, controller=model.controller,
                       method=method, wall_s=time.perf_counter() - start, notes=tuple(notes),
                       output_unit=scene.drivetrain.output_unit)


def _card_line(s) -> str:
    """The one-line repr of a result of this module."""
    dev = s.deviation()
    amps = ", ".join(s.unit.text(a, 3) for a in s.amplitudes_rad)
    worst = max(dev["max_gain_difference_dB"] or [math.nan])
    return (f"{s.scene}: {s.frequencies_hz.size} frequencies x {s.amplitudes_rad.size} amplitude(s) ({amps}), "
            f"largest |dG| {num(worst, 3)} dB from the linear loop, {int(s.failed.sum())} failed")


def _card_html(s) -> str:
    """The Jupyter card (HTML) of a result of this module."""
    dev = s.deviation()
    rows = [(s.unit.text(a, 3), f"{num(g, 3)} dB", f"{num(p, 3)} deg", int(s.saturated[i].sum()), int(s.failed[i].sum()))
            for i, (a, g, p) in enumerate(zip(s.amplitudes_rad, dev["max_gain_difference_dB"],
                                              dev["max_phase_difference_deg"]))]
    model = ("full model" if not s.reduced else "reduced: left out " + ("; ".join(s.left_out) or "nothing"))
    parts = [table(("amplitude", "largest |dG|", "largest |dP|", "saturated", "failed"), rows),
             f'<p class="st-note">{model}</p>', svg(s.plot, size=(7.0, 4.6), rows=2, sharex=True)]
    return card(f"Sine-dwell sweep of {s.scene}" + (f", study {s.study}" if s.study else ""), parts=parts,
                notes=s.notes)


__all__ = ["DEFAULT_AMPLITUDE", "DEFAULT_FREQUENCY_HZ", "SweepResult", "linear_response", "study_points", "sweep"]
