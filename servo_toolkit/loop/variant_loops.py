"""The open loop of every parameter variant as a function of frequency, in closed form
(:class:`VariantLoops`), from the variants' plant fields (:mod:`.variant_plants`) and the
designed controller's blocks (:func:`controller_blocks`, the motion controller and the
sampling delay, in modal form computed once: :class:`ModalResponse`), and the frequency grid
the variants' margins are read on (:func:`variant_grid`).

The controller is the design's, the same on every variant (its current loop and the
feedthrough of an ideal current loop keep the nominal motor's R and Ke).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..plant.current_loop import sample_delay_block
from .assembly import _abcd
from .closed_loop import DELAY_SAMPLES
from .response import loop_response, mechanical_response, state_space_response


def controller_blocks(ctrl):
    """State-space matrices of the motion controller from [theta, omega_m] to i_ref and of
    the sampling delay (Pade) from i_ref to i_cmd."""
    motion = ctrl.motion_block
    Am, Bm, Cm, Dm = _abcd(motion)
    cols = [motion.inputs.index(name) for name in ("theta", "omega_m")]
    return (Am, Bm[:, cols], Cm, Dm[:, cols]), _abcd(sample_delay_block(ctrl.sample_time, DELAY_SAMPLES))


def controller_response(blocks, s):
    """Cy (from -theta), Cw (from -omega_m) and the delay at ``s``."""
    h = state_space_response(*blocks[0], s)
    d = state_space_response(*blocks[1], s)
    return -h[..., 0, 0], -h[..., 0, 1], d[..., 0, 0]


class ModalResponse:
    """``C (s I - A)^-1 B + D`` of one state-space block at any ``s``, its modal form
    computed once (:func:`.response.state_space_response` recomputes it per call); a block
    without a well-conditioned eigenvector basis is evaluated by that function."""

    def __init__(self, A, B, C, D):
        from scipy.linalg import matrix_balance
        from .response import MODAL_CONDITION
        A, B, C, D = (np.atleast_2d(np.asarray(m, float)) for m in (A, B, C, D))
        self.block, self.D, self.lam, self.residues = (A, B, C, D), D, None, None
        if A.size == 0 or A.shape[0] == 0:
            self.lam, self.residues = np.zeros(0), np.zeros((D.shape[0], 0, D.shape[1]))
            return
        Ab, T = matrix_balance(A)
        lam, V = np.linalg.eig(Ab)
        if np.linalg.cond(V) < MODAL_CONDITION:
            self.lam = lam
            self.residues = (C @ T @ V)[:, :, None] * np.linalg.solve(T @ V, B)[None, :, :]

    def __call__(self, s):
        s = np.asarray(s, complex)
        if self.lam is None:
            return state_space_response(*self.block, s)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.einsum("...k,pkm->...pm", 1.0 / (s[..., None] - self.lam), self.residues) + self.D


def _controller_gains(motion, delay, s):
    """Cy, Cw and the delay at ``s`` from the cached modal forms."""
    h, d = motion(s), delay(s)
    return -h[..., 0, 0], -h[..., 0, 1], d[..., 0, 0]


def current_gain(s, cols, g1, kp: float, ki: float):
    """i / i_cmd of the analog current PI on each variant's winding; 1 without inductance."""
    L = np.asarray(cols["L"], float)
    if np.all(L <= 0):
        return np.ones(np.broadcast(s, g1).shape, complex)
    cpi = kp + ki / s
    tg = cols["eta"] * cols["N"] * cols["Kt"]
    return cpi / (L * s + cols["R"] + cpi + cols["Ke"] * cols["N"] * s * tg * g1)


@dataclass(frozen=True)
class VariantLoops:
    """The open loop of every variant as a function of frequency, closed form (see
    :mod:`.response`): ``self(rows, w)`` is ``L`` of variants ``rows`` at angular
    frequencies ``w`` (arrays broadcasting together)."""

    cols: dict
    current_gains: tuple
    blocks: tuple  # (motion A, B [theta, omega_m], C, D), (delay A, B, C, D)

    def __post_init__(self):
        object.__setattr__(self, "_modal", (ModalResponse(*self.blocks[0]), ModalResponse(*self.blocks[1])))

    def __call__(self, rows, w):
        s = 1j * np.asarray(w, float)
        rows = np.asarray(rows)
        f = {k: v[rows] for k, v in self.cols.items()}
        g1, g2 = mechanical_response(s, f["J1"], f["J2"], f["K"], f["c"], f["b1"], f["b2"], f["kh"])
        ic = current_gain(s, f, g1, *self.current_gains)
        tg = f["eta"] * f["N"] * f["Kt"]
        cy, cw, delay = _controller_gains(*self._modal, s)
        return loop_response(s, tg * g1 * ic, tg * g2 * ic, delay, cy, cw, f["N"])


#: points per decade of the variants' frequency grid away from lightly damped features, and
#: over the bands of the drivetrain modes (of every variant) and of the controller's
#: lightly damped poles and zeros: 1.5 % steps, finer than the uniform 600-point grid's
#: 2.2 %; the refinement then solves every crossing to solver precision
BASE_PER_DECADE, FINE_PER_DECADE = 30, 150
#: a pole or zero with a damping ratio below this is a feature the grid resolves finely
LIGHT_DAMPING = 0.3
#: the fine band extends this factor beyond the features on either side
BAND_FACTOR = 1.6


def variant_grid(cols: dict, rigid: bool, blocks, f_req: float, f_min: float = 0.01, f_max: float = 5e3):
    """Angular frequencies (rad/s) for the loops of every variant: :data:`BASE_PER_DECADE`
    over ``f_min..f_max``, :data:`FINE_PER_DECADE` over the band of the drivetrain's
    resonance and antiresonance of all variants and around each lightly damped pole and
    zero of the controller (damping below :data:`LIGHT_DAMPING`), and ``f_req`` (Hz)."""
    from ..lti.convert import ss2zpk_zeros
    bands = []
    if not rigid:
        J1, J2, K, kh = (np.asarray(cols[k], float) for k in ("J1", "J2", "K", "kh"))
        with np.errstate(divide="ignore", invalid="ignore"):
            wr = np.sqrt(K * (1 / J1 + 1 / J2))
            wa = np.sqrt(np.abs(K + kh) / J2)
        both = np.concatenate([wr[np.isfinite(wr)], wa[np.isfinite(wa)]])
        if both.size:
            bands.append((both.min(), both.max()))
    for A, B, C, D in blocks:
        if np.size(A) == 0:
            continue
        roots = [np.linalg.eigvals(A)]
        for j in range(B.shape[1]):
            with np.errstate(all="ignore"):
                roots.append(ss2zpk_zeros(A, B[:, j:j + 1], C, D[:, j:j + 1]).ravel())
        for r in np.concatenate(roots):
            mag = abs(r)
            if np.isfinite(mag) and mag > 0 and abs(r.real) < LIGHT_DAMPING * mag:
                bands.append((mag, mag))
    lo, hi = np.log10(2 * np.pi * f_min), np.log10(2 * np.pi * f_max)
    parts = [np.logspace(lo, hi, int(np.ceil((hi - lo) * BASE_PER_DECADE)) + 1)]
    for a, b in bands:
        a, b = max(np.log10(a / BAND_FACTOR), lo), min(np.log10(b * BAND_FACTOR), hi)
        if b > a:
            parts.append(np.logspace(a, b, int(np.ceil((b - a) * FINE_PER_DECADE)) + 1))
    parts.append([2 * np.pi * f_req])
    return np.unique(np.concatenate(parts))

__all__ = ["VariantLoops", "controller_blocks", "controller_response", "variant_grid"]
