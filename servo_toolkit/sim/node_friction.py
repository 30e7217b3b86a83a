"""Friction at the full chain's intermediate nodes: the parameter block of the stages'
friction that acts at a kept node between the motor side and the load.

A stage's friction acts at the chain node carrying its output members
(:func:`~servo_toolkit.drivetrain.stage_friction.stage_nodes`). In the full chain
(:mod:`.chain_model`) a node with inertia between the motor side and the load is a state of
its own, and its stages' friction stays there, reflected to the node's coordinate
(:func:`~servo_toolkit.drivetrain.stage_friction.node_friction`): it slides with the motor's
law and sticks by its own breakaway level (``node_moment``, ``servo_toolkit/_physics/friction.h``). The block
(``NODE_FRIC``, :mod:`.layout`) holds per intermediate node [Tc, Ts, 1 / v_st, B, direction];
with friction that does not hold (``ModelOptions.friction`` "smooth" or "off") only the
viscous part stays, as it does for the load.
"""

from __future__ import annotations

import math

import numpy as np

from ..drivetrain.stage_friction import node_friction
from . import layout as lo


def with_node_friction(P, scene, q0: float, nodes, options, unit: str, notes: list):
    """Append the intermediate nodes' friction block to P (unchanged when none carries any).

    Parameters
    ----------
    P : numpy.ndarray
        The parameters so far.
    scene : Scene
    q0 : float
        Operating point of the reflection.
    nodes : sequence of int
        The full chain's kept nodes (motor side first, load last).
    options : ModelOptions
    unit : str
        The output's force unit ("N*m" or "N") for the notes.
    notes : list of str
        Receives one line per node carrying friction.

    Returns
    -------
    numpy.ndarray
    """
    mid = list(nodes[1:-1])
    at = node_friction(scene, q0, mid)
    if not at:
        return P
    holds = options.friction == "stick"
    block = np.zeros(lo.NF_STRIDE * len(mid))
    for j, node in enumerate(mid):
        if node not in at:
            continue
        tc, ts, vs, b, exact, keys = at[node]
        row = block[lo.NF_STRIDE * j:lo.NF_STRIDE * (j + 1)]
        row[lo.NF_VISC] = b
        if holds:
            row[lo.NF_TC], row[lo.NF_TS] = tc, ts
            row[lo.NF_INV_VS] = 1.0 / vs if vs > 0 else math.inf
        levels = (f"Coulomb {tc:.4g} {unit}, breakaway {ts:.4g} {unit}" if holds else
                  "its Coulomb and static friction left out (friction that holds only)")
        notes.append(f"friction of {', '.join(keys)} at chain node {node}, reflected to the node at q0: {levels}, "
                     f"viscous {b:.4g} {unit}*s/{'m' if unit == 'N' else 'rad'}"
                     + ("" if exact or not holds else f" (Stribeck speeds differ: their drops' weighted mean "
                                                      f"{vs:.4g})"))
    P = np.asarray(P, dtype=float)
    P[lo.NODE_FRIC] = P.size
    if holds and np.any(block[lo.NF_TS::lo.NF_STRIDE] > 0):
        P[lo.STICK] = 1.0  # the motor and the load may carry none
    return np.concatenate([P, block])


__all__ = ["with_node_friction"]
