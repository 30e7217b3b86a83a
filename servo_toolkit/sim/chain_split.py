"""The compiled model's share of the drivetrain chain: its two-mass split, its loss placement
and its refusal of a free play without a compliance (see :mod:`servo_toolkit.drivetrain.chain`).
"""

from __future__ import annotations

from ..errors import SceneError
from . import layout as lo


def load_split(drive, q0: float):
    """The chain's two-mass reduction at q0 as the compiled model uses it.

    Returns
    -------
    load_inertia : float
        J2 of :meth:`~servo_toolkit.drivetrain.chain.Chain.two_mass` at q0 (held constant
        along the stroke).
    names : tuple of str
        The elements beyond the node split (the load side's members).
    last_motor_node : int
        The node split's last motor-side node (whose elements' J_w the loss spares).
    stiffness_factor : float
        The reduction's stiffness over the series stiffness at q0: the stroke table of the
        series stiffness is scaled by it, so that the model's mode at q0 is the chain's.
    """
    chain = drive.chain
    split = chain.two_mass([q0])
    last = int(split.last_motor_node[0])
    names = tuple(e.label for e in chain.elements if e.node > last)
    factor = 1.0
    if not chain.rigid:
        factor = float(split.stiffness[0] / chain.node_split([q0]).stiffness[0])
    return float(split.load_side[0]), names, last, factor


#: smallest back-drive efficiency modelled (a self-locking chain's is 0 or less)
MIN_BACKDRIVE = 0.1
#: torque scale of the smooth sign of the transmitted torque, relative to the peak motor
#: torque at the output (Kt I_max N(q0))
LOSS_TORQUE_SCALE = 1e-3


def loss_slots(P, drive, motor, q0: float, options, notes: list,
               last_motor_node: int | None = None) -> None:
    """Fill the drivetrain-loss slots (``ETA_MEAN``, ``ETA_HALF``, ``INV_TAU_S``, ``JW``): the
    loss coefficients 1 - eta (driving) and 1/eta_b - 1 (back-driven) as mean and half
    difference, the reciprocal torque scale, and the inertia before the losses at the motor
    shaft (the chain's J_w up to ``last_motor_node``, over N(q0)^2); all zero for a lossless
    chain or ``efficiency=False``."""
    eta, eta_b = drive.efficiency, drive.backdrive_efficiency
    if not options.efficiency or (eta >= 1.0 and eta_b >= 1.0):
        if eta < 1.0:
            notes.append(f"drivetrain efficiency {eta:.3g} left out (lossless transmission)")
        return
    hold_slots(P, eta, eta_b)
    if eta_b < MIN_BACKDRIVE:
        notes.append(f"the chain is self-locking (back-drive efficiency {eta_b:.3g}); modelled with "
                     f"back-drive efficiency {MIN_BACKDRIVE:g}")
        eta_b = MIN_BACKDRIVE
    c_drive, c_back = 1.0 - eta, 1.0 / eta_b - 1.0
    P[lo.ETA_MEAN], P[lo.ETA_HALF] = 0.5 * (c_drive + c_back), 0.5 * (c_drive - c_back)
    n0 = abs(float(drive.ratio([q0])[0][0]))
    P[lo.INV_TAU_S] = 1.0 / (LOSS_TORQUE_SCALE * motor.torque_constant * motor.current_limit * n0)
    P[lo.JW] = float(drive.chain.loss_inertia([q0], last_motor_node)[0]) / n0**2
    notes.append(f"drivetrain efficiency {eta:.3g} driving, {eta_b:.3g} back-driven (LossyGear-like loss "
                 "on the torque transmitted past the rotor and the members before the losses)")
    if P[lo.STICK] > 0:  # friction that holds (filled before the losses)
        eta_rest = drive.backdrive_efficiency
        notes.append("at rest the drivetrain holds within the band of its efficiencies (LossyGear's stuck mode, "
                     + ("self-locking: the load cannot drive the motor" if eta_rest <= 0 else
                        f"back-driven at {eta_rest:.3g}") + ")")


def hold_slots(P, eta: float, eta_b: float) -> None:
    """Fill the loss-at-rest slots (``HOLD_FWD`` = 1/eta - 1, ``HOLD_BACK`` = 1 - max(eta_b, 0)):
    the band within which a gear at rest holds (:func:`servo_toolkit.sim.kernel.gear_at_rest`), with
    the back-drive efficiency as it is (0 or less: self-locking, the load cannot drive the
    motor), not the moving loss's :data:`MIN_BACKDRIVE`."""
    P[lo.HOLD_FWD] = 1.0 / eta - 1.0
    P[lo.HOLD_BACK] = 1.0 - max(eta_b, 0.0)


def refuse_rigid_lash(lashes, options) -> None:
    """A free play needs a compliance to act in: a chain simulated rigid because the scene
    gives no compliance (or no inertia beyond it) with a lash is refused, never simulated
    without it (``options.backlash=False`` or ``play=0`` leave it out on purpose)."""
    lashes = [b for b in lashes if b.lash > 0]
    if lashes and options.backlash and options.play != 0.0:
        raise SceneError(lashes[0].key, "a free play in a rigid chain cannot be simulated: give the "
                         "chain a compliance (the stage's stiffness or a compliance stage) or set it "
                         f"to 0 (got a total play of {lashes[0].shown})")


__all__ = ["LOSS_TORQUE_SCALE", "MIN_BACKDRIVE", "hold_slots", "load_split", "loss_slots", "refuse_rigid_lash"]
