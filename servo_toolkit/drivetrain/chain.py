"""One lumped model of the drivetrain: every inertia at its node, every compliance, lash and
loss at its place.

The chain is built once from a drivetrain, as Simscape Driveline and
Modelica.Mechanics.Rotational build theirs: inertias joined by spring-dampers and ideal,
lossy gears. Walking the stages from the motor to the load,

- the motor rotor sits on node 0;
- a stage's *input members* (``Element.member == "input"``: the first gear of a gear train,
  a screw, the rod end at the nut) stay on the current node, on the motor side of the stage's
  compliance and before its loss (a pinion turning with the motor stays on the motor side
  of its mesh spring);
- the stage's loss acts on the torque its input members pass on (its efficiency on the
  torque transmitted through the stage, never on the torque accelerating what is before it);
- each compliance of the stage (gear mesh, screw/nut axial, rod, housing, coupling) ends the
  current node: the spring joins it to a new node;
- its *output members* (the gear wheel, the nut, the rocker arm and output shaft) sit on the
  node after the spring. A gear wheel of a rigid gear followed by a compliant shaft is thus
  on the motor side of that shaft;
- the load sits on the last node.

Coordinates: every node's coordinate is referred to the output coordinate q (with the springs
undeflected every node moves as q). An element of inertia m moving with u(q) adds
m (du/dq)^2 to its node's inertia; a spring of stiffness k on coordinate u acts between its
two nodes with k (du/dq)^2 (seed 001, eq 8). Hence the mass matrix M(q) (diagonal) and the
stiffness matrix K(q) (tridiagonal) of the n-node chain at q. A node without inertia (two
springs in series) is condensed statically.

Losses: element e lies beyond the losses of the stages before it (and of its own stage when
it is an output member); Pi_e is the product of their forward efficiencies. With the motor
driving the load, the torque equation of a rigid chain is
sum_e J_e (eta / Pi_e) q'' = eta N tau_shaft + M_ext: the loss never acts on the torque that
accelerates the rotor itself (Modelica's LossyGear). In general the driving-mode chain is
the lossless one with each element's inertia weighted by eta / Pi_e and each spring by
eta / Pi_s (Pi_s the losses before it), the motor torque taken as eta N tau and the output's
torque as is: multiply each node's equation by eta / Pi to see it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import linalg

from .elements import STIFFNESS_UNIT, stage_units

#: scene key of a stage's free play, by stage class (error messages)
_LASH_KEYS = {"Cam": "clearance"}
#: node inertias at or below this fraction of the total are condensed statically
_MASSLESS = 1e-12


@dataclass(frozen=True)
class TwoMassSplit:
    """Motor-side and load-side inertia (reflected to the output) and the stiffness between
    them (the springs' series stiffness of :meth:`Chain.node_split`, the model's K = w_a^2 J2
    of :meth:`Chain.two_mass`), arrays over q (kg*m^2, kg*m^2, N*m/rad; kg and N/m for an
    output travel);
    ``spring`` names the most compliant spring where the chain is split (empty when the chain
    is rigid); ``last_motor_node`` is the chain's last node on the motor side, per q."""

    motor_side: np.ndarray
    load_side: np.ndarray
    stiffness: np.ndarray
    spring: tuple
    last_motor_node: np.ndarray = None


@dataclass(frozen=True)
class ChainElement:
    """An inertial element at its node: ``stage`` -1 for the rotor, ``len(stages)`` for the
    load; ``loss`` is Pi_e, the product of the forward efficiencies before it; ``past_loss``
    says whether it sits beyond its own stage's loss (an output member, the load) or before it
    (an input member: a pinion, a screw; the rotor)."""

    label: str
    stage: int
    node: int
    loss: float
    past_loss: bool = True


@dataclass(frozen=True)
class ChainSpring:
    """A compliance between ``nodes`` (i, i + 1): its own stiffness in ``unit`` and the damping
    ratio its stage gives it (None: the model's default, :mod:`.chain_damping`)."""

    label: str
    stage: int
    stiffness: float
    unit: str
    nodes: tuple
    damping_ratio: float | None = None


@dataclass(frozen=True)
class ChainLash:
    """A free play at its place: ``spring`` is the index of the compliance it sits in, None for
    a lash in a rigid stage; ``key`` is its scene key (``drivetrain[i].backlash``); ``lash``
    is the total play in ``unit`` (rad or m)."""

    label: str
    stage: int
    lash: float
    key: str
    spring: int | None
    unit: str = "rad"

    @property
    def shown(self) -> str:
        """The total play in degrees or millimetres."""
        return f"{math.degrees(self.lash):.4g} deg" if self.unit == "rad" else f"{self.lash * 1e3:.4g} mm"


@dataclass(frozen=True)
class Chain:
    """The lumped chain of a drivetrain (see the module docstring).

    Attributes
    ----------
    drivetrain : Drivetrain
    elements : tuple of ChainElement
        In the order of ``drivetrain.kinematics(q).elements``.
    springs : tuple of ChainSpring
        Motor side first; spring i joins nodes i and i + 1.
    lashes : tuple of ChainLash
    n_nodes : int
    """

    drivetrain: object
    elements: tuple
    springs: tuple
    lashes: tuple
    n_nodes: int

    @classmethod
    def from_drivetrain(cls, drivetrain) -> "Chain":
        """Place every element, spring, lash and loss of ``drivetrain``."""
        kin = drivetrain.kinematics([drivetrain.mid_stroke])
        stages = drivetrain.stages
        out_units, units = stage_units(stages)
        owner = np.asarray(kin.element_stage)
        spring_owner = list(kin.spring_stage)
        node, eff = 0, 1.0
        placed = {}
        springs, lashes = [], []
        for k, stage in enumerate(stages):
            mine = list(np.flatnonzero(owner == k))
            for i in mine:
                if kin.elements[i].member == "input":
                    placed[i] = (node, eff, False)
            for j in [j for j, s in enumerate(spring_owner) if s == k]:
                springs.append(ChainSpring(kin.springs[j].label, k, kin.springs[j].stiffness,
                                           STIFFNESS_UNIT[units[k]], (node, node + 1),
                                           kin.springs[j].damping_ratio))
                node += 1
            eff *= float(getattr(stage, "efficiency", 1.0))
            for i in mine:
                if i not in placed:
                    placed[i] = (node, eff, True)
            at = len(springs) - 1 if spring_owner.count(k) else None
            key = f"drivetrain[{k}].{_LASH_KEYS.get(type(stage).__name__, 'backlash')}"
            lashes += [ChainLash(b.label, k, b.lash, key, at, out_units[k]) for b in stage.lashes(np.zeros(1))]
        elements = []
        for i, e in enumerate(kin.elements):
            if owner[i] < 0:
                where = (0, 1.0, False)  # the rotor
            elif owner[i] >= len(stages):
                where = (node, eff, True)  # the load
            else:
                where = placed[i]
            elements.append(ChainElement(e.label, int(owner[i]), *where))
        return cls(drivetrain, tuple(elements), tuple(springs), tuple(lashes), node + 1)

    # --- along the stroke ---------------------------------------------------------------

    @property
    def rigid(self) -> bool:
        """True when the chain has no compliance."""
        return not self.springs

    @property
    def rigid_lashes(self) -> tuple:
        """Lashes in stages without a compliance of their own."""
        return tuple(b for b in self.lashes if b.spring is None)

    def element_inertias(self, q) -> np.ndarray:
        """Each element's inertia reflected to q, m_e (du_e/dq)^2, shape (n_elements, n_q)."""
        kin = self.drivetrain.kinematics(q)
        return np.array([e.inertia * e.u.d1**2 for e in kin.elements])

    def node_jets(self, q, weights=None) -> tuple[np.ndarray, np.ndarray]:
        """Each node's inertia along q and its derivative, J_j(q) = sum_e w_e m_e (du_e/dq)^2
        and dJ_j/dq = sum_e w_e 2 m_e (du_e/dq) (d2u_e/dq2), shapes (n_nodes, n_q).

        ``weights``: one per element (default 1; the loss fractions of
        :meth:`loss_fractions` give each node's inertia before the losses, J_w,j)."""
        kin = self.drivetrain.kinematics(q)
        w = np.ones(len(self.elements)) if weights is None else np.asarray(weights, dtype=float)
        value = np.zeros((self.n_nodes, kin.q.size))
        slope = np.zeros_like(value)
        for e, ce, we in zip(kin.elements, self.elements, w):
            value[ce.node] += we * e.inertia * e.u.d1**2
            slope[ce.node] += we * 2.0 * e.inertia * e.u.d1 * e.u.d2
        return value, slope

    def loss_fractions(self) -> np.ndarray:
        """Each element's share of the chain's loss, (1 - eta / Pi_e) / (1 - eta): 1 before
        every loss (the rotor, a pinion), 0 beyond them all; zeros for a lossless chain."""
        eta = self.efficiency
        if eta >= 1.0:
            return np.zeros(len(self.elements))
        return np.array([(1.0 - eta / e.loss) / (1.0 - eta) for e in self.elements])

    @property
    def efficiency(self) -> float:
        """eta, the product of every stage's forward efficiency."""
        return float(np.prod([getattr(s, "efficiency", 1.0) for s in self.drivetrain.stages]))

    def node_inertias(self, q, driving: bool = False) -> np.ndarray:
        """Each node's inertia at q, shape (n_nodes, n_q).

        ``driving``: each element weighted by eta / Pi_e, the chain the motor drives with the
        output's torque taken as is and the motor torque as eta N tau (module docstring)."""
        j = self.element_inertias(q)
        if driving:
            eta = self.efficiency
            j = j * np.array([eta / e.loss for e in self.elements])[:, None]
        out = np.zeros((self.n_nodes, j.shape[1]))
        for e, row in zip(self.elements, j):
            out[e.node] += row
        return out

    def spring_stiffness(self, q, driving: bool = False) -> np.ndarray:
        """Each spring reflected to q, k (du/dq)^2, shape (n_springs, n_q); ``driving``: weighted
        by eta / Pi of the losses before it (a stage's loss comes before its own spring)."""
        kin = self.drivetrain.kinematics(q)
        k = np.array([s.stiffness * s.u.d1**2 for s in kin.springs]).reshape(len(self.springs), -1)
        if driving and self.springs:
            eta, before = self.efficiency, self.spring_losses()
            k = k * (eta / before)[:, None]
        return k

    def spring_losses(self) -> np.ndarray:
        """Pi of each spring: the product of the forward efficiencies of the losses before it,
        its own stage's included."""
        stages = self.drivetrain.stages
        return np.array([float(np.prod([getattr(st, "efficiency", 1.0) for st in stages[:s.stage + 1]]))
                         for s in self.springs])

    def loss_inertia(self, q, last_node: int | None = None) -> np.ndarray:
        """J_w(q) = sum_e J_e (1 - eta / Pi_e) / (1 - eta): the inertia whose torque the
        losses do not see, as a share of the chain's loss (eta the product of every stage's
        forward efficiency). Driving, the chain's inertia at q is J - (1 - eta) J_w; with one
        lossy stage J_w is the inertia before its loss (the rotor and the input members).
        Zero for a lossless chain. ``last_node``: only the elements on the nodes up to it (the
        motor side of a two-mass split)."""
        j = self.element_inertias(q)
        last = self.n_nodes if last_node is None else last_node
        weight = np.where([e.node <= last for e in self.elements], self.loss_fractions(), 0.0)
        return weight @ j

    # --- at one operating point -----------------------------------------------------------

    def mass_matrix(self, q: float, driving: bool = False) -> np.ndarray:
        """M(q): the node inertias on the diagonal, shape (n_nodes, n_nodes)."""
        return np.diag(self.node_inertias([q], driving)[:, 0])

    def stiffness_matrix(self, q: float, driving: bool = False) -> np.ndarray:
        """K(q): each spring k_s between its nodes, shape (n_nodes, n_nodes)."""
        K = np.zeros((self.n_nodes, self.n_nodes))
        for s, k in zip(self.springs, self.spring_stiffness([q], driving)[:, 0]):
            a, b = s.nodes
            K[a, a] += k
            K[b, b] += k
            K[a, b] -= k
            K[b, a] -= k
        return K

    def condensed(self, q: float, driving: bool = False):
        """``(M, K, nodes)``: the matrices with every node without inertia condensed
        statically (K_aa - K_ab K_bb^-1 K_ba); ``nodes`` are the kept node indices."""
        M, K = self.mass_matrix(q, driving), self.stiffness_matrix(q, driving)
        m = np.diag(M)
        keep = np.flatnonzero(np.abs(m) > _MASSLESS * np.sum(np.abs(m)))
        drop = np.setdiff1d(np.arange(self.n_nodes), keep)
        if drop.size:
            K = K[np.ix_(keep, keep)] - K[np.ix_(keep, drop)] @ np.linalg.solve(
                K[np.ix_(drop, drop)], K[np.ix_(drop, keep)])
        return M[np.ix_(keep, keep)], K, keep

    def eigenfrequencies(self, q: float, driving: bool = False) -> np.ndarray:
        """Undamped modes of the free chain (rad/s, ascending), the rigid-body mode left
        out: det(K - w^2 M) = 0."""
        if self.rigid:
            return np.zeros(0)
        M, K, _ = self.condensed(q, driving)
        w2 = np.sort(linalg.eigh(K, M, eigvals_only=True))[1:]
        return np.sqrt(np.clip(w2, 0.0, None))

    def antiresonances(self, q: float, driving: bool = False) -> np.ndarray:
        """Modes with the motor node held (rad/s, ascending): the zeros of the motor speed's
        response to the motor torque."""
        if self.rigid:
            return np.zeros(0)
        M, K, _ = self.condensed(q, driving)
        return np.sqrt(np.clip(np.sort(linalg.eigh(K[1:, 1:], M[1:, 1:], eigvals_only=True)), 0.0, None))

    # --- reductions -----------------------------------------------------------------------

    def node_split(self, q, driving: bool = False) -> TwoMassSplit:
        """The chain split at its most compliant spring (the node rule of :meth:`two_mass`).

        At each q, the spring with the largest share of the series compliance divides the
        nodes: those before it are the motor side, those after it the load side (each
        element on its own node, so a pinion stays with the motor). The series stiffness of
        every spring (their static condensation) acts between the two inertias. Exact for
        a chain with one compliance; J_motor_side + J_load_side = J(q). ``driving``: the
        motor side's elements weighted by eta / Pi_e (losses beyond the split lumped at it).
        """
        nodes = self.node_inertias(q)
        n_q = nodes.shape[1]
        weighted = self.node_inertias(q, True) if driving else nodes
        if self.rigid:
            return TwoMassSplit(weighted.sum(axis=0), np.zeros(n_q), np.full(n_q, np.inf), ("",) * n_q,
                                np.full(n_q, self.n_nodes - 1))
        k = self.spring_stiffness(q)
        compliance = 1.0 / k
        worst = np.argmax(compliance, axis=0)
        last_motor_node = np.array([self.springs[w].nodes[0] for w in worst])
        motor = np.arange(self.n_nodes)[:, None] <= last_motor_node[None, :]
        return TwoMassSplit(np.sum(np.where(motor, weighted, 0.0), axis=0),
                            np.sum(np.where(motor, 0.0, nodes), axis=0),
                            1.0 / compliance.sum(axis=0), tuple(self.springs[w].label for w in worst),
                            last_motor_node)

    def two_mass(self, q, driving: bool = False) -> TwoMassSplit:
        """Two-mass reduction with the chain's lowest resonance and antiresonance.

        At each q the two-mass model keeps the chain's total inertia J, its lowest mode w_r
        and its lowest antiresonance w_a (motor held): J1 = J (w_a / w_r)^2, J2 = J - J1,
        K = w_a^2 J2 (:meth:`modal_two_mass`). For a chain with one compliance these are its
        two sides and its spring (the node split, :meth:`node_split`); with several
        compliances the notch of a design on it sits on the chain's real lowest mode, where
        the node split's series stiffness misses it when a large inertia sits between
        comparable springs. ``spring`` and ``last_motor_node`` come from the node split.

        ``driving``: of the driving-mode chain (each element and spring weighted by the
        losses before it, the motor torque reaching the output as eta N tau): the loss never
        acts on the torque that accelerates the rotor.
        """
        split = self.node_split(q, driving)
        if self.rigid:
            return split
        qs = np.atleast_1d(np.asarray(q, dtype=float))
        jkk = np.array([self.modal_two_mass(x, driving) for x in qs]).T
        return TwoMassSplit(jkk[0], jkk[1], jkk[2], split.spring, split.last_motor_node)

    def modal_two_mass(self, q: float, driving: bool = False) -> tuple[float, float, float]:
        """``(J1, J2, K)`` of the two-mass model with the chain's total inertia, its lowest
        resonance w_r and lowest antiresonance w_a: J1 = J w_a^2 / w_r^2, K = w_a^2 J2."""
        total = float(self.node_inertias([q], driving).sum())
        if self.rigid:
            return total, 0.0, math.inf
        wr, wa = self.eigenfrequencies(q, driving)[0], self.antiresonances(q, driving)[0]
        j1 = total * (wa / wr) ** 2
        return j1, total - j1, wa**2 * (total - j1)

    def describe(self) -> list[str]:
        """One line per node: its elements, and the spring after it."""
        lines = []
        for n in range(self.n_nodes):
            names = [e.label for e in self.elements if e.node == n] or ["(no inertia)"]
            lines.append(f"node {n}: " + ", ".join(names))
            lines += [f"  spring {s.label} ({s.unit})" for s in self.springs if s.nodes[0] == n]
        return lines


__all__ = ["Chain", "ChainElement", "ChainLash", "ChainSpring", "TwoMassSplit"]
