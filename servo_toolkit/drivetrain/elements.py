"""Per-element reflected inertia, coordinate units and seed 001's neglect criterion.

Helpers of :mod:`servo_toolkit.drivetrain.reflected`, kept apart so that module stays small.

Coordinate units
----------------
Every coordinate of a chain is an angle (``"rad"``) or a travel (``"m"``). The motor shaft
is an angle; a gear train keeps angles, a ball or roller screw turns an angle into a nut
travel, a rocker linkage turns a travel back into an angle, a compliance keeps the unit of
the coordinate it sits on, and a cam chain is described in its input (cam) angle. A spring
has the unit of the coordinate it stretches: a gear mesh ``"rad"`` (N*m/rad), a screw's nut
and a link rod ``"m"`` (N/m).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: SI stiffness unit of a spring on a coordinate of the given unit
STIFFNESS_UNIT = {"rad": "N*m/rad", "m": "N/m"}
#: SI inertia unit of an element on a coordinate of the given unit
INERTIA_UNIT = {"rad": "kg*m^2", "m": "kg"}


def stage_units(stages) -> tuple[tuple, tuple]:
    """Unit of each stage's output-side coordinate and of its springs, motor to load.

    Returns
    -------
    output_units, spring_units : tuple of str
        ``"rad"`` or ``"m"`` per stage.
    """
    unit = "rad"  # the motor shaft
    outs, springs = [], []
    for stage in stages:
        _, out, spring = getattr(stage, "UNITS", ("rad", "rad", "rad"))  # the stage's own facts
        out = unit if out is None else out
        springs.append(out if spring is None else spring)
        outs.append(out)
        unit = out
    return tuple(outs), tuple(springs)


@dataclass(frozen=True)
class ReflectedInertias:
    """Each inertial element reflected to the output coordinate q and to the motor shaft.

    With T_i = du_i/dq, T2_i = d2u_i/dq2 (equivalent-element method, seed 000) and the
    overall ratio N = d(motor angle)/dq:

        J_i = m_i T_i^2,                      dJ_i/dq = 2 m_i T_i T2_i,
        Jm_i = J_i / N^2,                     dJm_i/dq = dJ_i/dq / N^2 - 2 J_i (dN/dq) / N^3.

    All derivatives are with respect to q (divide by N for the rate per motor radian).

    Attributes
    ----------
    labels : tuple of str
        One per element (gears, screw, nut, rod ends, rod rotation, output shaft, motor
        rotor, load).
    stage : tuple of int
        Index of the owning stage; -1 for the motor rotor, ``len(stages)`` for the load.
    output, output_dq : numpy.ndarray
        J_i and dJ_i/dq, shape (n_elements, n_q), in kg*m^2 (kg for a linear output) per
        unit of q.
    motor, motor_dq : numpy.ndarray
        Jm_i and dJm_i/dq at the motor shaft, kg*m^2 and kg*m^2 per unit of q.
    total, total_dq : numpy.ndarray
        Sums over the elements at the output: ``Drivetrain.inertia(q)``.
    motor_total, motor_total_dq : numpy.ndarray
        Sums at the motor shaft: ``Drivetrain.motor_inertia(q)`` and its derivative.
    """

    labels: tuple
    stage: tuple
    output: np.ndarray
    output_dq: np.ndarray
    motor: np.ndarray
    motor_dq: np.ndarray

    @property
    def total(self) -> np.ndarray:
        """J(q) = sum of J_i."""
        return self.output.sum(axis=0)

    @property
    def total_dq(self) -> np.ndarray:
        """dJ/dq."""
        return self.output_dq.sum(axis=0)

    @property
    def motor_total(self) -> np.ndarray:
        """J(q) / N(q)^2."""
        return self.motor.sum(axis=0)

    @property
    def motor_total_dq(self) -> np.ndarray:
        """d(J/N^2)/dq."""
        return self.motor_dq.sum(axis=0)

    def by_label(self) -> dict:
        """label -> (J_i, dJ_i/dq, Jm_i, dJm_i/dq)."""
        return {lab: (self.output[i], self.output_dq[i], self.motor[i], self.motor_dq[i])
                for i, lab in enumerate(self.labels)}


def reflect_elements(kin) -> ReflectedInertias:
    """:class:`ReflectedInertias` of a :class:`~servo_toolkit.drivetrain.reflected.Kinematics`."""
    m = np.array([e.inertia for e in kin.elements])[:, None]
    t = np.array([e.u.d1 for e in kin.elements])
    t2 = np.array([e.u.d2 for e in kin.elements])
    j, dj = m * t**2, 2 * m * t * t2
    n, dn = kin.motor.d1, kin.motor.d2
    return ReflectedInertias(tuple(e.label for e in kin.elements), tuple(kin.element_stage),
                             j, dj, j / n**2, dj / n**2 - 2 * j * dn / n**3)


@dataclass(frozen=True)
class NeglectCriterion:
    """Seed 001's two conditions for leaving a front stage out of the stiffness chain.

    Stiffnesses of different stages are compared in one unit, that of the output coordinate
    (N*m/rad for an output angle, N/m for an output travel): a spring on a coordinate of
    the output's unit keeps its own stiffness k_i and its ratio n_i = |du_i/dq|; a spring
    on a coordinate of the other kind (a nut or a rod in a rotary chain, a gear mesh in a
    linear one) is first expressed at the output's unit through one lever c for all of
    them, the ratio at mid-stroke of the last of them (nearest the output), c = n_last(q0):
    own stiffness K_i = k_i c^2, ratio rho_i(q) = n_i(q) / c. Then K_i rho_i^2 is always
    the stiffness reflected to the output, rho_i is a pure number, and the ratio between two
    springs of that kind (two gear meshes before a screw) stays their gear ratio.

    With those, for a stage i and a later stage j the compliance ratio is
    (K_j / K_i) / (rho_i / rho_j)^2. The seed's conditions are

    1. the later stages' ratio is large: rho_i / rho_j >= ``min_ratio`` for every later
       spring j (``later_ratio``, the smallest of them, per q);
    2. the front stiffness is within an order of magnitude of some later stage:
       K_i >= K_j / ``within`` for at least one later j (``stiffness_to_later``, the
       largest K_i / K_j).

    Together they bound the compliance of stage i by ``within / min_ratio^2`` (0.1 with
    the defaults) times that of the comparable later stage; the seed's gear train comes
    out near 1e-4 of the total. The last spring has no later stage: both flags are False.

    Attributes
    ----------
    own_stiffness : numpy.ndarray
        K_i, shape (n_springs,), in the output's stiffness unit.
    ratio : numpy.ndarray
        rho_i(q), shape (n_springs, n_q).
    later_ratio : numpy.ndarray
        min over later j of rho_i / rho_j, (n_springs, n_q); NaN for the last spring.
    stiffness_to_later : numpy.ndarray
        max over later j of K_i / K_j, (n_springs,); NaN for the last spring.
    ratio_large : numpy.ndarray of bool
        Condition 1 per q, (n_springs, n_q).
    stiffness_comparable : numpy.ndarray of bool
        Condition 2, (n_springs,).
    negligible : numpy.ndarray of bool
        Both conditions at every q, (n_springs,).
    min_ratio, within : float
        The thresholds used.
    """

    own_stiffness: np.ndarray
    ratio: np.ndarray
    later_ratio: np.ndarray
    stiffness_to_later: np.ndarray
    ratio_large: np.ndarray
    stiffness_comparable: np.ndarray
    negligible: np.ndarray
    min_ratio: float
    within: float


def neglect_criterion(own_stiffness, ratio, min_ratio: float = 10.0,
                      within: float = 10.0) -> NeglectCriterion:
    """Evaluate seed 001's conditions (see :class:`NeglectCriterion`).

    Parameters
    ----------
    own_stiffness : array_like, shape (n,)
        K_i in the output's stiffness unit, springs listed motor side first.
    ratio : array_like, shape (n, n_q)
        rho_i(q), dimensionless.
    min_ratio, within : float
        Thresholds of conditions 1 and 2.
    """
    k = np.asarray(own_stiffness, dtype=float)
    rho = np.atleast_2d(np.asarray(ratio, dtype=float))
    n, n_q = rho.shape
    later = np.full((n, n_q), np.nan)
    stiff = np.full(n, np.nan)
    for i in range(n - 1):
        later[i] = np.min(rho[i] / rho[i + 1:], axis=0)
        stiff[i] = np.max(k[i] / k[i + 1:])
    large = np.nan_to_num(later, nan=0.0) >= min_ratio
    comparable = np.nan_to_num(stiff, nan=0.0) >= 1.0 / within
    return NeglectCriterion(k, rho, later, stiff, large, comparable,
                            comparable & np.all(large, axis=-1), float(min_ratio), float(within))
