"""Drivetrain reflection: ratio, inertia, stiffness, lash and efficiency along the stroke.

The generalized coordinate ``q`` is the output angle of the chain (the cam angle when the
chain ends in a cam). Every inertial element i moves with a coordinate u_i(q); with the
Jacobians T_i = du_i/dq and T2_i = d2u_i/dq2 the equivalent-element method of seed 000 gives

    J(q) = sum m_i T_i^2 = T' M T,      (1/2) dJ/dq = sum m_i T_i T2_i = T' M T2,

and a spring k on coordinate u reflects to the output as k (du/dq)^2 (seed 001, eq 8).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np

from ..components.base import Element, Jet, Lash
from ..components.compliance import Compliance
from ..errors import SceneError
from .chain import Chain
from .elements import (STIFFNESS_UNIT, NeglectCriterion, ReflectedInertias, neglect_criterion, reflect_elements,
                       stage_units)


#: |N| (motor rad per output rad or per output m) the models are conditioned for: beyond it the
#: linear plant's matrices and the simulation's stiffness span more than double precision holds
RATIO_RANGE = (1e-4, 1e8)
#: the keys that set a stage's ratio, for error messages


def ratio_keys(drivetrain) -> str:
    """``drivetrain[i].key`` of every key that sets a ratio of the chain."""
    out = [f"drivetrain[{i}].{s.RATIO_KEYS}" for i, s in enumerate(drivetrain.stages) if s.RATIO_KEYS]
    return ", ".join(out) or "ratios"


@dataclass(frozen=True)
class Kinematics:
    """Every coordinate of the chain as a function of q (arrays over q)."""

    q: np.ndarray
    motor: Jet
    output: Jet
    elements: tuple
    springs: tuple
    lashes: tuple
    element_stage: tuple = ()
    spring_stage: tuple = ()


@dataclass(frozen=True)
class StiffnessChain:
    """Series stiffness at the output and each spring's share of the compliance.

    Attributes
    ----------
    names : tuple of str
    stage_stiffness : numpy.ndarray
        Each spring reflected to the output, shape (n_springs, n_q) (N*m/rad; N/m when
        the output is a travel).
    total : numpy.ndarray
        Series total, shape (n_q,); ``inf`` when the chain has no spring (rigid).
    shares : numpy.ndarray
        Compliance shares (sum to 1 over springs).
    ratio_to_output : numpy.ndarray
        |du/dq| of each spring's coordinate (rad or m per unit of q).
    native_stiffness : numpy.ndarray
        Each spring's own stiffness k_i, unreflected, shape (n_springs,).
    native_units : tuple of str
        ``"N*m/rad"`` or ``"N/m"`` per spring: the unit of ``native_stiffness``.
    lever : numpy.ndarray
        c_i, shape (n_springs,): 1 for a spring on a coordinate of the output's unit, else
        the ratio to the output at mid-stroke of the last spring of the other kind, the same
        for all of them (see :class:`~servo_toolkit.drivetrain.elements.NeglectCriterion`).
    """

    names: tuple
    stage_stiffness: np.ndarray
    total: np.ndarray
    shares: np.ndarray
    ratio_to_output: np.ndarray
    native_stiffness: np.ndarray = field(default_factory=lambda: np.zeros(0))
    native_units: tuple = ()
    lever: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def negligible(self, threshold: float = 1e-3) -> np.ndarray:
        """Share rule: a stage whose compliance share is below ``threshold`` at every q
        may be left out (its reflected stiffness is then orders of magnitude above the
        rest). See :meth:`criterion` for seed 001's own two conditions."""
        return np.all(self.shares < threshold, axis=-1)

    def criterion(self, min_ratio: float = 10.0, within: float = 10.0) -> NeglectCriterion:
        """Seed 001's two conditions per stage, stiffnesses compared in the output's unit.

        Parameters
        ----------
        min_ratio : float
            Condition 1: the ratio between the stage and every later stage is at least this.
        within : float
            Condition 2: the stage's own stiffness is at least 1/``within`` of some later
            stage's.

        Returns
        -------
        NeglectCriterion
        """
        lever = self.lever[:, None] if self.lever.size else np.ones((len(self.names), 1))
        return neglect_criterion(self.native_stiffness * lever[:, 0] ** 2,
                                 self.ratio_to_output / lever, min_ratio, within)


#: stroke of an output travel (m) when the scene gives none
DEFAULT_LINEAR_STROKE = (-0.05, 0.05)


def series(stiffnesses) -> float | np.ndarray:
    """Series combination 1 / sum(1/k_i) along axis 0."""
    k = np.asarray(stiffnesses, dtype=float)
    return 1.0 / np.sum(1.0 / k, axis=0)


@dataclass(frozen=True)
class Drivetrain:
    """Motor, stages and load of a scene; immutable, evaluated on demand.

    Parameters
    ----------
    motor : DCMotor
    stages : tuple
    load : Load
    """

    motor: object
    stages: tuple
    load: object

    @classmethod
    def from_scene(cls, scene) -> "Drivetrain":
        """The drivetrain of a scene."""
        if not scene.stages or scene.motor is None:
            raise SceneError("drivetrain", "this scene has no motor-driven drivetrain")
        return cls(scene.motor, scene.stages, scene.load)

    @property
    def ends_in_cam(self) -> bool:
        """True when q is a cam angle rather than an output angle."""
        return self.stages[-1].direction == "forward"

    @property
    def stroke(self) -> tuple:
        """Range of q: a stage's stroke (a linkage's angles, a roller screw's ``stroke`` in m),
        else one turn for a cam, +-pi for an output angle, :data:`DEFAULT_LINEAR_STROKE` for
        an output travel."""
        for stage in self.stages:
            if stage.stroke is not None:
                return tuple(stage.stroke)
        if self.ends_in_cam:
            return (0.0, 2 * math.pi)
        return DEFAULT_LINEAR_STROKE if self.output_is_linear else (-math.pi, math.pi)

    @property
    def stroke_note(self) -> str | None:
        """Where :attr:`stroke` comes from when no stage gives it (a default), naming the key
        that sets it; None when a stage gives it or the chain ends in a cam (one turn)."""
        if self.ends_in_cam or any(stage.stroke is not None for stage in self.stages):
            return None
        from .operating_point import show_q
        lo, hi = self.stroke
        last = max((i for i, s in enumerate(self.stages) if not isinstance(s, Compliance)), default=0)
        what = "travel" if self.output_is_linear else "angle"
        return (f"stroke {show_q(lo, self.output_unit)} .. {show_q(hi, self.output_unit)}: the default for an "
                f"output {what} (the scene gives none; set it with stroke = [lowest, highest] on "
                f"drivetrain[{last}])")

    @property
    def output_unit(self) -> str:
        """Unit of q: ``"rad"`` (an output angle, or the cam angle of a cam chain) or
        ``"m"`` (a travel, e.g. the nut of a chain ending in a screw)."""
        if self.ends_in_cam:
            return "rad"
        return stage_units(self.stages)[0][-1]

    @property
    def output_is_linear(self) -> bool:
        """True when q is a travel (m): ratio in rad/m, inertia in kg, stiffness in N/m."""
        return self.output_unit == "m"

    @property
    def mid_stroke(self) -> float:
        """Default operating point q0 (rad)."""
        lo, hi = self.stroke
        return 0.5 * (lo + hi)

    @property
    def efficiency(self) -> float:
        """Product of the stages' efficiencies."""
        return float(np.prod([getattr(s, "efficiency", 1.0) for s in self.stages]))

    @property
    def backdrive_efficiency(self) -> float:
        """Product of the stages' back-drive efficiencies (the load driving the motor); zero
        or less: the chain is self-locking."""
        effs = [getattr(s, "backdrive_efficiency", getattr(s, "efficiency", 1.0)) for s in self.stages]
        if any(e <= 0 for e in effs):
            return 0.0
        return float(np.prod(effs))

    def kinematics(self, q) -> Kinematics:
        """Compose every stage's coordinates into jets in q."""
        q = np.atleast_1d(np.asarray(q, dtype=float))
        local = {}  # stage index -> its local coordinate as a jet in q
        z = Jet.linear(q, 1.0)
        for i, stage in enumerate(self.stages):
            if stage.direction == "forward":
                local[i] = z
                z = stage.map(z.value).compose(z)
        output = z
        sides, motor = self.output_sides(q)
        for i, stage in enumerate(self.stages):
            if stage.direction == "backward":
                local[i] = sides[i]
        elements, springs, lashes = [], [], []
        element_stage, spring_stage = [], []
        for i, stage in enumerate(self.stages):  # listed from the motor to the load
            n_e, n_s = len(elements), len(springs)
            self._collect(stage, local[i], elements, springs, lashes)
            element_stage += [i] * (len(elements) - n_e)
            spring_stage += [i] * (len(springs) - n_s)
        elements.append(Element("motor rotor", self.motor.rotor_inertia, motor))
        element_stage.append(-1)
        if self.load.inertia:
            elements.append(Element("load", self.load.inertia, output))
            element_stage.append(len(self.stages))
        return Kinematics(q, motor, output, tuple(elements), tuple(springs), tuple(lashes),
                          tuple(element_stage), tuple(spring_stage))

    def output_sides(self, q) -> tuple[list[Jet], Jet]:
        """The backward pass of :meth:`kinematics`: for each stage (listed from the motor to
        the load) the jet in q of its output side's coordinate (the input of the stage after
        it; q for the last), composed from the backward stages after it, and the motor
        angle's jet (every backward stage composed)."""
        q = np.atleast_1d(np.asarray(q, dtype=float))
        sides = [None] * len(self.stages)
        z = Jet.linear(q, 1.0)
        for i in reversed(range(len(self.stages))):
            sides[i] = z
            if self.stages[i].direction == "backward":
                z = self.stages[i].map(z.value).compose(z)
        return sides, z

    @staticmethod
    def _collect(stage, z: Jet, elements, springs, lashes) -> None:
        elements += [replace(e, u=e.u.compose(z)) for e in stage.elements(z.value)]
        springs += [replace(s, u=s.u.compose(z)) for s in stage.springs(z.value)]
        lashes += [Lash(b.label, b.lash, b.u.compose(z)) for b in stage.lashes(z.value)]

    def ratio(self, q) -> tuple[np.ndarray, np.ndarray]:
        """Overall ratio N(q) = d(motor angle)/dq and dN/dq."""
        m = self.kinematics(q).motor
        return m.d1, m.d2

    def jacobians(self, q):
        """Equivalent-element data: labels, masses M (diagonal), T = du/dq, T2 = d2u/dq2.

        Returns
        -------
        labels : tuple of str
        masses : numpy.ndarray, shape (n,)
        T, T2 : numpy.ndarray, shape (n, len(q))
        """
        kin = self.kinematics(q)
        labels = tuple(e.label for e in kin.elements)
        masses = np.array([e.inertia for e in kin.elements])
        return labels, masses, np.array([e.u.d1 for e in kin.elements]), np.array([e.u.d2 for e in kin.elements])

    def inertia(self, q) -> tuple[np.ndarray, np.ndarray]:
        """Reflected inertia at q, J(q) = T'MT, and dJ/dq = 2 T'M T2 (kg*m^2, kg*m^2/rad)."""
        _, m, t, t2 = self.jacobians(q)
        return m @ t**2, 2 * m @ (t * t2)

    def motor_inertia(self, q) -> np.ndarray:
        """Reflected inertia seen at the motor shaft, J(q) / N(q)^2."""
        n, _ = self.ratio(q)
        return self.inertia(q)[0] / n**2

    def reflected_inertias(self, q) -> ReflectedInertias:
        """Every element's inertia reflected to q and to the motor, with d/dq.

        J_i = m_i T_i^2 and dJ_i/dq = 2 m_i T_i T2_i at the output (seed 000); J_i / N^2
        and dJ_i/dq / N^2 - 2 J_i (dN/dq) / N^3 at the motor shaft. The elements sum to
        :meth:`inertia` and :meth:`motor_inertia`.

        Parameters
        ----------
        q : array_like
            Output coordinate(s) (rad, or m when :attr:`output_is_linear`).

        Returns
        -------
        ReflectedInertias
        """
        return reflect_elements(self.kinematics(q))

    def stiffness(self, q) -> StiffnessChain:
        """Each spring reflected to q and the series total."""
        kin = self.kinematics(q)
        if not kin.springs:
            inf = np.full_like(kin.q, np.inf)
            return StiffnessChain((), np.zeros((0, kin.q.size)), inf, np.zeros((0, kin.q.size)),
                                  np.zeros((0, kin.q.size)))
        ratio = np.array([np.abs(s.u.d1) for s in kin.springs])
        native = np.array([s.stiffness for s in kin.springs])
        k = native[:, None] * ratio**2
        compliance = 1.0 / k
        total = 1.0 / compliance.sum(axis=0)
        units = [stage_units(self.stages)[1][i] for i in kin.spring_stage]
        at_mid = [np.abs(s.u.d1[0]) for s in self.kinematics([self.mid_stroke]).springs]
        # one lever for every spring of the other kind (the mid-stroke ratio of the last of them,
        # nearest the output), so that the ratios between springs of that kind stay their own
        other = [c for u, c in zip(units, at_mid) if u != self.output_unit]
        lever = np.array([1.0 if u == self.output_unit else other[-1] for u in units])
        return StiffnessChain(tuple(s.label for s in kin.springs), k, total,
                              compliance / compliance.sum(axis=0), ratio, native,
                              tuple(STIFFNESS_UNIT[u] for u in units), lever)

    @cached_property
    def chain(self) -> Chain:
        """The lumped chain (:class:`~servo_toolkit.drivetrain.chain.Chain`): every inertia
        at its node, every compliance, lash and loss at its place; its ``two_mass(q)`` is the
        two-mass reduction the plant and the simulation use."""
        return Chain.from_drivetrain(self)

    def backlash(self, q) -> np.ndarray:
        """Total lost motion seen at q (rad): each lash divided by its ratio to q."""
        kin = self.kinematics(q)
        total = np.zeros_like(kin.q)
        for lash in kin.lashes:
            total = total + lash.lash / np.abs(lash.u.d1)
        return total

    def check(self) -> None:
        """Validate along the stroke: finite ratio and positive-definite inertia."""
        lo, hi = self.stroke
        if not (math.isfinite(lo) and math.isfinite(hi)):
            raise SceneError("drivetrain", f"the stroke must be finite (got {lo:g} .. {hi:g})")
        q = np.linspace(lo, hi, 181)
        with np.errstate(all="ignore"):
            n, _ = self.ratio(q)
            j, _ = self.inertia(q)
        if not np.all(np.isfinite(n)) or np.any(n == 0):
            raise SceneError("drivetrain", "the ratio is zero or not finite somewhere in the stroke")
        size = np.abs(n)
        if size.min() < RATIO_RANGE[0] or size.max() > RATIO_RANGE[1]:
            raise SceneError("drivetrain", f"the ratio from the motor to the output, {size.min():.3g} .. {size.max():.3g} "
                             f"motor rad per output {self.output_unit}, lies outside the {RATIO_RANGE[0]:g} .. "
                             f"{RATIO_RANGE[1]:g} a drivetrain model is conditioned for: check the stages' "
                             f"{ratio_keys(self)}")
        if not np.all(np.isfinite(j)):
            raise SceneError("drivetrain", "the reflected inertia is not finite somewhere in the stroke")
        if np.any(j <= 0):
            i = int(np.argmin(j))
            linear = self.output_unit == "m"
            at = f"{q[i] * 1e3:.2f} mm" if linear else f"{math.degrees(q[i]):.2f} deg"
            raise SceneError("drivetrain", f"reflected inertia is not positive at q = {at} "
                             f"({j[i]:.4g} {'kg' if linear else 'kg*m^2'}): mass matrix indefinite")
