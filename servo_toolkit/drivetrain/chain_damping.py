"""The chain's segments between the nodes that carry inertia, and the damping of each.

Nodes without inertia are condensed (:meth:`~servo_toolkit.drivetrain.chain.Chain.condensed`):
the springs between two consecutive kept nodes act in series, a *segment*. Each segment has
its own viscous damper, stiffness-proportional along the stroke: its force is
``beta_s k_s(q) z'`` (the elasto-backlash contact's damper part in the compiled model).

A damper per compliance cannot give every mode the same damping ratio (a damper strong enough
for a low mode damps a higher mode that deforms the same spring in proportion to that mode's
frequency), so the scene states what each compliance does to the mode it *dominates*:

- the stage key ``damping_ratio`` gives each compliance its ratio zeta_i (default: the
  model's structural damping ratio); a segment of several springs in series takes their
  compliance-weighted mean, sum (zeta_i / k_i) / sum (1 / k_i);
- the undamped chain's modes k at q0 (rigid-body mode left out) share their strain energy
  among the segments, e_sk = k_s (phi_a - phi_b)^2 / phi' K phi (each row sums to 1);
- segment s dominates the mode k(s) holding the largest share of its energy in s, max_k e_sk
  (ties: the lowest such mode);
- ``beta_s = 2 zeta_s / (w_k(s) E_k(s))``, E_k the shares of mode k in the segments that
  dominate it: mode k's modal damping ratio, (w_k / 2) sum_s beta_s e_sk, is then the
  energy-weighted mean of those segments' ratios, plus what the other segments' dampers add.

With one compliance this is the damper of the two-mass mode, ``2 zeta / w_n`` times K, the
classical stiffness-proportional structural damping; when every segment dominates its own
mode (well separated modes, each in one compliance) each mode has its compliance's ratio.
The two-mass reduction keeps the lowest mode's modal damping ratio (:attr:`ChainDamping.lowest_ratio`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import linalg

#: shares within this relative distance of the largest count as a tie (the lowest mode wins)
TIE = 1e-9


def kept_nodes(chain, q0: float) -> np.ndarray:
    """The chain's nodes with inertia at q0 (the others are condensed)."""
    return chain.condensed(q0)[2]


def segments(chain, q0: float) -> list[tuple[int, int]]:
    """(first, last) node of each segment between consecutive kept nodes; segment s holds the
    chain's springs first .. last - 1."""
    keep = kept_nodes(chain, q0)
    return [(int(a), int(b)) for a, b in zip(keep[:-1], keep[1:])]


def segment_stiffness(chain, q, segs, driving: bool = False) -> np.ndarray:
    """Series stiffness of each segment along q, shape (n_segments, n_q) (``driving``: each
    spring weighted by the losses before it, :meth:`Chain.spring_stiffness`)."""
    k = chain.spring_stiffness(q, driving)
    return np.array([1.0 / np.sum(1.0 / k[a:b], axis=0) for a, b in segs])


def segment_ratios(chain, q0: float, default: float, segs=None) -> np.ndarray:
    """Each segment's damping ratio: its springs' ratios (``default`` where the scene gives
    none) weighted by their compliance at q0."""
    segs = segments(chain, q0) if segs is None else segs
    k = chain.spring_stiffness([q0])[:, 0]
    zeta = np.array([default if s.damping_ratio is None else s.damping_ratio for s in chain.springs])
    return np.array([np.sum(zeta[a:b] / k[a:b]) / np.sum(1.0 / k[a:b]) for a, b in segs])


@dataclass(frozen=True)
class ChainDamping:
    """The dampers of the chain's segments at an operating point (see the module docstring).

    Attributes
    ----------
    segments : tuple of (int, int)
        First and last node of each segment.
    ratios : numpy.ndarray
        zeta_s, the damping ratio each segment gives the mode it dominates.
    frequencies : numpy.ndarray
        w_k, the undamped modes (rad/s, ascending; the rigid-body mode left out).
    shares : numpy.ndarray
        e_sk, shape (n_modes, n_segments): mode k's strain energy in segment s.
    dominated : numpy.ndarray
        k(s), the mode each segment dominates.
    beta : numpy.ndarray
        beta_s (s): segment s's damper is beta_s times its stiffness.
    """

    segments: tuple
    ratios: np.ndarray
    frequencies: np.ndarray
    shares: np.ndarray
    dominated: np.ndarray
    beta: np.ndarray

    @property
    def modal_ratios(self) -> np.ndarray:
        """Each mode's modal damping ratio, (w_k / 2) sum_s beta_s e_sk (phi' C phi over
        2 w_k phi' M phi; exact for the eigenvalues when the damping is proportional)."""
        return 0.5 * self.frequencies * (self.shares @ self.beta)

    @property
    def lowest_ratio(self) -> float:
        """The lowest mode's modal damping ratio: the two-mass reduction's."""
        return float(self.modal_ratios[0])

    def matrix(self, stiffness) -> np.ndarray:
        """C = sum_s beta_s K_s for the segment stiffnesses ``stiffness`` (n_segments,) over
        the kept nodes."""
        n = len(self.segments) + 1
        C = np.zeros((n, n))
        for s, (b, k) in enumerate(zip(self.beta, stiffness)):
            C[s:s + 2, s:s + 2] += b * k * np.array([[1.0, -1.0], [-1.0, 1.0]])
        return C


def chain_damping(chain, q0: float, default_ratio: float, driving: bool = True,
                  stiffness_scale: float = 1.0) -> ChainDamping:
    """The segments' dampers at q0 (module docstring).

    Parameters
    ----------
    chain : Chain
    q0 : float
        Operating point.
    default_ratio : float
        Damping ratio of a compliance whose stage gives none.
    driving : bool
        Modes of the driving-mode chain (each inertia and spring weighted by the losses before
        it), as the plant and the simulation have them.
    stiffness_scale : float
        Multiplies every spring (the simulation's ``ModelOptions.stiffness_scale``).

    Returns
    -------
    ChainDamping
    """
    segs = segments(chain, q0)
    zeta = segment_ratios(chain, q0, default_ratio, segs)
    k = segment_stiffness(chain, [q0], segs, driving)[:, 0] * stiffness_scale
    m = chain.node_inertias([q0], driving)[kept_nodes(chain, q0), 0]
    n = len(segs)
    K = np.zeros((n + 1, n + 1))
    for s, ks in enumerate(k):
        K[s:s + 2, s:s + 2] += ks * np.array([[1.0, -1.0], [-1.0, 1.0]])
    w2, phi = linalg.eigh(K, np.diag(m))
    w = np.sqrt(np.clip(w2[1:], 0.0, None))
    phi = phi[:, 1:]
    strain = k[None, :] * np.diff(phi, axis=0).T ** 2  # (n_modes, n_segments)
    shares = strain / strain.sum(axis=1, keepdims=True)
    dominated = np.array([int(np.flatnonzero(col >= (1.0 - TIE) * col.max())[0]) for col in shares.T])
    held = np.zeros(n)
    np.add.at(held, dominated, shares[dominated, np.arange(n)])
    beta = 2.0 * zeta / (w[dominated] * held[dominated])
    return ChainDamping(tuple(segs), zeta, w, shares, dominated, beta)


__all__ = ["ChainDamping", "TIE", "chain_damping", "kept_nodes", "segment_ratios", "segment_stiffness",
           "segments"]
