"""Command signals evaluated inside the kernel, and the initial state of a run.

A :class:`Reference` fills five parameter slots (a sampled command also its table slots and
its samples after the parameters); changing it does not recompile anything, so a frequency
sweep is a loop over ``run(model, Reference.sine(a, f), ...)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..core.units import argument_value, quantity_unit
from ..errors import SceneError, SimulationError
from ..loop.profile import MoveProfile
from . import layout as lo
from .kernel import hermite, measured_angle, measured_motor_angle, reference as reference_at
from .reference_table import duration_of, pack_table, table_span

KINDS = {"hold": lo.REF_CONST, "sine": lo.REF_SINE, "step": lo.REF_STEP, "ramp": lo.REF_RAMP,
         "move": lo.REF_MOVE, "table": lo.REF_TABLE}
#: the units a position argument is given in: an output angle (rad) or an output travel (m)
POSITION = ("rad", "m")
#: and a rate of it
RATE = ("rad/s", "m/s")
#: the unit of each kind's ``amplitude``
AMPLITUDE_UNITS = {"ramp": RATE, "voltage": "V"}


@dataclass(frozen=True)
class Reference:
    """A position command of the output (rad), or an open-loop armature voltage.

    Parameters
    ----------
    kind : str
        ``"hold"``, ``"sine"``, ``"step"``, ``"ramp"``, ``"move"``, ``"table"`` (sampled, see
        :meth:`table`) or ``"voltage"`` (open loop).
    amplitude : float
        Sine amplitude or step size (rad), ramp rate (rad/s), a move's distance (rad), or the
        voltage (V).
    frequency : float
        Sine frequency (Hz).
    offset : float or None
        Starting / centre value (rad); None = the model's mid-stroke q0.
    t0 : float
        Step time, ramp start, sine phase origin or a table's first sample time (s).
    swing : float
        Open loop: amplitude (V) of a sine at ``frequency`` added to the voltage (a sine
        dwell of the plant).
    profile : MoveProfile or None
        A move's jerk-limited profile (:meth:`move`).
    samples : tuple of float
        A table's values (relative to ``offset``), one every ``spacing`` seconds from ``t0``.
    spacing : float
        A table's sample spacing (s).
    periodic : bool
        The table is one period of a command that repeats.
    position_unit : {None, "rad", "m"}
        The output a position argument given as a pint Quantity was in: an angle (rad) or a
        travel (m); None when every position was a bare number (then in the output's SI
        unit, whichever it is). A run refuses a reference in the other output's unit.
    """

    kind: str = "hold"
    amplitude: float = 0.0
    frequency: float = 0.0
    offset: float | None = None
    t0: float = 0.0
    swing: float = 0.0
    profile: MoveProfile | None = None
    samples: tuple = field(default=(), repr=False)
    spacing: float = 0.0
    periodic: bool = False
    position_unit: str | None = field(default=None, compare=False)
    _packed: tuple = field(default=(), init=False, repr=False, compare=False)

    def __post_init__(self):
        if self.kind not in KINDS and self.kind != "voltage":
            raise ValueError(f"reference kind must be one of {sorted(KINDS) + ['voltage']}, got {self.kind!r}")
        if (self.kind == "move") != (self.profile is not None):
            raise ValueError("a move reference needs its profile (Reference.move), and only a move has one")
        for name, unit in (("amplitude", AMPLITUDE_UNITS.get(self.kind, POSITION)), ("frequency", "Hz"),
                           ("offset", POSITION), ("t0", "s"), ("swing", "V"), ("spacing", "s")):
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(self, name, argument_value(value, unit, name))
        if self.frequency < 0 or (self.kind == "sine" and self.frequency == 0):
            raise SceneError("frequency", f"must be {'positive' if self.kind == 'sine' else 'at least 0'} "
                                          f"(got {self.frequency:g} Hz)")
        if self.kind == "table":
            times = self.t0 + self.spacing * np.arange(len(self.samples))
            object.__setattr__(self, "_packed", pack_table(times, self.samples, periodic=self.periodic))

    @classmethod
    def sine(cls, amplitude: float, frequency: float, offset: float | None = None) -> "Reference":
        """offset + amplitude sin(2 pi f t).

        Each argument is a number in SI (rad, or m for an output travel; Hz) or a pint
        Quantity, converted. A SceneError names the argument that is not a finite number
        (a str is not parsed) or a frequency that is not positive.
        """
        frequency = argument_value(frequency, "Hz", "frequency")
        if not frequency > 0:
            raise SceneError("frequency", f"must be positive (got {frequency:g} Hz)")
        return cls("sine", argument_value(amplitude, POSITION, "amplitude"), frequency, _position(offset),
                   position_unit=_unit_of(("amplitude", amplitude, POSITION), ("offset", offset, POSITION)))

    @classmethod
    def step(cls, size: float, at: float = 0.0, offset: float | None = None) -> "Reference":
        """offset, then offset + size from t = at (arguments as :meth:`sine`'s)."""
        return cls("step", argument_value(size, POSITION, "size"), 0.0, _position(offset),
                   argument_value(at, "s", "at"),
                   position_unit=_unit_of(("size", size, POSITION), ("offset", offset, POSITION)))

    @classmethod
    def ramp(cls, rate: float, at: float = 0.0, offset: float | None = None) -> "Reference":
        """offset + rate * max(t - at, 0) (rad/s or m/s; arguments as :meth:`sine`'s)."""
        return cls("ramp", argument_value(rate, RATE, "rate"), 0.0, _position(offset), argument_value(at, "s", "at"),
                   position_unit=_unit_of(("rate", rate, RATE), ("offset", offset, POSITION)))

    @classmethod
    def move(cls, distance: float, v_max: float, a_max: float, j_max: float, at: float = 0.0,
             offset: float | None = None) -> "Reference":
        """A jerk-limited move of ``distance`` from ``offset`` starting at ``at`` (s), within the
        speed, acceleration and jerk limits (:class:`~servo_toolkit.loop.profile.MoveProfile`;
        arguments as :meth:`sine`'s)."""
        given = tuple((name, value, (f"rad{per}", f"m{per}")) for value, per, name in (
            (distance, "", "distance"), (v_max, "/s", "v_max"), (a_max, "/s^2", "a_max"), (j_max, "/s^3", "j_max")))
        profile = MoveProfile(*(argument_value(value, units, name) for name, value, units in given))
        return cls("move", profile.distance, 0.0, _position(offset), argument_value(at, "s", "at"), profile=profile,
                   position_unit=_unit_of(*given, ("offset", offset, POSITION)))

    @classmethod
    def table(cls, time_s, values, offset: float | None = None, periodic: bool = False) -> "Reference":
        """A sampled command: offset + the cubic spline through ``values`` at ``time_s``.

        Parameters
        ----------
        time_s : array_like
            Sample times (s), strictly increasing and equally spaced (at least 4).
        values : array_like
            The command at those times relative to ``offset`` (rad, or m for an output travel).
        offset : float, optional
            Added to every value; None = the model's mid-stroke q0 (0 for absolute values).
        periodic : bool
            The samples are one period of a repeating command (period: ``len(values)``
            spacings; the spline is periodic).

        Before the first sample and after the last the end values are held; a periodic
        table repeats. The run starts in equilibrium at the command's value at t = 0. The
        kernel evaluates the spline and its first two derivatives exactly
        (``servo_toolkit/_physics/command.h``), so the model-based feedforward follows it.

        Raises
        ------
        SceneError
            Naming ``time_s`` or ``values``: fewer than 4 samples, a value that is not
            finite, times that do not increase equally spaced.
        """
        from .reference_table import check_samples
        t0, step, v = check_samples(time_s, values, periodic=periodic)
        return cls("table", 0.0, 0.0, _position(offset), t0, samples=tuple(float(x) for x in v), spacing=step,
                   periodic=bool(periodic), position_unit=_unit_of(("offset", offset, POSITION)))

    @classmethod
    def voltage(cls, volts: float, swing: float = 0.0, frequency: float = 0.0) -> "Reference":
        """Open loop: armature voltage ``volts + swing sin(2 pi frequency t)`` (clamped at the
        voltage limit)."""
        return cls("voltage", argument_value(volts, "V", "volts"), argument_value(frequency, "Hz", "frequency"),
                   swing=argument_value(swing, "V", "swing"))

    def describe(self, output_unit: str = "rad") -> str:
        """One line in engineering units: deg for an output angle, mm for an output travel
        (``output_unit`` ``"m"``)."""
        scale, unit = (1e3, "mm") if output_unit == "m" else (180 / np.pi, "deg")
        off = "q0" if self.offset is None else f"{self.offset * scale:.3g} {unit}"
        if self.kind == "sine":
            return f"sine {self.amplitude * scale:.3g} {unit} at {self.frequency:.3g} Hz about {off}"
        if self.kind == "step":
            return f"step {self.amplitude * scale:.3g} {unit} at t = {self.t0:.3g} s from {off}"
        if self.kind == "ramp":
            return f"ramp {self.amplitude * scale:.3g} {unit}/s from {off}"
        if self.kind == "move":
            return f"{self.profile.describe(output_unit)} at t = {self.t0:.3g} s from {off}"
        if self.kind == "voltage":
            sine = f" + {self.swing:.4g} V sine at {self.frequency:.4g} Hz" if self.swing else ""
            return f"open loop, {self.amplitude:.4g} V{sine}"
        if self.kind == "table":
            lo_, hi_ = table_span(self._packed[2])
            span = f"{lo_ * scale:.3g} to {hi_ * scale:.3g} {unit}"
            what = (f"periodic table of {len(self.samples)} samples (period {self.duration:.4g} s)" if self.periodic
                    else f"table of {len(self.samples)} samples over {self.duration:.4g} s")
            return f"{what} every {self.spacing:.3g} s, {span} about {off}"
        return f"hold {off}"

    @property
    def duration(self) -> float:
        """A table's time span (s): its period, or first to last sample; 0 for other kinds."""
        if self.kind != "table":
            return 0.0
        return duration_of(len(self.samples), self.spacing, self.periodic)

    def to_dict(self) -> dict:
        """JSON-ready description (SI); a table gives its sample count, spacing, period flag
        and the range of its values, not the samples."""
        out = {"kind": self.kind, "amplitude": self.amplitude, "frequency_Hz": self.frequency,
               "offset_rad": self.offset, "t0_s": self.t0}
        if self.swing:
            out["swing_V"] = self.swing
        if self.profile is not None:
            out["move"] = self.profile.to_dict()
        if self.kind == "table":
            lo_, hi_ = table_span(self._packed[2])
            out.update(samples=len(self.samples), step_s=self.spacing, periodic=self.periodic, duration_s=self.duration,
                       values_min=lo_, values_max=hi_)
        return out


def _unit_of(*arguments) -> str | None:
    """The output (``"rad"`` or ``"m"``) a constructor's Quantity arguments are in, each
    ``(name, value, units)`` with the units a Quantity of it may be in (a position or a rate of
    it: the output is the unit's part before any ``/``); None when all are bare numbers.
    SceneError naming the first that is in the other output's."""
    found = None
    for name, value, units in arguments:
        unit = quantity_unit(value, units)
        if unit is None:
            continue
        output = unit.split("/")[0]
        if found is not None and output != found[1]:
            raise SceneError(name, f"{'a travel' if output == 'm' else 'an angle'} where {found[0]} is "
                                   f"{'a travel' if found[1] == 'm' else 'an angle'}: give both for the same output")
        found = found or (name, output)
    return None if found is None else found[1]


def _position(offset):
    """A constructor's ``offset``: None (the model's q0) or a finite position."""
    return None if offset is None else argument_value(offset, POSITION, "offset")


def fill(model, ref: Reference) -> np.ndarray:
    """Parameters of ``model`` with the reference slots set."""
    P = model.parameters()
    if ref.kind == "voltage":
        if model.closed_loop:
            raise ValueError("a voltage reference needs an open-loop model (controller=None)")
        P[lo.V_OPEN] = ref.amplitude
        P[lo.REF_OFF] = model.q0 if ref.offset is None else ref.offset
        if ref.swing:
            P[lo.REF_KIND], P[lo.REF_A], P[lo.REF_F], P[lo.REF_T0] = lo.REF_SINE, ref.swing, ref.frequency, ref.t0
        return P
    if not model.closed_loop:
        raise ValueError("an open-loop model needs Reference.voltage(V)")
    P[lo.REF_KIND] = KINDS[ref.kind]
    P[lo.REF_A], P[lo.REF_F], P[lo.REF_T0] = ref.amplitude, ref.frequency, ref.t0
    P[lo.REF_OFF] = model.q0 if ref.offset is None else ref.offset
    if ref.profile is not None:  # the move's block after the parameters, its index in REF_F
        P[lo.REF_F] = P.size
        P = np.concatenate([P, ref.profile.block()])
    if ref.kind == "table":
        t0, step, data, fingerprint = ref._packed
        P[lo.REF_TAB_OFF], P[lo.REF_TAB_N], P[lo.REF_TAB_T0] = P.size, data.size // 2, t0
        P[lo.REF_TAB_INV_DT], P[lo.REF_TAB_WRAP], P[lo.REF_TAB_SUM] = 1.0 / step, float(ref.periodic), fingerprint
        P = np.concatenate([P, data])
    return P


def initial_state(model, P: np.ndarray, at_rest: bool = False) -> np.ndarray:
    """Static equilibrium at the reference's starting angle.

    The compliance carries the hinge moment (deflection beyond the play), the motor holds it
    with the current f / (N Kt), the current-loop integral supplies R i, and the controller
    state is the least-squares solution of ``x = A x + B u, C x + D u = i`` (sampled) or
    ``A x + B u = 0, C x + D u = i`` (continuous); a speed estimator starts at the measured
    motor angle with zero speed. ``at_rest`` starts unloaded instead. With the model-based
    feedforward the controller holds the current less the feedforward's static share (the
    load moment over N(r) Kt at the starting reference).
    """
    x = np.zeros(model.nx)
    q = P[lo.REF_OFF] if P[lo.REF_KIND] != lo.REF_TABLE else reference_at(0.0, P)
    x[0] = x[2] = x[6] = q
    if at_rest:
        return _estimator_at_rest(model, P, x)
    nm, o = int(P[lo.NMID]), int(P[lo.OFF_NODE])
    x[o:o + 2 * nm:2] = q  # the full chain's intermediate nodes
    f = P[lo.HINGE_M] + P[lo.HINGE_K] * q  # moment the drivetrain must supply
    motor_side = f
    if nm and f != 0.0:
        motor_side = _chain_equilibrium(model, P, x, q, f)
    elif not model.rigid and f != 0.0:
        c = P[lo.HALF_PLAY]
        x[0] = q
        for _ in range(3):  # K is evaluated at p: a few fixed-point passes
            k, dk = hermite(model.T, lo.T_K, P, x[0])
            z = f / (k * P[lo.KSCALE])
            x[0] = q + z + (c if f > 0 else -c)
        x[6] = q + z
        motor_side = f + 0.5 * dk * P[lo.KSCALE] * z * z
    check_start_on_tables(model, P, x)
    n = hermite(model.T, lo.T_N, P, x[0])[0]
    cur = motor_side / (n * P[lo.KT])
    if not model.closed_loop:
        return x  # open loop starts at rest
    cur = float(np.clip(cur, -P[lo.ILIM], P[lo.ILIM]))
    x[4] = cur
    x[5] = P[lo.R] * cur
    nc = int(P[lo.NC])
    if nc:
        a, b, c, d = _controller_matrices(P, nc)
        u = np.array([q, measured_angle(x[2], P), 0.0])
        lhs = (np.eye(nc) - a) if P[lo.CMODE] == lo.SAMPLED else -a
        mat = np.vstack([lhs, c])
        # the model-based feedforward supplies the static load's share at rest (r' = r'' = 0)
        held = cur - (P[lo.FF_MODEL] * P[lo.FF_ON] * f / (hermite(model.T, lo.T_N, P, q)[0] * P[lo.KT]))
        rhs_ = np.concatenate([b @ u, [held - float(d @ u)]])
        x[lo.NX_PHYS:lo.NX_PHYS + nc] = np.linalg.lstsq(mat, rhs_, rcond=None)[0]
    return _estimator_at_rest(model, P, x)


def check_start_on_tables(model, P, x0):
    """Refuse a start whose motor side or intermediate nodes lie beyond the stroke tables
    (the stroke and 10 % on each side), where the kinematics are held at the tables' ends
    rather than known: a compliance wound up by the load moment far past the stroke."""
    if model.rigid or P[lo.PERIODIC] > 0.0:
        return
    lo_t = P[lo.TAB_LO]
    hi_t = lo_t + (P[lo.TAB_N] - 1.0) * P[lo.TAB_H]
    nm, o = int(P[lo.NMID]), int(P[lo.OFF_NODE])
    nodes = [x0[0], *x0[o:o + 2 * nm:2]]
    worst = max(nodes, key=lambda v: max(v - hi_t, lo_t - v))
    if lo_t <= worst <= hi_t:
        return
    travel = getattr(model, "output_unit", "rad") == "m"
    scale, unit, moment = (1e3, "mm", "N") if travel else (math.degrees(1.0), "deg", "N*m")
    f = P[lo.HINGE_M] + P[lo.HINGE_K] * x0[2]
    raise SimulationError(
        f"the start puts the drivetrain's motor side at {worst * scale:.4g} {unit} (deflected by "
        f"{(worst - x0[2]) * scale:.4g} {unit} from the output at {x0[2] * scale:.4g} {unit}), outside the stroke "
        f"[{model.stroke[0] * scale:.4g}, {model.stroke[1] * scale:.4g}] {unit} and its tables' 10 % margin: the "
        f"compliances cannot carry the load's moment ({f:.4g} {moment}, load.hinge_moment) within the stroke; "
        f"stiffen them or lighten the load")


def _chain_equilibrium(model, P, x, q, f):
    """The full chain carrying the moment f at rest (no loss at rest): every segment
    deflected by f / k_s beyond its play, from the load back to the motor side (k at p: a few
    fixed-point passes). Returns the moment at the motor side, f + sum k_s' z_s^2 / 2."""
    nm, o, g = int(P[lo.NMID]), int(P[lo.OFF_NODE]), int(P[lo.OFF_SEG])
    side = 1.0 if f > 0 else -1.0
    for _ in range(3):
        pos, pot = q, 0.0
        for j in range(nm, -1, -1):
            row = lo.T_K if j == 0 else lo.T_KS + 2 * (j - 1)
            k, dk = hermite(model.T, row, P, x[0])
            z = f / (k * P[lo.KSCALE])
            half = P[lo.HALF_PLAY] if j == 0 else P[g + lo.SEG_STRIDE * j + lo.SEG_PLAY]
            pos = pos + z + side * half
            pot += 0.5 * dk * P[lo.KSCALE] * z * z
            if j == 0:
                x[0] = pos
                x[6] = pos - side * half
            else:
                x[o + 2 * (j - 1)] = pos
    return f + pot


def _estimator_at_rest(model, P, x):
    """The speed estimator at rest: the measured motor angle, zero speed and acceleration."""
    if P[lo.EST] != lo.EST_IDEAL:
        e = int(P[lo.OFF_E])
        x[e:] = 0.0
        x[e] = measured_motor_angle(P, model.T, x[0])
    return x


def _controller_matrices(P, nc):
    oa, ob, oc, od = (int(P[i]) for i in (lo.OFF_A, lo.OFF_B, lo.OFF_C, lo.OFF_D))
    return (P[oa:oa + nc * nc].reshape(nc, nc), P[ob:ob + 3 * nc].reshape(nc, 3),
            P[oc:oc + nc].reshape(1, nc), P[od:od + 3])
