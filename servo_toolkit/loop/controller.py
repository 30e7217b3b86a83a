"""The controller description shared by loop design and simulation.

A cascade: an inner analog current loop (PI on the armature current, output a voltage
clamped at the motor's voltage limit) and a sampled motion controller, a linear system from
``['theta_ref', 'theta', 'omega_m']`` (output-angle reference and measurement, rad; motor
speed, rad/s) to ``['i_ref']`` (A), clamped at the motor's current limit.

An optional :class:`Feedforward` adds a current computed from the commanded trajectory (the
reference and its first and second derivatives) to the motion controller's output before the
clamp. It is outside the feedback loop: the loop transfer functions, and so the margins, are
the same with and without it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..lti.convert import sample_tustin
from ..lti.lazy import ControlSystem, block_of

MOTION_INPUTS = ("theta_ref", "theta", "omega_m")
MOTION_OUTPUTS = ("i_ref",)
#: what a feedforward may be made of
FEEDFORWARD_KINDS = ("off", "gains", "model")


@dataclass(frozen=True)
class Feedforward:
    """Feedforward from the commanded trajectory r(t), r'(t), r''(t) (output rad, rad/s,
    rad/s^2), added to the motion controller's current reference before the current limit.

    Parameters
    ----------
    velocity : float
        Velocity feedforward gain (A per rad/s of the output reference rate).
    acceleration : float
        Acceleration feedforward gain (A per rad/s^2 of the output reference acceleration).
    model : bool
        Model-based torque feedforward: the current the drivetrain's inverse dynamics needs to
        follow r along the stroke (rigid chain, the model's tables)::

            T   = s J(r) r'' + s J'(r) r'^2 / 2 - M_load(r, r')
            T_t = T - J_w(r) r'' - J_w'(r) r'^2 / 2          (past the rotor, J_w = JW N^2)
            N tau = J_w r'' + J_w' r'^2 / 2 + T_t / (1 - c)
            i_ff = (tau + b N r' + Tc tanh(N r' / w_s)) / Kt

        with s = ``inertia_scale``, M_load the hinge moment, stiffness and damping, and c the
        drivetrain's loss coefficient chosen by the direction of the power flow: 1 - eta when
        T_t r' > 0 (the motor drives the load), 1 - 1/eta_b when the load back-drives the
        motor, blended by the model's smooth signs (torque scale and friction speed) so the
        current has no step at a reversal. The motor's Coulomb friction is compensated with the
        model's smoothing ``tanh(omega_m / friction_speed)``. The speed loop then takes the
        motor speed along the command, N(r) r', as its reference (the measured motor speed less
        it is what the motion controller's ``omega_m`` input sees), so it does not oppose the
        commanded motion.
    inertia_scale : float
        The feedforward's inertia J(q) and J'(q) relative to the simulated model's (1: the
        model's; a sensitivity study sets 0.7 or 1.3).
    load_inertia : float or None
        The load inertia (kg*m^2; kg for an output travel) the model-based feedforward assumes
        (None: the simulated scene's). A drive's feedforward knows the nominal load: Monte
        Carlo variants keep it at the nominal scene's while their own load varies. The load
        sits at the output, so it enters J(q) one to one.

    Notes
    -----
    The feedforward is evaluated once per controller sample and held with the rest of the
    current reference (zero-order hold); its current along the trajectory half a sample ahead
    (the hold's mean delay), its speed reference at the sample instant. Step references have r' = r'' = 0
    (their impulses are not fed forward); ramps have r' = rate.
    """

    velocity: float = 0.0
    acceleration: float = 0.0
    model: bool = False
    inertia_scale: float = 1.0
    load_inertia: float | None = None

    def __post_init__(self):
        for name in ("velocity", "acceleration", "inertia_scale"):
            value = getattr(self, name)
            if not np.isfinite(value):
                raise ValueError(f"feedforward {name} must be finite, got {value!r}")
        if self.inertia_scale < 0:
            raise ValueError(f"feedforward inertia_scale must be >= 0, got {self.inertia_scale!r}")
        if self.load_inertia is not None and not (np.isfinite(self.load_inertia) and self.load_inertia >= 0):
            raise ValueError(f"feedforward load_inertia must be >= 0 and finite, got {self.load_inertia!r}")

    @property
    def kind(self) -> str:
        """``"model"``, ``"gains"`` or ``"off"``."""
        return "model" if self.model else "gains" if self.active else "off"

    def to_dict(self) -> dict:
        """JSON-ready fields (SI: A per output rad/s and rad/s^2, or per m/s and m/s^2)."""
        return {"kind": self.kind, "velocity_gain": self.velocity, "acceleration_gain": self.acceleration,
                "model": self.model, "inertia_scale": self.inertia_scale, "load_inertia": self.load_inertia}

    @property
    def active(self) -> bool:
        """Whether it adds anything."""
        return bool(self.model or self.velocity or self.acceleration)

    @classmethod
    def from_kind(cls, kind: str, gains: tuple = (0.0, 0.0)) -> "Feedforward | None":
        """``"off"`` (None), ``"gains"`` (``gains`` = (velocity, acceleration)) or ``"model"``."""
        if kind not in FEEDFORWARD_KINDS:
            raise ValueError(f"feedforward must be one of {FEEDFORWARD_KINDS}, got {kind!r}")
        if kind == "off":
            return None
        if kind == "gains":
            return cls(velocity=float(gains[0]), acceleration=float(gains[1]))
        return cls(model=True)


@dataclass(frozen=True)
class CascadeController:
    """A designed controller; immutable, shared by linear analysis and simulation.

    Parameters
    ----------
    motion : control.StateSpace
        Continuous-time motion controller with inputs ``MOTION_INPUTS`` and output
        ``i_ref`` (A). It is sampled at ``sample_time`` (Tustin) for simulation. Given as a
        python-control system or a :class:`servo_toolkit.lti.system.StateSpace`, it reads as
        python-control's (:attr:`motion_block`: the toolkit's own, without python-control).
    current_kp : float
        Current-loop proportional gain (V/A).
    current_ki : float
        Current-loop integral gain (V/(A*s)).
    sample_time : float
        Motion-controller sample time (s); 0 for continuous.
    description : str
        What the controller is made of (for reports).
    feedforward : Feedforward or None
        Feedforward from the commanded trajectory (None: feedback only). Outside the loop:
        it changes no margin.
    schedule : GainSchedule or None
        Gains scheduled along the stroke (:mod:`servo_toolkit.loop.schedule`): the motion
        controller's inputs scaled by the factors at the measured output position, once per
        sample (None: the same gains everywhere).
    shaper : InputShaper or None
        Command shaper on the reference and its derivatives (:mod:`servo_toolkit.loop.shaper`):
        outside the loop, it delays the command by its stated delay.
    """

    motion: object = ControlSystem()
    current_kp: float
    current_ki: float
    sample_time: float = 0.0
    description: str = ""
    feedforward: Feedforward | None = None
    schedule: object = None
    shaper: object = None

    @property
    def motion_block(self):
        """The motion controller as a :class:`servo_toolkit.lti.system.StateSpace`."""
        return block_of(self, "motion")

    def discrete_motion(self):
        """``(Ad, Bd, Cd, Dd)`` of the motion controller sampled at ``sample_time``.

        With ``sample_time == 0`` the continuous matrices are returned.
        """
        sys = self.motion_block
        if self.sample_time > 0:
            sys = sample_tustin(sys, self.sample_time)
        return tuple(np.asarray(m, dtype=float) for m in (sys.A, sys.B, sys.C, sys.D))
