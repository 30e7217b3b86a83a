"""Closed-loop state matrices assembled with numpy, batched over plant variants.

Used where thousands of loops must be checked for stability (design search, robustness);
python-control's ``interconnect`` builds the same loops for the reported results, and the
tests compare the two.
"""

from __future__ import annotations

import numpy as np

from ..plant.current_loop import current_loop_block, sample_delay_block
from .closed_loop import DELAY_SAMPLES


def _abcd(sys):
    return tuple(np.asarray(m, float).reshape(s) for m, s in
                 ((sys.A, (sys.nstates, sys.nstates)), (sys.B, (sys.nstates, sys.ninputs)),
                  (sys.C, (sys.noutputs, sys.nstates)), (sys.D, (sys.noutputs, sys.ninputs))))


def controller_matrices(controller, motor):
    """The whole controller (motion, sampling delay, current loop) as one system from
    ``y = [theta, omega_m, i]`` (reference zero) to ``u``: (A, B, C, D)."""
    Am, Bm, Cm, Dm = _abcd(controller.motion_block)          # [theta_ref, theta, omega_m] -> i_ref
    Bm, Dm = Bm[:, 1:], Dm[:, 1:]                      # [theta, omega_m]
    Ad, Bd, Cd, Dd = _abcd(sample_delay_block(controller.sample_time, DELAY_SAMPLES))  # i_ref -> i_cmd
    cur = current_loop_block(controller.current_kp, controller.current_ki, motor)
    Ac, Bc, Cc, Dc = _abcd(cur)
    ideal = cur.ninputs == 2                           # [i_cmd, omega_m] else [i_cmd, i, omega_m]
    nm, nd, nc = Am.shape[0], Ad.shape[0], Ac.shape[0]
    n = nm + nd + nc
    # i_cmd = Cd xd + Dd (Cm xm + Dm [theta, omega_m])
    icmd_x = np.hstack([Dd @ Cm, Cd, np.zeros((1, nc))])
    icmd_y = np.hstack([Dd @ Dm, np.zeros((1, 1))])   # columns theta, omega_m, i
    bi = Bc[:, :1]
    di = Dc[:, :1]
    if ideal:
        extra_b = np.hstack([np.zeros((nc, 1)), Bc[:, 1:2], np.zeros((nc, 1))])
        extra_d = np.hstack([np.zeros((1, 1)), Dc[:, 1:2], np.zeros((1, 1))])
    else:
        extra_b = np.hstack([np.zeros((nc, 1)), Bc[:, 2:3], Bc[:, 1:2]])
        extra_d = np.hstack([np.zeros((1, 1)), Dc[:, 2:3], Dc[:, 1:2]])
    A = np.zeros((n, n))
    B = np.zeros((n, 3))
    A[:nm, :nm] = Am
    B[:nm, :2] = Bm
    A[nm:nm + nd, :nm] = Bd @ Cm
    A[nm:nm + nd, nm:nm + nd] = Ad
    B[nm:nm + nd, :2] = Bd @ Dm
    A[nm + nd:, :] = bi @ icmd_x
    A[nm + nd:, nm + nd:] += Ac
    B[nm + nd:, :] = bi @ icmd_y + extra_b
    C = np.hstack([di @ icmd_x[:, :nm + nd], Cc]) if nc else di @ icmd_x
    D = di @ icmd_y + extra_d
    return A, B, C, D


def closed_loop_matrix(Ap, Bu, Cy, Dyu, Ak, Bk, Ck, Dk):
    """A of the loop u = K y, y = P u; plant arrays may carry a leading batch axis.

    ``Bu`` is the plant's voltage column (n, 1), ``Cy`` / ``Dyu`` its rows theta, omega_m, i.
    """
    Ap = np.asarray(Ap, float)
    batch = Ap.shape[:-2]
    Bu, Cy, Dyu = (np.broadcast_to(np.asarray(m, float), batch + np.shape(m)[-2:]) for m in (Bu, Cy, Dyu))
    # u = Ck xk + Dk (Cy xp + Dyu u)  ->  u = F (Ck xk + Dk Cy xp), F = (1 - Dk Dyu)^-1
    F = 1.0 / (1.0 - (Dk @ Dyu)[..., 0, 0])[..., None, None]
    u_xp = F * (Dk @ Cy)
    u_xk = F * np.broadcast_to(Ck, batch + Ck.shape)
    y_xp = Cy + Dyu @ u_xp
    y_xk = Dyu @ u_xk
    top = np.concatenate([Ap + Bu @ u_xp, Bu @ u_xk], axis=-1)
    bot = np.concatenate([Bk @ y_xp, np.broadcast_to(Ak, batch + Ak.shape) + Bk @ y_xk], axis=-1)
    return np.concatenate([top, bot], axis=-2)
