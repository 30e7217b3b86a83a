"""The full linear plant of the drivetrain's lumped chain: every node, every mode.

The chain (:mod:`servo_toolkit.drivetrain.chain`) at q0 in its driving-mode form (each
element's inertia and each spring weighted by the losses before it, the motor torque reaching
the output as eta N Kt i) gives M, K; nodes without inertia are condensed statically.
Each segment between two kept nodes has its own damper, beta_s times its stiffness, with
beta_s from the damping ratio of the mode it dominates
(:mod:`servo_toolkit.drivetrain.chain_damping`, as the compiled model has it); the two-mass
plant keeps the lowest mode's damping ratio. The motor's viscous friction b N^2 acts on
node 0, the load's damping and hinge stiffness on the last node.

Signals: inputs ``u`` (V) and ``tau_ext`` (N*m at the output, on the last node); states
``theta[j]``, ``omega[j]`` per kept node j (referred to the output), and ``i`` (A) with
inductance; outputs :data:`~servo_toolkit.plant.linear.PLANT_OUTPUTS` (``theta`` and
``omega`` of the last node, ``omega_m`` = N omega[0], ``i``), then ``theta[j]`` of every node.
"""

from __future__ import annotations

import numpy as np

from ..drivetrain.chain_damping import chain_damping, segment_stiffness
from ..drivetrain.stage_friction import lumped_friction
from ..errors import SceneError
from ..lti.system import StateSpace, ss
from .signals import DEFAULT_STRUCTURAL_DAMPING, PLANT_OUTPUTS


def chain_plant(scene, q0=None, inductance: bool = True,
                structural_damping: float = DEFAULT_STRUCTURAL_DAMPING) -> "control.StateSpace":
    """Voltage-driven n-mass plant of the scene's drivetrain chain at ``q0`` (default
    mid-stroke); ``plant(scene, model="chain")`` gives it, or the rigid plant for a rigid
    chain.

    Parameters
    ----------
    scene : Scene
    q0 : float, optional
        Operating point (rad, or m for an output travel).
    inductance : bool
        Armature inductance as a state (False: i = (u - Ke omega_m) / R).
    structural_damping : float
        Damping ratio of each compliance whose stage gives none (``damping_ratio``), in the
        mode it dominates.

    Returns
    -------
    control.StateSpace
    """
    return chain_plant_block(scene, q0, inductance, structural_damping).to_control()


def chain_plant_block(scene, q0=None, inductance: bool = True,
                      structural_damping: float = DEFAULT_STRUCTURAL_DAMPING) -> StateSpace:
    """:func:`chain_plant` as the toolkit's own state-space block."""
    drive = scene.drivetrain
    chain = drive.chain
    q0 = drive.mid_stroke if q0 is None else float(q0)
    if chain.rigid:
        raise SceneError("drivetrain", "an n-mass plant needs a compliance; this chain is rigid")
    M, K, nodes = chain.condensed(q0, driving=True)
    if nodes[0] != 0:
        raise SceneError("motor.rotor_inertia", "the chain's motor node has no inertia")
    m = np.diag(M)
    n_n = m.size
    damping = chain_damping(chain, q0, structural_damping)
    C = damping.matrix(segment_stiffness(chain, [q0], damping.segments, driving=True)[:, 0])
    motor, load = lumped_friction(scene, q0, False, [])  # the stages' viscous friction at the motor or the load
    n = abs(float(drive.ratio([q0])[0][0]))
    gain = chain.efficiency * n * motor.torque_constant
    Kx, Cx = K.copy(), C.copy()
    Cx[0, 0] += motor.viscous_friction * n**2
    Kx[-1, -1] += load.hinge_stiffness
    Cx[-1, -1] += load.damping
    ind = inductance and motor.inductance > 0
    nx = 2 * n_n + (1 if ind else 0)
    A = np.zeros((nx, nx))
    A[:n_n, n_n:2 * n_n] = np.eye(n_n)
    A[n_n:2 * n_n, :n_n] = -Kx / m[:, None]
    A[n_n:2 * n_n, n_n:2 * n_n] = -Cx / m[:, None]
    B = np.zeros((nx, 2))
    B[2 * n_n - 1, 1] = 1.0 / m[-1]
    n_out = len(PLANT_OUTPUTS) + n_n
    Cm, D = np.zeros((n_out, nx)), np.zeros((n_out, 2))
    Cm[0, n_n - 1] = 1.0                 # theta: the last node
    Cm[1, n_n] = n                       # omega_m = N omega[0]
    Cm[3, 2 * n_n - 1] = 1.0             # omega: the last node
    Cm[4:, :n_n] = np.eye(n_n)
    w0 = n_n                             # index of omega[0]
    if ind:
        A[w0, nx - 1] = gain / m[0]
        A[nx - 1, w0] = -motor.back_emf_constant * n / motor.inductance
        A[nx - 1, nx - 1] = -motor.resistance / motor.inductance
        B[nx - 1, 0] = 1.0 / motor.inductance
        Cm[2, nx - 1] = 1.0
    else:  # i = (u - Ke N omega[0]) / R
        A[w0, w0] -= gain * motor.back_emf_constant * n / (motor.resistance * m[0])
        B[w0, 0] += gain / (motor.resistance * m[0])
        Cm[2, w0] = -motor.back_emf_constant * n / motor.resistance
        D[2, 0] = 1.0 / motor.resistance
    states = [f"theta[{j}]" for j in nodes] + [f"omega[{j}]" for j in nodes] + (["i"] if ind else [])
    outputs = list(PLANT_OUTPUTS) + [f"theta[{j}]" for j in nodes]
    return ss(A, B, Cm, D, inputs=["u", "tau_ext"], outputs=outputs, states=states, name="chain_plant")


__all__ = ["chain_plant", "chain_plant_block"]
