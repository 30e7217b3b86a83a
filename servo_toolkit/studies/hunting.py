"""Friction at rest: the stick phases of a run, the position error where it stops, hunting.

With friction that holds (``ModelOptions(friction="stick")``) a position loop stops where the
moment it applies no longer breaks the static friction: without integral action anywhere in
the loop, inside the dead band |e| <= Ts / K (Ts the breakaway level, widened by a lossy
chain's band at rest, :func:`holding_band`; K the loop's stiffness at rest); with integral action and a breakaway level above the Coulomb level, the integral
winds up while the shaft sticks, breaks it away, and the shaft overshoots and sticks on the
other side: a limit cycle (hunting) whose amplitude and period this study measures.

A stick phase is an interval over which the motor speed (and the load's speed, where the
load carries friction) is exactly 0 on consecutive records: the compiled model holds a stuck
node's speed at exactly zero, so stick is read without a threshold. A breakaway is the end of
a stick phase before the end of the run. The run is judged on its second half (the
``window``): hunting when the output breaks away at least twice in the same direction there
(period: the mean interval between same-direction breakaways; amplitude: half the output's
peak-to-peak over the last period) unless the run ends in a stick phase longer than that
period (the stick-slip died out), at rest when it ends in a stick phase.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..core.output_units import OutputUnit, output_unit
from ..display.cards import RichDisplay, card, facts, num, svg
from ..drivetrain.stage_friction import lumped_friction

#: a step-to-rest run is this fraction of the output's default command amplitude (1 deg, 0.5 mm)
STEP_FRACTION = 0.5
#: records a stick phase must span (one exact zero is a reversal, not a stick)
MIN_STICK_RECORDS = 2
#: angular frequency (rad/s) at which the controller's proportional stiffness is read
LOW_FREQUENCY = 1e-3


@dataclass(frozen=True)
class Hunting:
    """A limit cycle against static friction.

    Attributes
    ----------
    amplitude : float
        Half the output's peak-to-peak over the last period (rad, or m for a travel).
    period : float
        Mean interval between breakaways in the same direction (s).
    cycles : int
        Periods seen in the window.
    """

    amplitude: float
    period: float
    cycles: int


@dataclass(frozen=True, repr=False)
class RestResult(RichDisplay):
    """Where a position loop with friction that holds comes to rest, or how it hunts.

    Attributes
    ----------
    times : numpy.ndarray
        Record times (s).
    error : numpy.ndarray
        Command minus output at the records (rad, or m).
    stuck : numpy.ndarray
        True where the run is in a stick phase.
    stick_phases : tuple of (float, float)
        Start and end time (s) of each stick phase.
    position_error_at_rest : float or None
        Command minus output where the run ends at rest; while hunting, the largest |error|
        over the stick phases of the last period (signed as it is there); None when the
        run neither ends at rest nor hunts.
    hunting : Hunting or None
        The limit cycle, or None (the output does not break away twice in the same
        direction within the window).
    window : float
        Start of the judged part of the run (s): its second half.
    output_unit : {"rad", "m"}
    notes : tuple of str
    dead_band : float or None
        Half-width (rad, or m) of the dead band of the loop's proportional path,
        :func:`dead_band`; None when not computed or the loop has no proportional stiffness.
    """

    times: np.ndarray
    error: np.ndarray
    stuck: np.ndarray
    stick_phases: tuple
    position_error_at_rest: float | None
    hunting: Hunting | None
    window: float
    output_unit: str = "rad"
    notes: tuple = ()
    dead_band: float | None = None

    @property
    def unit(self) -> OutputUnit:
        """The output coordinate's units."""
        return OutputUnit(self.output_unit)

    @property
    def at_rest(self) -> bool:
        """True when the run ends in a stick phase and does not hunt."""
        return self.hunting is None and bool(self.stuck[-1])

    def to_dict(self) -> dict:
        """JSON-ready summary (errors and amplitudes in the shown unit, deg or mm)."""
        u = self.unit
        rest = self.position_error_at_rest
        hunt = self.hunting
        return {u.key("position_error_at_rest"): None if rest is None else float(u.show(rest)),
                "hunting": None if hunt is None else {u.key("amplitude"): float(u.show(hunt.amplitude)),
                                                      "period_s": hunt.period, "cycles": hunt.cycles},
                "at_rest": self.at_rest, "stick_phases_s": [list(p) for p in self.stick_phases],
                u.key("dead_band"): None if self.dead_band is None else float(u.show(self.dead_band)),
                "stuck_fraction": float(self.stuck.mean()), "window_s": self.window, "notes": list(self.notes)}

    def plot(self, ax=None):
        """The error against time with the stick phases shaded; returns the axes."""
        if ax is None:
            import matplotlib.pyplot as plt
            _, ax = plt.subplots(figsize=(7.0, 3.2))
        u = self.unit
        ax.plot(self.times, u.show(self.error), lw=1.0, label="command - output")
        shade_stick_phases(ax, self.stick_phases)
        if self.dead_band is not None:
            show_dead_band(ax, 0.0, float(u.show(self.dead_band)))
        ax.set(xlabel="time [s]", ylabel=f"error [{u.shown}]")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize="small")
        return ax

    def _repr_line(self) -> str:
        return summary_line(self)

    def _repr_card(self) -> str:
        u = self.unit
        rest = self.position_error_at_rest
        rows = [("position error at rest", "moving at the end" if rest is None else f"{num(u.show(rest))} {u.shown}"),
                ("hunting", hunting_text(self.hunting, u)), ("stick phases", str(len(self.stick_phases))),
                ("dead band", "none" if self.dead_band is None else f"+-{num(u.show(self.dead_band))} {u.shown}"),
                ("time stuck", f"{self.stuck.mean():.0%}")]
        return card("Friction at rest", parts=[facts(rows), svg(self.plot, size=(7.0, 3.2))], notes=self.notes)


def hunting_text(hunting, u: OutputUnit) -> str:
    """``"none"`` or the amplitude and period of a limit cycle, in words."""
    if hunting is None:
        return "none"
    seen = f"{hunting.cycles} cycle{'s' if hunting.cycles != 1 else ''} seen"
    return f"amplitude {num(u.show(hunting.amplitude))} {u.shown}, period {num(hunting.period * 1e3)} ms ({seen})"


def summary_line(r: RestResult) -> str:
    """One line: the error at rest and the hunting."""
    u = r.unit
    rest = r.position_error_at_rest
    at = "moving at the end" if rest is None else f"error at rest {num(u.show(rest))} {u.shown}"
    return f"{at}; hunting {hunting_text(r.hunting, u)}; {len(r.stick_phases)} stick phases"


def shade_stick_phases(ax, phases, scale: float = 1.0, label: str = "stuck (speed exactly 0)"):
    """Shade the stick phases (times x ``scale``) on a time axis."""
    for k, (a, b) in enumerate(phases):
        ax.axvspan(a * scale, b * scale, color="0.85", lw=0, zorder=0, label=label if k == 0 else None)


def show_dead_band(ax, centre: float, half_width: float, label: str = "dead band (proportional path)"):
    """Draw a dead band ``centre +- half_width`` across a time axis."""
    ax.axhspan(centre - half_width, centre + half_width, color="C2", alpha=0.15, lw=0, label=label)


def holding_band(scene, q0: float, efficiency: bool = True) -> float:
    """Half the width of the band of motor torques (N*m at the motor shaft) that hold the
    drive at rest at the output angle q0, with friction that holds.

    A node at rest holds while the motor torque tau stays within the breakaway levels: with the
    lossless chain taken as rigid, Ts + Ts_L / N either side of the torque the load needs. A
    lossy chain at rest holds more (:func:`~servo_toolkit.sim.kernel.gear_at_rest`):
    with M = -(M_h + k q0) the load's moment at the output, eta and eta_b the chain's
    efficiencies (eta_b <= 0: self-locking, taken as 0) and g(m) = eta_b m where the load
    drives the gear, m / eta where it is driven,

        tau_hi = Ts - g(M - Ts_L) / N,    tau_lo = -Ts - g(M + Ts_L) / N,

    and the band's half width is (tau_hi - tau_lo) / 2: Ts + Ts_L / N without losses, plus
    about (1/eta - eta_b) |M| / (2 N) with them (``efficiency=False``: without).
    """
    n = abs(float(scene.drivetrain.ratio([q0])[0][0]))
    motor, load = lumped_friction(scene, q0, True, [])  # a stage's friction reflected to the motor
    ts, ts_l = motor.breakaway_torque, load.breakaway
    eta, eta_b = 1.0, 1.0
    if efficiency:
        eta, eta_b = scene.drivetrain.efficiency, max(scene.drivetrain.backdrive_efficiency, 0.0)
    moment = -(load.hinge_moment + load.hinge_stiffness * q0)

    def forward(m):  # the far side's moment seen at the gear's input, moving forward
        return eta_b * m if m > 0 else m / eta

    def backward(m):
        return eta_b * m if m < 0 else m / eta
    hi = ts - forward(moment - ts_l) / n
    lo = -ts - backward(moment + ts_l) / n
    return 0.5 * (hi - lo)


def dead_band(scene, controller, q0: float | None = None, efficiency: bool = True) -> float | None:
    """Half-width of the dead band of a loop's proportional path at the output (rad, or m).

    A node at rest sticks while the moment on it stays within its breakaway level; the loop's
    moment per unit of position error, before any integral action winds up, is its
    proportional stiffness Kt Kp with Kp the real part of the motion controller's response
    from the output angle to the current command at a low frequency (an integrator adds a
    purely imaginary part there). With the motor's breakaway Ts (a stage's reflected to the
    motor added) and the load's Ts_L reflected to the motor (the chain at rest taken as rigid),

        |e| <= (Ts + Ts_L / N) / (Kt Kp)

    for a lossless chain; a lossy one at rest holds more, within the half-width of
    :func:`holding_band` in place of Ts + Ts_L / N (``efficiency=False``: without the loss).

    Parameters
    ----------
    scene : Scene
    controller : CascadeController
    q0 : float, optional
        Operating point (default the design's).

    Returns
    -------
    float or None
        None when the controller has no proportional stiffness (Kp <= 0).
    """
    import control as ct

    from ..drivetrain.operating_point import operating_point
    q0 = operating_point(scene)[0] if q0 is None else q0
    motion = controller.motion
    path = motion[0, list(motion.input_labels).index("theta")]
    gain = -complex(np.asarray(ct.frequency_response(path, [LOW_FREQUENCY]).complex).ravel()[0]).real
    if not gain > 0:
        return None
    return holding_band(scene, q0, efficiency) / (scene.motor.torque_constant * gain)


def stick_mask(result, load_friction: bool = False) -> np.ndarray:
    """True where a run's motor speed (and, with ``load_friction``, the load's speed) is
    exactly 0, on at least :data:`MIN_STICK_RECORDS` consecutive records."""
    stuck = np.asarray(result.motor_speed) == 0.0
    if load_friction and "output_rate_rad_s" in result.state_names:
        stuck |= result.trace("output_rate_rad_s") == 0.0
    runs = _runs(stuck)
    keep = np.zeros_like(stuck)
    for a, b in runs:
        if b - a >= MIN_STICK_RECORDS:
            keep[a:b] = True
    return keep


def _runs(mask):
    """(start, stop) index pairs of the runs of True in ``mask``."""
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)))


def analyse(result, load_friction: bool = False, window: float | None = None) -> RestResult:
    """Stick phases, position error at rest and hunting of a closed-loop run.

    Parameters
    ----------
    result : SimulationResult
        A closed-loop run with friction that holds.
    load_friction : bool
        The load carries friction: its exact zero speed counts as stuck too.
    window : float, optional
        Start (s) of the judged part; default the second half of the run.

    Returns
    -------
    RestResult
    """
    t = np.asarray(result.times)
    err = np.asarray(result.reference_angle) - np.asarray(result.output_angle)
    stuck = stick_mask(result, load_friction)
    runs = _runs(stuck)
    phases = tuple((float(t[a]), float(t[b - 1])) for a, b in runs)
    start = 0.5 * (t[0] + t[-1]) if window is None else float(window)
    # breakaways inside the window, with the direction the output leaves in
    breaks = [(b, math.copysign(1.0, err[b - 1] - err[min(b + 1, t.size - 1)]))
              for _, b in runs if b < t.size and t[b - 1] >= start]
    hunting, rest = None, None
    cycles = {}
    for idx, direction in breaks:
        cycles.setdefault(direction, []).append(idx)
    same = max(cycles.values(), key=len) if cycles else []
    period = float(np.mean(np.diff(t[same]))) if len(same) >= 2 else math.nan
    if stuck[-1] and runs and t[-1] - t[runs[-1][0]] > period:
        same = []  # stuck for longer than a period at the end: the stick-slip died out, at rest
    if len(same) >= 2:
        a, b = same[-2], same[-1]
        amp = 0.5 * float(np.ptp(result.output_angle[a:b + 1]))
        hunting = Hunting(amplitude=amp, period=period, cycles=len(same) - 1)
        last = [(i, j) for i, j in runs if i >= a and j <= b + 1]
        if last:
            worst = max((err[i] for i, _ in last), key=abs)
            rest = float(worst)
    elif stuck[-1]:
        rest = float(err[-1])
    notes = (f"judged from {start:.4g} s to {t[-1]:.4g} s (the second half of the run)"
             if window is None else f"judged from {start:.4g} s to {t[-1]:.4g} s",)
    return RestResult(times=t, error=err, stuck=stuck, stick_phases=phases, position_error_at_rest=rest,
                      hunting=hunting, window=start, output_unit=result.output_unit, notes=notes)


def load_holds(scene) -> bool:
    """True when the load carries static friction of its own (a stage's beyond the two-mass
    split joins it): its exact zero speed counts as stuck too."""
    from ..drivetrain.operating_point import operating_point
    load = lumped_friction(scene, operating_point(scene)[0], False, [])[1] if scene.stage_friction else scene.load
    return load.breakaway > 0


def rest_study(scene, controller=None, *, step: float | None = None, duration: float = 1.0,
               method: str = "rk4", dt: float | None = None, options=None) -> RestResult:
    """A step of the position loop run to rest with friction that holds.

    Parameters
    ----------
    scene : Scene
    controller : CascadeController, optional
        Default: the designed controller (:func:`servo_toolkit.sim.controller_for`).
    step : float, optional
        Step size (rad, or m for an output travel); default :data:`STEP_FRACTION` of the
        output's default command amplitude.
    duration : float
        Seconds; the second half is judged.
    method : {"rk4", "reference", "auto"}
    dt : float, optional
        Fixed step of RK4 (s).
    options : ModelOptions, optional
        Its ``friction`` is set to ``"stick"``.

    Returns
    -------
    RestResult
        Its notes say which run it judged.
    """
    from ..sim import ModelOptions, Reference, controller_for, simulate
    if controller is None:
        controller, _ = controller_for(scene)
    options = replace(options or ModelOptions(), friction="stick")
    u = output_unit(scene)
    size = STEP_FRACTION * u.default_amplitude if step is None else float(step)
    run = simulate(scene, controller, reference=Reference.step(size), duration=duration, method=method, dt=dt,
                   options=options)
    res = analyse(run, load_friction=load_holds(scene))
    ts = scene.motor.breakaway_torque
    head = (f"{u.text(size, 3)} step, {duration:g} s, {run.method}"
            + (f" at {run.dt_s:.3g} s" if run.dt_s else "")
            + f"; friction that holds (motor breakaway {ts:.4g} N*m, Coulomb {scene.motor.coulomb_friction:.4g} N*m)")
    return replace(res, notes=(head, *res.notes, *run.notes), dead_band=dead_band(scene, controller, efficiency=options.efficiency))


__all__ = ["Hunting", "LOW_FREQUENCY", "load_holds", "MIN_STICK_RECORDS", "RestResult", "STEP_FRACTION", "analyse", "dead_band",
           "holding_band", "hunting_text", "rest_study", "shade_stick_phases", "show_dead_band", "stick_mask", "summary_line"]
