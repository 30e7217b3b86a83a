"""Linear plant blocks at an operating point: python-control StateSpace with named signals.

Everything mechanical is referred to the output coordinate q (the output shaft angle; the
cam angle for a cam drive). Sign convention: positive motor current drives q positive;
``tau_ext`` is an external torque on the output acting along +q (a hinge moment opposing
positive motion is a negative ``tau_ext``).

Signals and units
-----------------
Inputs
    ``u`` armature voltage (V); ``tau_ext`` external torque at the output (N*m);
    ``tau_m`` motor torque (N*m at the motor shaft, mechanics block only).
States
    ``theta_1`` motor-side angle referred to the output, motor angle / N (rad);
    ``omega_1`` its rate (rad/s); ``theta`` output (load-side) angle (rad);
    ``omega`` its rate (rad/s); ``i`` armature current (A), present with inductance.
Outputs
    ``theta`` (rad), ``omega_m`` motor speed N*omega_1 (rad/s), ``i`` (A), ``omega`` (rad/s).

The linear plant is the driving-mode linearization of the drivetrain's lumped chain
(:mod:`servo_toolkit.drivetrain.chain`): the motor torque reaches the output as
eta * N * Kt * i, and the losses never act on the torque that accelerates the rotor and the
members before them: each motor-side element's inertia counts with eta / Pi_e (Pi_e the
efficiency of the losses before it), so a rigid chain accelerates at
eta N Kt i / (eta J_before + J_after). ``model="chain"`` gives every node and mode
(:mod:`servo_toolkit.plant.chain_plant`).

Each block is built as the toolkit's own :class:`~servo_toolkit.lti.system.StateSpace`
(``*_block``, what the loop's analyses use, without python-control); the public functions
hand the same matrices and names over as python-control systems. The current loop and the
sampling delay are :mod:`.current_loop`'s (their names are kept here too).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..core.units import argument_value
from ..drivetrain.chain_damping import chain_damping
from ..drivetrain.elements import stage_units
from ..drivetrain.stage_friction import lumped_friction
from ..errors import SceneError
from ..lti.system import StateSpace, ss
# the current loop's and the sampling delay's names, kept here for code that imports them from here
from .current_loop import (current_controller, current_loop_block, current_loop_gains,  # noqa: F401
                           sample_delay, sample_delay_block)
from .signals import DEFAULT_STRUCTURAL_DAMPING, PLANT_OUTPUTS


@dataclass(frozen=True)
class PlantParameters:
    """Lumped linear parameters at one operating point, SI, referred to the output.

    Parameters
    ----------
    J1, J2 : float
        Motor-side and load-side inertia (kg*m^2); a rigid plant has ``K = inf`` and
        carries the whole inertia in ``J1 + J2``.
    K : float
        The two-mass model's stiffness between them (N*m/rad), ``K = w_a^2 J2`` of the chain's
        reduction (:meth:`~servo_toolkit.drivetrain.chain.Chain.two_mass`): the springs' series
        stiffness only for a chain with one compliance; ``inf`` for a rigid drivetrain.
    c : float
        Damping across the spring (N*m*s/rad).
    b1, b2 : float
        Viscous friction on the motor side (motor b * N^2) and on the load (N*m*s/rad).
    kh : float
        Hinge stiffness at the output (N*m/rad).
    N : float
        Ratio, motor rad per output rad at q0.
    eta : float
        Forward efficiency of the drivetrain.
    Kt, Ke, R, L : float
        Motor torque constant (N*m/A), back-emf constant (V*s/rad), resistance (ohm),
        inductance (H).
    q0 : float
        Operating point (rad).
    """

    J1: float
    J2: float
    K: float
    c: float
    b1: float
    b2: float
    kh: float
    N: float
    eta: float
    Kt: float
    Ke: float
    R: float
    L: float
    q0: float = 0.0

    @property
    def torque_gain(self) -> float:
        """Output torque per ampere, eta * N * Kt (N*m/A)."""
        return self.eta * self.N * self.Kt

    @property
    def rigid(self) -> bool:
        """True when there is no compliance between motor and load."""
        return not math.isfinite(self.K)

    @property
    def resonance_hz(self) -> float:
        """Undamped drivetrain resonance sqrt(K (1/J1 + 1/J2)) / (2 pi) (Hz)."""
        if self.rigid or self.J2 <= 0:
            return math.inf
        return math.sqrt(self.K * (1 / self.J1 + 1 / self.J2)) / (2 * math.pi)

    @property
    def antiresonance_hz(self) -> float:
        """Load-side mode with the motor held, sqrt(K / J2) / (2 pi) (Hz)."""
        if self.rigid or self.J2 <= 0:
            return math.inf
        return math.sqrt(self.K / self.J2) / (2 * math.pi)

    def with_variation(self, load_inertia_delta: float = 0.0, stiffness_factor: float = 1.0,
                       structural_damping: float = DEFAULT_STRUCTURAL_DAMPING) -> "PlantParameters":
        """A varied copy: load inertia added to J2, stiffness scaled, damping re-derived."""
        J2 = self.J2 + load_inertia_delta
        K = self.K * stiffness_factor
        return replace(self, J2=J2, K=K, c=spring_damping(self.J1, J2, K, structural_damping))


def two_mass_damping(chain, q0: float, structural_damping: float = DEFAULT_STRUCTURAL_DAMPING) -> float:
    """The damping ratio of the chain's two-mass reduction: its lowest mode's modal damping
    ratio with each compliance's damper (:mod:`servo_toolkit.drivetrain.chain_damping`;
    ``structural_damping`` where a stage gives no ``damping_ratio``). With one compliance,
    that compliance's ratio."""
    if chain.rigid:
        return 0.0
    damping = chain_damping(chain, q0, structural_damping)
    return damping.lowest_ratio if damping.segments else 0.0


def spring_damping(J1, J2, K, zeta):
    """Damper across the spring giving the two-mass mode the damping ratio ``zeta``."""
    J1, J2, K = np.asarray(J1, float), np.asarray(J2, float), np.asarray(K, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        jr = np.where(J2 > 0, J1 * J2 / np.where(J1 + J2 > 0, J1 + J2, 1.0), 0.0)
        c = np.where(np.isfinite(K), 2 * zeta * np.sqrt(K * jr), 0.0)
    return c if c.ndim else float(c)


def friction_note(scene) -> tuple:
    """What the linear plant leaves out of the scene's friction, in words (empty when the
    scene has only viscous friction).

    The plant keeps the viscous friction (the motor's b N^2 on the motor side, the load's
    damping); Coulomb and static friction have no linearization at rest (their slope there
    is infinite): a loop designed on the plant may stop short of its command inside the
    static friction's dead band, or hunt against it with integral action, which the
    nonlinear model with ``ModelOptions(friction="stick")`` shows
    (:mod:`servo_toolkit.studies.hunting`).

    Returns
    -------
    tuple of str
    """
    from ..core.output_units import output_unit
    motor, load = scene.motor, scene.load
    if motor is None:
        return ()
    parts = [f"the {who}'s Coulomb friction {tc:.4g} {unit}" + (f", static {ts:.4g} {unit}" if ts > tc else "")
             for who, tc, ts, unit in (("motor", motor.coulomb_friction, motor.breakaway_torque, "N*m"),
                                       ("load", load.coulomb_friction, load.breakaway, output_unit(scene).moment))
             if max(tc, ts) > 0]
    outs = stage_units(scene.stages)[0] if scene.stage_friction else ()
    for k, fr in enumerate(scene.stage_friction):
        unit = "N" if outs[k] == "m" else "N*m"
        if fr is not None and max(fr.coulomb_friction, fr.breakaway) > 0:
            parts.append(f"drivetrain[{k}]'s Coulomb friction {fr.coulomb_friction:.4g} {unit}"
                         + (f", static {fr.breakaway:.4g} {unit}" if fr.breakaway > fr.coulomb_friction else ""))
    if not parts:
        return ()
    return ("linear plant: viscous friction only (the motor's b N^2, the stages' viscous friction reflected, the "
            "load's damping); left out, having no "
            "linearization at rest: " + "; ".join(parts) + ". A loop may stop short of its command inside the "
            "dead band of static friction or hunt against it with integral action (the report's time section "
            "runs the step with friction that holds)",)


class _AtOnePoint:
    """A drivetrain whose kinematics at the points asked for are composed once: the
    parameters at one operating point read the chain's inertias, springs, modes and damping
    there, each asking the drivetrain for the same kinematics (some 17 times). Lives for one
    :func:`plant_parameters` call; everything else is the drivetrain's."""

    def __init__(self, drivetrain):
        self._drivetrain = drivetrain
        self._kinematics = {}

    def kinematics(self, q):
        q = np.atleast_1d(np.asarray(q, dtype=float))
        key = (q.shape, q.tobytes())
        if key not in self._kinematics:
            self._kinematics[key] = self._drivetrain.kinematics(q)
        return self._kinematics[key]

    def __getattr__(self, name):
        return getattr(self._drivetrain, name)


def plant_parameters(scene, q0=None, model: str = "auto",
                     structural_damping: float = DEFAULT_STRUCTURAL_DAMPING) -> PlantParameters:
    """Linear parameters of a scene's drivetrain at ``q0``.

    Parameters
    ----------
    scene : Scene
    q0 : float, optional
        Operating point (rad); default mid-stroke.
    model : {"auto", "two_mass", "rigid"}
        ``auto`` is two-mass when the chain has a finite stiffness, else rigid (both
        reductions of the drivetrain's chain; :func:`plant` also takes ``"chain"``).
    structural_damping : float
        Damping ratio of each compliance whose stage gives none (``damping_ratio``); the
        two-mass plant's mode has the chain's lowest mode's damping ratio
        (:func:`two_mass_damping`).

    Returns
    -------
    PlantParameters
        Computed once per scene object and argument set (:meth:`Scene.derived
        <servo_toolkit.scene.loader.Scene.derived>`); later calls return the same object.
    """
    if model not in ("auto", "two_mass", "rigid"):
        raise SceneError("model", f"unknown plant model {model!r}; use auto, two_mass or rigid")
    drive = scene.drivetrain
    q0 = drive.mid_stroke if q0 is None else argument_value(q0, drive.output_unit, "q0")
    # keyed on the exact bits of the floats: -0.0 and 0.0 give results that print apart
    key = ("plant_parameters", q0.hex(), model, float(structural_damping).hex())
    return scene.derived(key, lambda: _parameters_at(scene, drive, q0, model, structural_damping))


def _parameters_at(scene, drive, q0: float, model: str, structural_damping: float) -> PlantParameters:
    """The parameters of :func:`plant_parameters`, computed."""
    chain = replace(drive.chain, drivetrain=_AtOnePoint(drive))
    split = chain.two_mass([q0], driving=True)
    n = float(drive.ratio([q0])[0][0])
    motor, load = scene.motor, scene.load
    J1, J2, K = float(split.motor_side[0]), float(split.load_side[0]), float(split.stiffness[0])
    if model == "two_mass" and not math.isfinite(K):
        raise SceneError("drivetrain", "a two-mass plant needs a compliance; this chain is rigid")
    if model == "rigid" or not math.isfinite(K) or J2 <= 0:
        J1, J2, K = float(chain.node_inertias([q0], driving=True).sum()), 0.0, math.inf
    zeta = two_mass_damping(chain, q0, structural_damping) if math.isfinite(K) else 0.0
    motor, load = lumped_friction(scene, q0, not math.isfinite(K), [])  # the stages' viscous friction
    return PlantParameters(J1=J1, J2=J2, K=K, c=float(spring_damping(J1, J2, K, zeta)),
                           b1=motor.viscous_friction * n**2, b2=load.damping, kh=load.hinge_stiffness,
                           N=abs(n), eta=drive.efficiency, Kt=motor.torque_constant,
                           Ke=motor.back_emf_constant, R=motor.resistance, L=motor.inductance, q0=q0)


def plant_matrices(p: PlantParameters, inductance: bool = True):
    """``(A, B, C, D, states)`` of the voltage-driven plant; inputs ``[u, tau_ext]``,
    outputs ``PLANT_OUTPUTS``. Without inductance the current is algebraic,
    i = (u - Ke * omega_m) / R."""
    kt = p.torque_gain
    ind = inductance and p.L > 0
    if p.rigid:
        J = p.J1 + p.J2
        states = ["theta", "omega"]
        A = np.array([[0, 1], [-p.kh / J, -(p.b1 + p.b2) / J]], float)
        B = np.array([[0, 0], [0, 1 / J]], float)
        C = np.array([[1, 0], [0, p.N], [0, 0], [0, 1]], float)
        w1 = 1  # index of the motor-side speed
    else:
        states = ["theta_1", "omega_1", "theta", "omega"]
        J1, J2, K, c = p.J1, p.J2, p.K, p.c
        A = np.array([[0, 1, 0, 0],
                      [-K / J1, -(c + p.b1) / J1, K / J1, c / J1],
                      [0, 0, 0, 1],
                      [K / J2, c / J2, -(K + p.kh) / J2, -(c + p.b2) / J2]], float)
        B = np.array([[0, 0], [0, 0], [0, 0], [0, 1 / J2]], float)
        C = np.array([[0, 0, 1, 0], [0, p.N, 0, 0], [0, 0, 0, 0], [0, 0, 0, 1]], float)
        w1 = 1
    n = A.shape[0]
    D = np.zeros((4, 2))
    if ind:
        A = np.pad(A, ((0, 1), (0, 1)))
        B = np.pad(B, ((0, 1), (0, 0)))
        C = np.pad(C, ((0, 0), (0, 1)))
        A[w1, n] = kt / p.J1 if not p.rigid else kt / (p.J1 + p.J2)
        A[n, w1] = -p.Ke * p.N / p.L
        A[n, n] = -p.R / p.L
        B[n, 0] = 1 / p.L
        C[2, n] = 1.0
        states.append("i")
    else:  # i = (u - Ke N omega_1) / R
        jm = p.J1 if not p.rigid else p.J1 + p.J2
        A[w1, w1] -= kt * p.Ke * p.N / (p.R * jm)
        B[w1, 0] += kt / (p.R * jm)
        C[2, w1] = -p.Ke * p.N / p.R
        D[2, 0] = 1 / p.R
    return A, B, C, D, states


def _plant(p: PlantParameters, inductance: bool, name: str) -> StateSpace:
    A, B, C, D, states = plant_matrices(p, inductance)
    return ss(A, B, C, D, inputs=["u", "tau_ext"], outputs=list(PLANT_OUTPUTS), states=states, name=name)


def rigid_plant(scene, q0=None, inductance: bool = True) -> "control.StateSpace":
    """Rigid drivetrain: the whole reflected inertia J(q0) on one shaft.

    Inputs ``u`` (V), ``tau_ext`` (N*m); states ``theta`` (rad), ``omega`` (rad/s) and ``i``
    (A) with inductance; outputs ``theta``, ``omega_m``, ``i``, ``omega`` (see module doc).
    """
    return _plant(plant_parameters(scene, q0, "rigid"), inductance, "rigid_plant").to_control()


def two_mass_plant(scene, q0=None, inductance: bool = True,
                   structural_damping: float = DEFAULT_STRUCTURAL_DAMPING) -> "control.StateSpace":
    """Two-mass drivetrain: motor-side and load-side inertia joined by the reduction's stiffness K.

    States ``theta_1``, ``omega_1`` (motor side referred to the output), ``theta``, ``omega``
    (load side), and ``i`` with inductance. Its poles include the resonance
    sqrt(K (1/J1 + 1/J2)); theta/u has the anti-resonance sqrt(K/J2) of omega_m/u as zeros.
    """
    return _plant(plant_parameters(scene, q0, "two_mass", structural_damping), inductance,
                  "two_mass_plant").to_control()


def plant(scene, q0=None, inductance: bool = True, model: str = "auto",
          structural_damping: float = DEFAULT_STRUCTURAL_DAMPING) -> "control.StateSpace":
    """Two-mass plant when the chain is compliant, else rigid (see :func:`two_mass_plant`);
    ``model="chain"``: every node and mode of the chain
    (:func:`~servo_toolkit.plant.chain_plant.chain_plant`)."""
    return plant_block(scene, q0, inductance, model, structural_damping).to_control()


def plant_block(scene, q0=None, inductance: bool = True, model: str = "auto",
                structural_damping: float = DEFAULT_STRUCTURAL_DAMPING) -> StateSpace:
    """:func:`plant` as the toolkit's own state-space block."""
    if model == "chain":
        if not scene.drivetrain.chain.rigid:
            from .chain_plant import chain_plant_block
            return chain_plant_block(scene, q0, inductance, structural_damping)
        model = "rigid"
    p = plant_parameters(scene, q0, model, structural_damping)
    return _plant(p, inductance, "rigid_plant" if p.rigid else "two_mass_plant")


def mechanics(scene, q0=None, model: str = "auto",
              structural_damping: float = DEFAULT_STRUCTURAL_DAMPING) -> "control.StateSpace":
    """The mechanical part alone: inputs ``tau_m`` (N*m at the motor shaft) and ``tau_ext``;
    outputs ``theta``, ``omega_m``, ``omega``. A current-driven plant is this block with
    tau_m = Kt * i."""
    return mechanics_block(scene, q0, model, structural_damping).to_control()


def mechanics_block(scene, q0=None, model: str = "auto",
                    structural_damping: float = DEFAULT_STRUCTURAL_DAMPING) -> StateSpace:
    """:func:`mechanics` as the toolkit's own state-space block."""
    p = plant_parameters(scene, q0, model, structural_damping)
    p = replace(p, Ke=0.0, R=1.0, L=0.0)
    A, B, C, D, states = plant_matrices(p, inductance=False)
    B = B.copy()
    B[:, 0] *= p.R / p.Kt  # u -> tau_m: with Ke = 0, i = u / R and tau_m = Kt i
    keep = [0, 1, 3]
    return ss(A, B, C[keep], D[keep] * 0, inputs=["tau_m", "tau_ext"],
              outputs=["theta", "omega_m", "omega"], states=states, name="mechanics")
