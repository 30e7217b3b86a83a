"""The parameter slots of an assembled model: the two-mass slots (shared with the batched
variants), the full chain's segment block and table rows, friction, a chain-ending cam's
parameters, the motion controller's matrices, and the measured
interpolation error of the stroke tables."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ..errors import SceneError
from ..loop.controller import MOTION_INPUTS
from . import layout as lo
from .chain_model import segment_stiffness, segments
from .chain_split import load_split
from .kernel import hermite


FRICTION_CHOICES = ("stick", "smooth", "off")


def _inverse_speed(v: float) -> float:
    return 1.0 / v if v > 0 else math.inf


def friction_slots(P, motor, load, options, notes: list) -> None:
    """The motor's and the load's friction (``ModelOptions.friction``): breakaway and Coulomb
    levels and Stribeck speeds with exact stick (``STICK``), the smooth Coulomb model of the
    motor alone, or none."""
    ts_m, ts_l = motor.breakaway_torque, load.breakaway
    any_friction = max(motor.coulomb_friction, ts_m, load.coulomb_friction, ts_l) > 0
    if options.friction == "off" or not any_friction:
        P[lo.TC] = 0.0
        if any_friction:
            notes.append("Coulomb and static friction left out (viscous friction kept)")
        return
    if options.friction == "smooth":
        left = [what for what, there in (("static friction", ts_m > motor.coulomb_friction or ts_l > load.coulomb_friction),
                                         ("the load's friction", load.coulomb_friction > 0 or ts_l > 0)) if there]
        ws = options.friction_speed
        if motor.coulomb_friction > 0:
            notes.append((" and ".join(left) + " left out; " if left else "")
                         + f"the motor's Coulomb friction {motor.coulomb_friction:.4g} N*m is smoothed, Tc tanh(w / "
                         f"{ws:g} rad/s), and never sticks: a motor held below breakaway creeps, a torque tau turning it at "
                         f"{ws:g} rad/s * atanh(tau / Tc) ({ws * math.atanh(0.5):.3g} rad/s at half of Tc) instead "
                         "of holding it, and any tau >= Tc accelerates it")
        elif left:
            notes.append(" and ".join(left) + " left out (the smooth model keeps only the motor's Coulomb friction)")
        return
    P[lo.STICK] = 1.0
    P[lo.TS_M], P[lo.INV_VS_M] = ts_m, _inverse_speed(motor.stribeck_speed)
    P[lo.TC_L], P[lo.TS_L], P[lo.INV_VS_L] = load.coulomb_friction, ts_l, _inverse_speed(load.stribeck_speed)


def drivetrain_slots(P, *, rigid: bool, j0_tot: float, jl: float, k0: float, options,
                     play: float, zeta: float | None = None) -> None:
    """Fill the parameter slots that follow from the inertias and the series stiffness at q0.

    Load-side inertia ``JL`` (and its reciprocal), the motor side's reciprocal ``INV_JD0``,
    stiffness factor ``KSCALE``, structural
    damping ``BETA = 2 zeta / omega_n`` of the two-mass mode at q0, half the lost motion,
    and the elastic stroke-end stop (10x the drivetrain stiffness; 100 Hz on a rigid chain).
    :func:`build_model` and the batched variants (:mod:`servo_toolkit.sim.batch`) both fill
    them here.

    Parameters
    ----------
    P : numpy.ndarray
        Parameters, written in place.
    rigid : bool
    j0_tot : float
        Total inertia at the output at q0 (kg*m^2).
    jl : float
        Load-side inertia (0 for a rigid chain).
    k0 : float
        Series stiffness at q0 before ``options.stiffness_scale`` (ignored when rigid).
    options : ModelOptions
    play : float
        Total lost motion at the output (rad; ignored when rigid).
    zeta : float, optional
        Damping ratio of the two-mass mode: the chain's lowest mode's
        (:func:`servo_toolkit.plant.linear.two_mass_damping`); None: ``options.damping_ratio``.
    """
    P[lo.JL] = jl
    P[lo.INV_JL] = 1.0 / jl if jl > 0 else 0.0
    P[lo.INV_JD0] = 1.0 / (j0_tot - jl)
    P[lo.KSCALE] = options.stiffness_scale
    if rigid:
        k_stop = j0_tot * (2 * math.pi * 100.0) ** 2
        j_stop = j0_tot
    else:
        k0 = k0 * options.stiffness_scale
        jd0 = j0_tot - jl
        wn = math.sqrt(k0 * (1 / jd0 + 1 / jl))
        P[lo.BETA] = 2 * (options.damping_ratio if zeta is None else zeta) / wn
        P[lo.HALF_PLAY] = 0.5 * play
        k_stop, j_stop = 10 * k0, jl
    P[lo.KSTOP], P[lo.DSTOP] = k_stop, math.sqrt(k_stop * j_stop)


def with_full_chain(P, full, options):
    """The full chain's slots (:mod:`.chain_model`): its segment block appended (each
    segment's play, loss fraction and damper), the rows of its per-node tables, the motor
    node's reciprocal inertia and segment 0's play and damper."""
    nm = len(full["nodes"]) - 2
    P[lo.NMID] = nm
    P[lo.ROW_JW0] = lo.T_KS + 2 * nm
    P[lo.ROW_NODE] = P[lo.ROW_JW0] + 2
    P[lo.INV_JD0] = 1.0 / full["j_motor0"]
    P[lo.BETA] = full["damping"].beta[0]
    P[lo.HALF_PLAY] = full["half_play"]
    k_stop = 10 * full["k_series0"] * options.stiffness_scale
    P[lo.KSTOP], P[lo.DSTOP] = k_stop, math.sqrt(k_stop * full["j_load"])
    P[lo.OFF_SEG] = P.size
    return np.concatenate([P, full["block"]])


def with_cam(P, drive, rigid, notes):
    """Append a chain-ending cam's parameters (its follower weight and guide friction load
    the shaft inside the kernel)."""
    if not drive.ends_in_cam:
        return P
    cam = drive.stages[-1]
    if cam.follower_weight == 0 and cam.guide_friction_coefficient == 0:
        return P
    if not rigid or cam.law != "modified_constant_velocity":
        notes.append("cam follower weight and guide friction left out (compliant chain or law "
                     f"{cam.law!r})")
        return P
    from ..components.cam.kernels import pack_cam
    P[lo.CAM] = P.size
    return np.concatenate([P, pack_cam(cam)])


def with_table_error(model, drive, q):
    """Measure the Hermite interpolation error at the cell midpoints against the drivetrain."""
    mid = 0.5 * (q[1:] + q[:-1])
    nm = int(model.P[lo.NMID])
    nodes = segments(drive.chain, model.q0) if nm else []
    beyond = [b for _, b in nodes]
    exact_nodes = drive.chain.node_jets(mid)[0][beyond] if nm else np.zeros((0, mid.size))
    held = exact_nodes.sum(axis=0) if nm else model.P[lo.JL]
    exact_j = drive.inertia(mid)[0] - (0.0 if model.rigid else held)
    exact_n = np.abs(drive.ratio(mid)[0])
    if not model.options.variable_inertia:
        exact_j = np.full_like(mid, model.T[lo.T_J, 0])
    interp = np.array([[hermite(model.T, row, model.P, x)[0] for x in mid]
                       for row in (lo.T_J, lo.T_N, lo.T_K)])
    err = {"J": float(np.max(np.abs(interp[0] - exact_j)) / np.max(np.abs(exact_j))),
           "N": float(np.max(np.abs(interp[1] - exact_n)) / np.max(exact_n))}
    if not model.rigid:
        if nm:
            exact_k = segment_stiffness(drive.chain, mid, segments(drive.chain, model.q0))[0]
        else:
            exact_k = drive.stiffness(mid).total * load_split(drive, model.q0)[3]
        err["K"] = float(np.max(np.abs(interp[2] - exact_k)) / np.max(exact_k))
    if nm and model.options.variable_inertia:
        rows = [int(model.P[lo.ROW_NODE]) + lo.NODE_ROWS * j for j in range(len(beyond))]
        got = np.array([[hermite(model.T, r, model.P, x)[0] for x in mid] for r in rows])
        err["J_nodes"] = float(np.max(np.abs(got - exact_nodes) / np.max(np.abs(exact_nodes), axis=1)[:, None]))
    return replace(model, table_error=err)


def pack_controller(controller, mode):
    """The motion controller's (A, B, C, D): discretized for a sampled loop, continuous otherwise."""
    names = tuple(controller.motion_block.inputs)
    if names != MOTION_INPUTS:
        raise SceneError("controller", f"motion controller inputs must be {MOTION_INPUTS}, got {names}")
    if mode == lo.SAMPLED:
        a, b, c, d = controller.discrete_motion()
    else:
        s = controller.motion_block
        a, b, c, d = (np.asarray(m, dtype=float) for m in (s.A, s.B, s.C, s.D))
    if c.shape[0] != 1:
        raise SceneError("controller", "the motion controller must have one output (i_ref)")
    return a, b, c, d


__all__ = ["FRICTION_CHOICES", "drivetrain_slots", "friction_slots", "pack_controller", "with_cam",
           "with_full_chain", "with_table_error"]
