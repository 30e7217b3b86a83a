"""What a compiled model includes: :class:`ModelOptions`, the switches of the model assembly
(:func:`servo_toolkit.sim.model.build_model`) and of the reduction study."""

from __future__ import annotations

from dataclasses import dataclass

from . import layout as lo
from .chain_model import CHAIN_CHOICES
from .model_slots import FRICTION_CHOICES


@dataclass(frozen=True)
class ModelOptions:
    """What the model includes. The "leave out" switches serve the reduction study.

    Parameters
    ----------
    inductance : bool
        Armature inductance (False: i follows v algebraically; the current loop is ideal).
    compliance : bool
        Series compliance between motor side and load side (False: rigid chain, q = p).
    backlash : bool
        Lost motion in the compliance (False: plain spring-damper).
    variable_inertia : bool
        J(q) and dJ/dq along the stroke, each node's in the full chain (False: their q0 values
        everywhere, no velocity term).
    stiffness_scale : float
        Multiplies the series stiffness (stiff-case studies).
    damping_ratio : float
        Damping ratio of each compliance whose stage gives none (``damping_ratio``), in the
        mode it dominates (:mod:`servo_toolkit.drivetrain.chain_damping`).
    friction_speed : float
        Motor speed (rad/s) of the tanh smoothing of Coulomb friction.
    controller_mode : str
        ``"sampled"`` (zero-order hold at the sample time, encoder quantization) or
        ``"continuous"`` (the continuous motion controller integrated with the plant, no
        quantization; its reference solution is one ``solve_ivp`` call).
    quantization : bool
        Output-encoder quantization in sampled mode.
    stroke_end : str
        ``"error"``: leaving the stroke raises :class:`SimulationError`; ``"stop"``: an
        elastic end stop (10x the drivetrain stiffness, never pulls).
    table_points : int
        Points of the stroke tables.
    play : float or None
        Total lost motion at the output (rad) replacing the scene's value (None: the scene's
        lost motion at q0).
    friction : {"smooth", "stick", "off"}
        The motor's and the load's Coulomb and static friction: ``"stick"``, exact stick at
        zero speed with the Stribeck law while sliding
        (``servo_toolkit/_physics/friction.h``); ``"smooth"`` (the default), the motor's
        Coulomb friction alone as ``Tc tanh(w / friction_speed)`` (no stick: a motor below
        breakaway creeps, the load's friction and static levels are left out and the notes
        say so); ``"off"``, left out (viscous friction stays).
    chain : {"auto", "full", "two_mass"}
        The drivetrain's compliances: every one of them (the full chain, every mode, every
        node's inertia along the stroke), its two-mass reduction (the lowest mode), or the
        full chain only where lumping its upper modes costs more than
        :data:`~.chain_choice.LUMP_TOLERANCE` of the response at the scene's working
        frequencies (:func:`~.chain_choice.choose_chain`; the model's notes say which, with
        both RK4 step limits and the cost).
    chain_note : str
        Why ``chain`` is what it is when a study chose it for its run
        (:attr:`~.chain_choice.ChainChoice.note`: the choice with its step limits and cost,
        in the study's notes): the model does not note the lumping again. Empty: the model
        notes ``chain`` as given.
    speed_estimator : {None, "ideal", "difference", "kalman"}
        Motor speed fed to the sampled speed loop (None: the scene's ``[sensors]
        speed_estimator``). ``"ideal"``: the true omega_m; ``"difference"``: backward
        difference of the motor-encoder angle over one sample; ``"kalman"``: constant-gain
        Kalman filter (constant-acceleration model, :func:`servo_toolkit.loop.encoder_estimators.steady_state_gain`)
        on the motor-encoder angle. The estimators quantize the motor encoder
        (``motor_encoder_counts``) when ``quantization`` is on. Continuous mode always uses
        the true speed.
    efficiency : bool
        The drivetrain's efficiency loss (False: lossless transmission).
    estimator_jerk : float or None
        Jerk level (motor rad/s^3) setting the Kalman filter's process noise. None: the jerk
        of the motor reaching its peak acceleration ``Kt I_max / J_m(q0)`` within one
        speed-loop time constant, ``a_max * w_c`` with ``w_c = |di_ref/domega_m| Kt / J_m``
        from the controller's direct speed gain (a tenth of the sample rate, ``0.2 pi / Ts``,
        when the controller has none).
    """

    inductance: bool = True
    compliance: bool = True
    backlash: bool = True
    variable_inertia: bool = True
    stiffness_scale: float = 1.0
    damping_ratio: float = 0.05
    friction_speed: float = 1.0
    controller_mode: str = "sampled"
    quantization: bool = True
    stroke_end: str = "error"
    table_points: int = 1025
    play: float | None = None
    speed_estimator: str | None = None
    estimator_jerk: float | None = None
    efficiency: bool = True
    chain: str = "auto"
    friction: str = "smooth"
    chain_note: str = ""

    def __post_init__(self):
        if self.friction not in FRICTION_CHOICES:
            raise ValueError(f"friction must be one of {FRICTION_CHOICES}, got {self.friction!r}")
        if self.chain not in CHAIN_CHOICES:
            raise ValueError(f"chain must be one of {CHAIN_CHOICES}, got {self.chain!r}")
        if self.speed_estimator is not None and self.speed_estimator not in lo.ESTIMATORS:
            raise ValueError(f"speed_estimator must be None or one of {lo.ESTIMATORS}, "
                             f"got {self.speed_estimator!r}")
        if self.estimator_jerk is not None and not self.estimator_jerk > 0:
            raise ValueError(f"estimator_jerk must be positive, got {self.estimator_jerk!r}")
        if self.controller_mode not in ("sampled", "continuous"):
            raise ValueError(f"controller_mode must be 'sampled' or 'continuous', got {self.controller_mode!r}")
        if self.stroke_end not in ("error", "stop"):
            raise ValueError(f"stroke_end must be 'error' or 'stop', got {self.stroke_end!r}")
        if not (self.stiffness_scale > 0 and self.friction_speed > 0 and self.damping_ratio >= 0
                and self.table_points >= 9):
            raise ValueError("stiffness_scale and friction_speed must be positive, damping_ratio "
                             "nonnegative and table_points >= 9")


__all__ = ["ModelOptions"]
