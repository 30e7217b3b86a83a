"""The result of a time simulation: traces, peaks, what ran, and how it was chosen."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import SceneError
from ..core.files import atomic_file, check_named, check_output_file
from ..core.output_units import OutputUnit
from ..display.cards import RichDisplay
from ..display.legends import legend_above
from ..display.cards import card, facts, num, svg


#: the output-referred traces (the motor side and the output as coordinates at the output,
#: the play, the command) of an output travel: they hold m and m/s, not rad
_TRAVEL_NAMES = {"motor_side_angle_rad": "motor_side_travel_m", "motor_side_rate_rad_s": "motor_side_rate_m_s",
                 "output_angle_rad": "output_travel_m", "output_rate_rad_s": "output_rate_m_s",
                 "play_state_rad": "play_state_m", "reference_angle_rad": "reference_travel_m"}


def shown_name(name: str, output_unit: str = "rad") -> str:
    """A trace's name with the unit it holds, as written to a file or shown.

    The simulation names its states for an output angle (``output_angle_rad``); for an
    output travel (``output_unit`` ``"m"``) the output-referred traces hold metres and are
    named so (``output_travel_m``, ``reference_travel_m``, ``output_rate_m_s``...). The
    chain's intermediate nodes get their unit too (``node[1]_position_rad`` or ``_m``,
    ``node[1]_rate_rad_s`` or ``_m_s``). Other names (motor current, speed estimator,
    already in motor units) are unchanged.
    """
    travel = output_unit == "m"
    if name.startswith("node[") and name.endswith("_position"):
        return name + ("_m" if travel else "_rad")
    if name.startswith("node[") and name.endswith("_rate"):
        return name + ("_m_s" if travel else "_rad_s")
    return _TRAVEL_NAMES.get(name, name) if travel else name


@dataclass(frozen=True, repr=False)
class SimulationResult(RichDisplay):
    """Recorded traces of one run.

    Attributes
    ----------
    times : numpy.ndarray
        Record times (s).
    states : numpy.ndarray
        (n, nx) state records; columns named by ``state_names``.
    state_names : tuple of str
        The simulation's names of the states (:meth:`trace` takes them, and the names
        written to files, :func:`shown_name`, which carry the unit each trace holds).
    reference_angle : numpy.ndarray
        Commanded output coordinate (rad, or m for an output travel) at the record times
        (open loop: the start position).
    motor_speed : numpy.ndarray
        omega_m (rad/s).
    motor_current, motor_voltage, current_reference, motor_torque : numpy.ndarray
        A, V, A, N*m (electromagnetic torque Kt i).
    max_abs_motor_torque : float
        Peak |Kt i| over every integration step (RK4) or every record (reference).
    wall_s : float
        Wall time of the integration (s).
    method : str
        What ran: ``"rk4"``, ``"paper"`` or ``"reference:LSODA"`` / ``"reference:Radau"``.
    dt_s : float or None
        Fixed step (None for the adaptive reference).
    steps : int
        Fixed steps taken (0 for the reference).
    requested : str
        The method asked for (``"auto"`` when chosen automatically).
    choice : str
        Why this method and step were used.
    stability : dict
        Fastest eigenvalue along the run and the RK4 step limit.
    reference : dict
        The command signal.
    controller : str
    notes : tuple of str
    output_unit : {"rad", "m"}
        Unit of the output coordinate (an angle, or a travel for a chain ending in a
        screw); tracking errors and plots are shown in deg or mm after it.
    peaks : dict
        Peaks over every integration step of a closed-loop RK4 run (``max_abs_current_A``,
        ``max_abs_tracking_error`` in rad or m), the same figures a Monte Carlo variant
        keeps; empty where they come from the records (the reference solver, the paper's
        scheme, open loop).
    """

    times: np.ndarray
    states: np.ndarray
    state_names: tuple
    reference_angle: np.ndarray
    motor_speed: np.ndarray
    motor_current: np.ndarray
    motor_voltage: np.ndarray
    current_reference: np.ndarray
    motor_torque: np.ndarray
    max_abs_motor_torque: float
    wall_s: float
    method: str
    dt_s: float | None
    steps: int = 0
    requested: str = ""
    choice: str = ""
    stability: dict = field(default_factory=dict)
    reference: dict = field(default_factory=dict)
    controller: str = ""
    notes: tuple = ()
    output_unit: str = "rad"
    peaks: dict = field(default_factory=dict)

    @property
    def unit(self) -> OutputUnit:
        """The output coordinate's units (deg or mm shown)."""
        return OutputUnit(self.output_unit)

    def trace(self, name: str) -> np.ndarray:
        """One state trace by its simulation name (``output_angle_rad``) or by the name it
        is written under (``output_travel_m`` for an output travel)."""
        if name not in self.state_names:
            shown = [shown_name(n, self.output_unit) for n in self.state_names]
            if name in shown:
                name = self.state_names[shown.index(name)]
        return self.states[:, self.state_names.index(name)]

    @property
    def shown_names(self) -> tuple:
        """The states' names as written and shown, with the unit each holds (:func:`shown_name`)."""
        return tuple(shown_name(n, self.output_unit) for n in self.state_names)

    @property
    def output_angle(self) -> np.ndarray:
        """Load-side output coordinate q (rad, or m for an output travel)."""
        return self.trace("output_angle_rad")

    @property
    def start_transient_s(self) -> float:
        """End of the start's transient (s): a sine starts at full speed from rest, so its first
        two periods are left out of :attr:`settled_tracking_error`; 0 for other commands."""
        ref = self.reference or {}
        f = ref.get("frequency_Hz") or 0.0
        if ref.get("kind") != "sine" or not f > 0:
            return 0.0
        end = float(ref.get("t0_s") or 0.0) + 2.0 / f
        return end if end < self.t_final else 0.0

    @property
    def settled_tracking_error(self) -> float:
        """Peak |q - r| after the start's transient (:attr:`start_transient_s`; rad, or m)."""
        keep = self.times > self.start_transient_s
        return float(np.max(np.abs(self.output_angle - self.reference_angle)[keep]))

    @property
    def final_state(self) -> dict:
        """Last state by the name it is shown under (with its unit, :func:`shown_name`)."""
        return {n: float(v) for n, v in zip(self.shown_names, self.states[-1])}

    @property
    def t_final(self) -> float:
        """Time of the last record (s)."""
        return float(self.times[-1])

    def columns(self) -> dict:
        """Every trace by column name (for CSV/NPZ); each name carries the unit its trace
        holds (:func:`shown_name`: ``output_travel_m`` and ``reference_travel_m`` for an
        output travel)."""
        cols = {"t_s": self.times}
        cols.update({n: self.states[:, j] for j, n in enumerate(self.shown_names)})
        cols.update({shown_name("reference_angle_rad", self.output_unit): self.reference_angle,
                     "motor_speed_rad_s": self.motor_speed,
                     "motor_current_A": self.motor_current, "motor_voltage_V": self.motor_voltage,
                     "current_reference_A": self.current_reference, "motor_torque_Nm": self.motor_torque})
        return cols

    def to_dict(self) -> dict:
        """JSON-ready summary (no traces)."""
        err = self.peaks.get("max_abs_tracking_error",
                             float(np.max(np.abs(self.output_angle - self.reference_angle))))
        return {
            "t_final_s": self.t_final,
            "final_state": self.final_state,
            "max_abs_motor_torque_Nm": float(self.max_abs_motor_torque),
            "max_abs_current_A": float(self.peaks.get("max_abs_current_A", np.max(np.abs(self.motor_current)))),
            "max_abs_voltage_V": float(np.max(np.abs(self.motor_voltage))),
            self.unit.key("max_abs_tracking_error"): float(self.unit.show(err)),
            self.unit.key("max_abs_tracking_error_after_start"): float(self.unit.show(self.settled_tracking_error)),
            "start_transient_s": self.start_transient_s,
            "wall_s": float(self.wall_s),
            "method": self.method,
            "requested_method": self.requested,
            "dt_s": self.dt_s,
            "steps": int(self.steps),
            "choice": self.choice,
            "stability": self.stability,
            "reference": self.reference,
            "controller": self.controller,
            "notes": list(self.notes),
        }

    def table(self) -> str:
        """Short text summary."""
        d = self.to_dict()
        dt = "adaptive" if self.dt_s is None else f"{self.dt_s:.4g} s"
        lines = [f"method {self.method} (asked {self.requested}), step {dt}, {self.steps} steps, "
                 f"wall {self.wall_s * 1e3:.1f} ms",
                 f"  choice: {self.choice}",
                 f"  controller: {self.controller}",
                 f"  t_final {d['t_final_s']:.4g} s, peak motor torque {d['max_abs_motor_torque_Nm']:.4g} N*m, "
                 f"peak current {d['max_abs_current_A']:.4g} A, peak |error| "
                 f"{d[self.unit.key('max_abs_tracking_error')]:.4g} {self.unit.shown}"
                 + (f" ({d[self.unit.key('max_abs_tracking_error_after_start')]:.4g} {self.unit.shown} after the "
                    f"start's transient, t > {self.start_transient_s:.3g} s)" if self.start_transient_s else "")]
        if self.stability:
            lam = self.stability.get("max_abs_lambda", math.nan)
            lines.append(f"  fastest eigenvalue over the run (the start and the states checked along it) "
                         f"|lambda| = {lam:.4g} 1/s at t = {self.stability.get('t_s', 0.0):.4g} s, RK4 step limit "
                         f"{self.stability.get('dt_limit_s', math.nan):.4g} s")
        lines.append("  final state: " + ", ".join(f"{k} = {v:.6g}" for k, v in d["final_state"].items()))
        lines += [f"  note: {n}" for n in self.notes]
        return "\n".join(lines)

    def save(self, path, inputs=(), key: str = "--output") -> Path:
        """Write the traces as CSV (``.csv``) or NumPy archive (``.npz``), atomically (see
        :mod:`servo_toolkit.core.files`; never over one of ``inputs``)."""
        path = check_trace_path(path, key, inputs)
        cols = self.columns()
        with atomic_file(path, key) as tmp:
            if path.suffix == ".npz":
                np.savez(tmp, **cols)
            else:
                data = np.column_stack(list(cols.values()))
                np.savetxt(tmp, data, delimiter=",", header=",".join(cols), comments="", fmt="%.10g")
        return path

    def plot(self, axes=None):
        """Output vs reference (deg or mm), current, voltage (three stacked axes)."""
        import matplotlib.pyplot as plt
        if axes is None:
            _, axes = plt.subplots(3, 1, sharex=True, figsize=(7, 6), layout="constrained")
        a0, a1, a2 = axes
        u = self.unit
        a0.plot(self.times, u.show(self.reference_angle), "k--", lw=1, label="reference")
        a0.plot(self.times, u.show(self.output_angle), label=f"output ({self.method})")
        a0.set_ylabel(f"{'travel' if u.linear else 'angle'} [{u.shown}]")
        legend_above(a0)  # a sine fills every corner of the axes
        a1.plot(self.times, self.current_reference, "--", color="0.45", lw=1, label="i_ref")
        a1.plot(self.times, self.motor_current, color="C1", label="i")
        a1.set_ylabel("current [A]")
        legend_above(a1)
        a2.plot(self.times, self.motor_voltage)
        a2.set_ylabel("voltage [V]")
        a2.set_xlabel("time [s]")
        return axes

    def _repr_line(self) -> str:
        return _card_line(self)

    def _repr_card(self) -> str:
        return _card_html(self)


TRACE_SUFFIXES = (".csv", ".npz")


def check_trace_path(path, key: str = "--output", inputs=()):
    """A trace file name :meth:`SimulationResult.save` can write (checked before a run).

    Parameters
    ----------
    path : str or pathlib.Path or None
        None passes (nothing to write).
    key : str
        Name of the option, for the error.
    inputs : sequence of path
        Files the run reads (the scene): the traces never replace one of them.

    Returns
    -------
    pathlib.Path or None

    Raises
    ------
    SceneError
        Suffix other than ``.csv`` / ``.npz``, or a path
        :func:`servo_toolkit.core.files.check_output_file` refuses.
    """
    if path is None:
        return None
    check_named(path, key, "file")
    path = Path(path)
    if path.suffix not in TRACE_SUFFIXES:
        raise SceneError(key, f"trace file {path.name!r} must end in .csv or .npz")
    return check_output_file(path, key, inputs=inputs)


def _card_line(s) -> str:
    """The one-line repr of a result of this module."""
    d = s.to_dict()
    key = s.unit.key("max_abs_tracking_error")
    return (f"{s.method}, {d['t_final_s']:.4g} s, peak current {d['max_abs_current_A']:.4g} A, "
            f"peak |error| {d[key]:.4g} {s.unit.shown}")


def _card_html(s) -> str:
    """The Jupyter card (HTML) of a result of this module."""
    d = s.to_dict()
    key = s.unit.key("max_abs_tracking_error")
    rows = (("method", f"{s.method} (asked {s.requested or 'auto'})"),
            ("step", "adaptive" if s.dt_s is None else f"{num(s.dt_s)} s"), ("duration", f"{num(d['t_final_s'])} s"),
            ("peak |tracking error|", f"{num(d[key])} {s.unit.shown}"),
            ("peak current", f"{num(d['max_abs_current_A'])} A"), ("peak voltage", f"{num(d['max_abs_voltage_V'])} V"),
            ("peak motor torque", f"{num(d['max_abs_motor_torque_Nm'])} N*m"),
            ("integration wall time", f"{num(s.wall_s * 1e3)} ms"), ("controller", s.controller))
    return card("Simulation", parts=[facts(rows), svg(s.plot, size=(7.0, 5.2), rows=3, sharex=True)],
                notes=(s.choice, *s.notes))
