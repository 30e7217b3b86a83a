"""Large-signal rows of the gate: the compiled nonlinear closed loop (voltage and current
limits, friction, backlash, the sampled controller) driven by the scene's requirement sine,
against the linear loop the margins describe.

A linear check cannot see saturation: a 3 V supply leaves every margin of the reference EMA
intact while the 2 deg, 8 Hz command pins the voltage and the output lags by tens of
degrees. The run is the actuator's requirement sine (:mod:`servo_toolkit.studies.actuator`:
the command of :func:`~servo_toolkit.studies.actuator.spec.plan`, at the required bandwidth,
8 Hz when the scene sets none, through the full model with friction that holds), the same
for ``design`` and ``check`` (which judges it once for these rows and its
``tracking_error``), for :data:`CYCLES` cycles; the fundamental of the last
:data:`FIT_CYCLES` is compared with the linear closed loop at that frequency. Rows:
``large_signal_gain`` (|gain difference| at most :data:`GAIN_TOLERANCE_DB`) and
``large_signal_phase`` (|phase difference| at most :data:`PHASE_TOLERANCE_DEG`); the time at the voltage and current limits (within 1 % of
each, :func:`~.actuator.figures.time_at_limit`) is reported beside them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ...display.cards import RichDisplay, card, facts, num, svg
from ...loop.requirements import Check
from ..actuator.figures import time_at_limit
from ..actuator.runs import JUDGED_CYCLES, SINE_CYCLES

GAIN_TOLERANCE_DB = 1.0
PHASE_TOLERANCE_DEG = 10.0
#: the requirement sine's periods and the last ones fitted: the actuator's sine run
#: (:mod:`.actuator.runs`), which the gate judges here too
CYCLES, FIT_CYCLES = SINE_CYCLES, JUDGED_CYCLES


@dataclass(frozen=True, repr=False)
class LargeSignal(RichDisplay):
    """The nonlinear closed loop on the requirement sine against the linear loop.

    Attributes
    ----------
    frequency_hz, amplitude : float
        The command (amplitude in the output's SI unit, rad or m).
    gain_db, phase_deg : float
        Fundamental of the nonlinear output over the command.
    linear_gain_db, linear_phase_deg : float
        The linear closed loop at the same frequency.
    time_at_voltage_limit_s, time_at_current_limit_s, duration_s : float
    peak_current_A, peak_voltage_V : float
    failure : str
        "" for a run that went through; else why the run ended early: the output left the
        stroke (a physical outcome that fails the ``large_signal_within_stroke`` row). A run
        that cannot be carried out numerically raises instead: no verdict on a figure it did
        not produce.
    stroke_end_s : float
        When the output left the stroke (NaN when it stayed within).
    """

    frequency_hz: float
    amplitude: float
    gain_db: float
    phase_deg: float
    linear_gain_db: float
    linear_phase_deg: float
    time_at_voltage_limit_s: float
    time_at_current_limit_s: float
    duration_s: float
    peak_current_A: float
    peak_voltage_V: float
    failure: str = ""
    stroke_end_s: float = math.nan

    @property
    def gain_error_db(self) -> float:
        return abs(self.gain_db - self.linear_gain_db)

    @property
    def phase_error_deg(self) -> float:
        d = (self.phase_deg - self.linear_phase_deg + 180.0) % 360.0 - 180.0
        return abs(d)

    def checks(self) -> list:
        """The ``large_signal_gain`` and ``large_signal_phase`` rows, or, for a run whose
        output left the stroke, the failing ``large_signal_within_stroke`` row (seconds the
        output stayed within the stroke against the run's duration)."""
        if self.failure:
            return [Check("large_signal_within_stroke", self.duration_s, self.stroke_end_s, False, "s", ">=",
                          "large signal", float(self.duration_s - self.stroke_end_s))]
        out = []
        for name, value, tol, unit in (("large_signal_gain", self.gain_error_db, GAIN_TOLERANCE_DB, "dB"),
                                       ("large_signal_phase", self.phase_error_deg, PHASE_TOLERANCE_DEG, "deg")):
            if math.isnan(value):
                from ...errors import SimulationError
                raise SimulationError(f"{name}: the large-signal figure is NaN, no verdict can be given on it")
            ok = bool(value <= tol)  # an output that never moved: -inf dB, a real (failing) figure
            out.append(Check(name, tol, float(value), ok, unit, "<=", "large signal",
                             0.0 if ok else float(value - tol)))
        return out

    def note(self, linear_output: bool) -> str:
        """One line: the command, both responses, and the time at the limits."""
        amp = f"{self.amplitude * 1e3:.3g} mm" if linear_output else f"{math.degrees(self.amplitude):.3g} deg"
        if self.failure:
            return (f"large signal: the {amp} sine at {self.frequency_hz:g} Hz through the nonlinear closed loop "
                    f"failed: {self.failure}")
        return (f"large signal: {amp} sine at {self.frequency_hz:g} Hz through the nonlinear closed loop (full "
                f"model, friction that holds): "
                f"{self.gain_db:+.2f} dB / {self.phase_deg:.1f} deg against the linear {self.linear_gain_db:+.2f} dB / "
                f"{self.linear_phase_deg:.1f} deg; {self.limits_text()}; "
                f"peak {self.peak_current_A:.3g} A, {self.peak_voltage_V:.3g} V")

    def limits_text(self) -> str:
        """How long the run spent at the drive's voltage and current limits, in words."""
        run = f"the {self.duration_s * 1e3:.4g} ms run"
        volt, amp = self.time_at_voltage_limit_s * 1e3, self.time_at_current_limit_s * 1e3
        if volt <= 0 and amp <= 0:
            return f"the drive reached neither its voltage nor its current limit in {run}"
        return f"the drive spent {volt:.4g} ms at its voltage limit and {amp:.4g} ms at its current limit in {run}"

    @property
    def passed(self) -> bool:
        """Both rows met: the gain and the phase within their tolerances of the linear loop's
        (False for a run that left the stroke)."""
        return (not self.failure and bool(self.gain_error_db <= GAIN_TOLERANCE_DB)
                and bool(self.phase_error_deg <= PHASE_TOLERANCE_DEG))

    def to_dict(self) -> dict:
        """JSON-ready, units in the key names."""
        d = dict(self.__dict__)
        d["gain_error_db"], d["phase_error_deg"] = self.gain_error_db, self.phase_error_deg
        return d

    def plot(self, ax=None):
        """The linear and the nonlinear closed loop at the sine's frequency in the gain-phase
        plane, with the box of the tolerances about the linear one (the rows are met when the
        nonlinear point lies in it); the nonlinear phase is shown within 180 deg of the linear."""
        from matplotlib.patches import Rectangle
        if ax is None:
            import matplotlib.pyplot as plt
            _, ax = plt.subplots(figsize=(5.0, 4.0))
        lin_ph, lin_g = self.linear_phase_deg, self.linear_gain_db
        ax.add_patch(Rectangle((lin_ph - PHASE_TOLERANCE_DEG, lin_g - GAIN_TOLERANCE_DB), 2 * PHASE_TOLERANCE_DEG,
                               2 * GAIN_TOLERANCE_DB, color="C2", alpha=0.15,
                               label=f"within {GAIN_TOLERANCE_DB:g} dB and {PHASE_TOLERANCE_DEG:g} deg"))
        ax.plot([lin_ph], [lin_g], "o", color="C0", label="linear closed loop")
        if math.isfinite(self.gain_db) and math.isfinite(self.phase_deg):
            phase = lin_ph + (self.phase_deg - lin_ph + 180.0) % 360.0 - 180.0
            ax.plot([phase], [self.gain_db], "x", ms=9, color="C3", label="nonlinear closed loop")
        ax.autoscale_view()
        ax.set_xlabel("phase [deg]")
        ax.set_ylabel("gain [dB]")
        ax.set_title(f"Requirement sine at {self.frequency_hz:g} Hz" + (": left the stroke" if self.failure else ""))
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize="small")
        return ax

    def _repr_line(self) -> str:
        if self.failure:
            return f"{self.frequency_hz:g} Hz requirement sine: left the stroke at {num(self.stroke_end_s, 3)} s"
        return (f"{self.frequency_hz:g} Hz requirement sine: |dG| {num(self.gain_error_db, 3)} dB "
                f"(at most {GAIN_TOLERANCE_DB:g}), |dP| {num(self.phase_error_deg, 3)} deg "
                f"(at most {PHASE_TOLERANCE_DEG:g}), {'met' if self.passed else 'NOT met'}")

    def _repr_card(self) -> str:
        ms = f" of {num(self.duration_s * 1e3, 4)} ms"
        rows = [("command", f"requirement sine at {self.frequency_hz:g} Hz"),
                ("nonlinear closed loop", f"{num(self.gain_db, 3)} dB, {num(self.phase_deg, 3)} deg"),
                ("linear closed loop", f"{num(self.linear_gain_db, 3)} dB, {num(self.linear_phase_deg, 3)} deg"),
                ("gain difference", f"{num(self.gain_error_db, 3)} dB (at most {GAIN_TOLERANCE_DB:g} dB)"),
                ("phase difference", f"{num(self.phase_error_deg, 3)} deg (at most {PHASE_TOLERANCE_DEG:g} deg)"),
                ("at the voltage limit", f"{num(self.time_at_voltage_limit_s * 1e3, 4)} ms{ms}"),
                ("at the current limit", f"{num(self.time_at_current_limit_s * 1e3, 4)} ms{ms}"),
                ("peak current, voltage", f"{num(self.peak_current_A, 3)} A, {num(self.peak_voltage_V, 3)} V")]
        return card("Large-signal check", status=self.passed, parts=[facts(rows), svg(self.plot, size=(5.0, 4.0))],
                    notes=(f"the run left the stroke: {self.failure}",) if self.failure else ())


def fit_sine(t, y, f):
    """Amplitude and phase (deg) of the component of ``y`` at ``f`` (least squares with an offset)."""
    w = 2 * np.pi * f
    a = np.column_stack([np.sin(w * t), np.cos(w * t), np.ones_like(t)])
    (s, c, _), *_ = np.linalg.lstsq(a, y, rcond=None)
    return math.hypot(s, c), math.degrees(math.atan2(c, s))


def large_signal(scene, result, actuator=None) -> LargeSignal:
    """Run the requirement sine through the nonlinear closed loop of ``result``'s controller.

    Parameters
    ----------
    scene : Scene
    result : DesignResult
    actuator : ActuatorCheck, optional
        The actuator's nonlinear runs (:mod:`.actuator`): its requirement sine is the run
        judged, not run again. Without it the same sine is run alone (the command of
        :func:`servo_toolkit.studies.actuator.spec.plan`, the full model with friction that
        holds), so the rows do not depend on whether the step was run too.

    Raises
    ------
    SimulationError
        The run could not be carried out (its step outside the RK4 stability region, a step
        budget spent, a non-finite state, the stroke end): the rows would have no figure.
    """
    from ...core.output_units import output_unit
    from ...errors import SimulationError, StrokeEndReached
    from ..actuator.runs import sine_run
    from ..actuator.spec import plan as make_plan
    unit = output_unit(scene)
    plan = actuator.plan if actuator is not None else make_plan(scene, result)
    f, amp = plan.frequency, plan.sine_amplitude
    duration = CYCLES / f
    lin = complex(result.block("closed_loop")(2j * np.pi * f))
    lin_db, lin_deg = 20 * math.log10(abs(lin)), math.degrees(np.angle(lin))
    try:
        run = actuator.sine_run if actuator is not None else None
        if actuator is not None and run is None:  # its sine left the stroke
            raise StrokeEndReached(actuator.failure, actuator.stroke_end_s)
        run = run or sine_run(scene, result.controller, plan)
    except StrokeEndReached as exc:  # the actuator ran into its end stop: a failed requirement, not bad input
        return LargeSignal(frequency_hz=float(f), amplitude=amp, gain_db=math.nan, phase_deg=math.nan,
                           linear_gain_db=lin_db, linear_phase_deg=lin_deg, time_at_voltage_limit_s=math.nan,
                           time_at_current_limit_s=math.nan, duration_s=float(duration), peak_current_A=math.nan,
                           peak_voltage_V=math.nan, failure=str(exc), stroke_end_s=exc.time_s)
    except SimulationError as exc:  # no figure to judge: no verdict (exit 2), never a row failed on NaN
        what = unit.text(amp, 3)
        raise SimulationError(f"the large-signal run ({what} sine at {f:g} Hz, nonlinear closed loop) could not "
                              f"be carried out: {exc} (--linear-only skips it)") from None
    t, y = run.times, run.output_angle - result.q0
    last = t >= (CYCLES - FIT_CYCLES) / f
    a, ph = fit_sine(t[last], y[last], f)
    motor = scene.motor
    v, i = np.abs(run.motor_voltage), np.abs(run.motor_current)
    with np.errstate(divide="ignore"):
        gain = 20 * math.log10(a / amp) if a > 0 else -math.inf
    return LargeSignal(frequency_hz=float(f), amplitude=amp, gain_db=gain, phase_deg=ph,
                       linear_gain_db=lin_db, linear_phase_deg=lin_deg,
                       time_at_voltage_limit_s=time_at_limit(t, v, motor.voltage_limit),
                       time_at_current_limit_s=time_at_limit(t, i, motor.current_limit),
                       duration_s=float(duration), peak_current_A=float(i.max()), peak_voltage_V=float(v.max()))


def with_large_signal(scene, result, actuator=None):
    """``result`` with the large-signal rows and note added (a DesignResult); an unstable
    linear closed loop (already failed by ``closed_loop_stable``) gets a note and no rows:
    its nonlinear run would diverge, with no figure to judge. With ``actuator`` (an
    ActuatorCheck) its requirement sine is the run judged."""
    if not result.margins.closed_loop_stable:
        return replace(result, notes=tuple(result.notes) + (
            "large signal: not run, the linear closed loop is unstable (closed_loop_stable fails)",)), None
    ls = large_signal(scene, result, actuator)
    return replace(result, requirements=list(result.requirements) + ls.checks(),
                   notes=tuple(result.notes) + (ls.note(scene.drivetrain.output_unit == "m"),)), ls
