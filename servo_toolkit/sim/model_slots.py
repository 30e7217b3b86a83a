"""The parameter slots of an assembled model that follow from the drivetrain: the two-mass
slots (shared with the batched variants), the full chain's segment block, a chain-ending cam's
parameters, and the measured interpolation error of the stroke tables."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

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
        if ts_m > motor.coulomb_friction or load.coulomb_friction > 0 or ts_l > 0:
            notes.append("static friction and the load's friction left out: the motor's Coulomb friction is "
                         f"smoothed, Tc tanh(w / {options.friction_speed:g} rad/s), and never sticks")
        return
    P[lo.STICK] = 1.0
    P[lo.TS_M], P[lo.INV_VS_M] = ts_m, _inverse_speed(motor.stribeck_speed)
    P[lo.TC_L], P[lo.TS_L], P[lo.INV_VS_L] = load.coulomb_friction, ts_l, _inverse_speed(load.stribeck_speed)


def drivetrain_slots(P, *, rigid: bool, j0_tot: float, jl: float, k0: float, options,
                     play: float) -> None:
    """Fill the parameter slots that follow from the inertias and the series stiffness at q0.

    Load-side inertia ``JL`` (and its reciprocal), the motor side's reciprocal ``INV_JD0``,
    stiffness factor ``KSCALE``, structural
    damping ``BETA = 2 zeta / omega_n`` of the drivetrain mode at q0, half the lost motion,
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
        P[lo.BETA] = 2 * options.damping_ratio / wn
        P[lo.HALF_PLAY] = 0.5 * play
        k_stop, j_stop = 10 * k0, jl
    P[lo.KSTOP], P[lo.DSTOP] = k_stop, math.sqrt(k_stop * j_stop)


def with_full_chain(P, full, options):
    """The full chain's slots (:mod:`.chain_model`): its segment block appended, the motor
    node's reciprocal inertia, segment 0's play and the chain's damping."""
    P[lo.NMID] = len(full["nodes"]) - 2
    P[lo.INV_JD0] = 1.0 / full["j_motor0"]
    P[lo.BETA] = full["beta"]
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
    g = int(model.P[lo.OFF_SEG])
    held = model.P[g + lo.SEG_J:g + lo.SEG_STRIDE * (nm + 1):lo.SEG_STRIDE].sum() if nm else model.P[lo.JL]
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
    return replace(model, table_error=err)


__all__ = ["FRICTION_CHOICES", "drivetrain_slots", "friction_slots", "with_cam", "with_full_chain", "with_table_error"]
