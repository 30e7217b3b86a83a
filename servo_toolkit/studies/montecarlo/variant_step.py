"""The batched runs' step checked at each variant's own parameters and states.

A variant shares the nominal run's RK4 step (:func:`.batch_step.batch_step`), checked along
the nominal run only; its own run may reach stiffer states than the nominal one. What makes
a state stiff is known: the drivetrain pressed into contact at the edge of its play (and an
elastic end stop passed), and the motor at a speed reversal, where the smooth Coulomb
friction's tanh(omega_m / w_s) and the loss's blend between driving and back-driven
(``loss_coefficient``, ``servo_toolkit/_physics/compliance.h``, steepest at zero speed and
scaled by the torque carried) change fastest. The batch keeps three states of each run: its
peak current (the largest torque), its largest drivetrain deflection and its end
(:data:`servo_toolkit.sim.batch.NSNAP`). Each is checked as it is, in contact
(:func:`~servo_toolkit.sim.stability.contact_states`) and at a speed reversal (both sides at
rest, every position, current and controller state kept: :func:`reversal_states`), and so is the start (as it is and
in contact): the largest |lambda dt| over them stands for the run, and a step outside RK4's
stability region at any of them fails the variant with that reason.

Friction that holds (``STICK``) takes a node at rest out of the dynamics while the moment on
it stays within its breakaway level: its speed stays 0 whatever the other states do, so the
step sees the rest of the chain only (:func:`held_nodes`). The smooth blend at zero speed, the
friction's and the loss's, is then not on the run's path: the Jacobian, taken on the smooth
dynamics, keeps its other rows, and the held node's speed row is 0. A node that breaks away
at a reversal slides through the blend and is judged with it.
"""

from __future__ import annotations

import numpy as np

from ...sim import layout as lo
from ...sim.batch import NSNAP, jacobians
from ...sim.kernel import rhs
from ...sim.stability import IMAG_LIMIT, contact_states, rk4_amplification, smooth_parameters


def reversal_states(model, X) -> np.ndarray:
    """The states ``X`` (rows) with the motor side and the load at rest (a speed reversal):
    the smooth friction's and the loss's steepest point, at the torque each state carries."""
    Y = np.array(X, dtype=float, copy=True)
    Y[:, 1] = 0.0
    if not model.rigid:
        Y[:, 3] = 0.0
    return Y


def checked_states(model, P, X0, snaps):
    """The states each variant's step is checked at: ``(states, times, irefs, owner)``: its
    start and the start in contact, then each snapshot as it is, in contact and at a speed
    reversal (:func:`reversal_states`)."""
    nv, nx = X0.shape
    S = snaps.reshape(nv * NSNAP, -1)
    x, t, ir = S[:, :nx], S[:, nx], S[:, nx + 1]
    own = np.repeat(np.arange(nv, dtype=np.int64), NSNAP)
    Psnap = P[own]
    states = np.concatenate([X0, contact_states(model, P, X0), x, contact_states(model, Psnap, x),
                             reversal_states(model, x)])
    start = np.zeros(nv)
    times = np.concatenate([start, start, t, t, t])
    irefs = np.concatenate([X0[:, 4], X0[:, 4], ir, ir, ir])
    owner = np.concatenate([np.arange(nv, dtype=np.int64)] * 2 + [own] * 3)
    return states, times, irefs, owner


def held_nodes(model, P, T, tix, X, times, irefs, owner) -> np.ndarray:
    """``(rows, 2)`` bool: whether the motor side (column 0) and the load (column 1) of state
    ``X[m]`` (variant ``owner[m]``) are held by friction that holds: at rest, with the variant's
    ``STICK`` on, and the right-hand side of the friction as it is (not smoothed) keeping
    their acceleration at exactly 0 (the stuck mode of
    :func:`~servo_toolkit.sim.kernel.gear_at_rest`)."""
    held = np.zeros((X.shape[0], 2), dtype=bool)
    at_rest = (X[:, 1] == 0.0) | ((X[:, 3] == 0.0) & (not model.rigid))
    rows = np.flatnonzero(at_rest & (P[owner, lo.STICK] > 0.0))
    dx, aux = np.empty(X.shape[1]), np.empty(lo.NAUX)
    for m in rows:
        v = owner[m]
        rhs(float(times[m]), X[m].copy(), P[v], T[tix[v]], float(irefs[m]), dx, aux)
        held[m, 0] = X[m, 1] == 0.0 and dx[1] == 0.0
        held[m, 1] = (not model.rigid) and X[m, 3] == 0.0 and dx[3] == 0.0
    return held


def step_check(model, P, T, tix, X0, snaps, dt):
    """Largest |lambda dt| per variant over the states :func:`checked_states` gives, and
    whether dt lies in RK4's stability region at every one of them.

    Parameters
    ----------
    model : Model
        The variants' shared build.
    P, T, tix : numpy.ndarray
        Their parameter rows, stroke tables and each row's table.
    X0 : numpy.ndarray
        Their starts (NaN rows: never run).
    snaps : numpy.ndarray
        The variants' snapshots (:func:`servo_toolkit.sim.batch_run.integrate_variants`).
    dt : float

    Returns
    -------
    worst : numpy.ndarray
    stable : numpy.ndarray of bool
    """
    nv, nx = X0.shape
    X, times, irefs, owner = checked_states(model, P, X0, snaps)
    ok_rows = np.all(np.isfinite(X), axis=1)
    X, times, irefs, owner = X[ok_rows], times[ok_rows], irefs[ok_rows], owner[ok_rows]
    J = np.empty((X.shape[0], nx, nx))
    jacobians(X, times, irefs, smooth_parameters(P), T, tix, owner, J)
    held = held_nodes(model, P, T, tix, X, times, irefs, owner)
    J[held[:, 0], 1, :] = 0.0  # a node held at rest: its speed stays 0 (the module's note)
    J[held[:, 1], 3, :] = 0.0
    good = np.all(np.isfinite(J), axis=(1, 2))
    lam = np.full((X.shape[0], nx), np.nan + 0j)
    lam[good] = np.linalg.eigvals(J[good])
    z = lam * dt
    mag = np.abs(z)
    decaying = z.real < -1e-9 * mag
    inside = np.where(decaying, np.abs(rk4_amplification(z)) <= 1 + 1e-12, mag <= IMAG_LIMIT)
    inside |= ~np.isfinite(z) | (mag == 0)
    worst = np.zeros(nv)
    stable = np.ones(nv, dtype=bool)
    np.maximum.at(worst, owner, np.nan_to_num(np.max(np.where(np.isfinite(mag), mag, 0.0), axis=1)))
    np.logical_and.at(stable, owner, np.all(inside, axis=1))
    return worst, stable


__all__ = ["checked_states", "held_nodes", "reversal_states", "step_check"]
