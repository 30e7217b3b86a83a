"""Stroke tables inside the compiled kernels: the cell of a position and the cubic Hermite
interpolation of a table row (values and exact derivatives), and the one array type every
kernel takes its tables as (:func:`frozen_tables`). Layout of the rows in
:mod:`servo_toolkit.sim.layout`."""

from __future__ import annotations

import math

import numpy as np

from ..core.jit_cache import install as _install_cache

_install_cache()  # noqa: E402 - before any kernel below is decorated

from .layout import INV_H, PERIODIC, TAB_H, TAB_LO, TAB_N  # noqa: E402
from .vmath import inline  # noqa: E402


@inline
def cell(P, q):
    """Table cell index k and local coordinate t in [0, 1] of q (clamped; periodic wraps)."""
    s = (q - P[TAB_LO]) * P[INV_H]
    last = P[TAB_N] - 1.0
    if P[PERIODIC] > 0.0:
        s = s - last * math.floor(s / last)
    if s <= 0.0:
        return 0, 0.0
    if s >= last:
        return int(last) - 1, 1.0
    k = int(s)
    return k, s - k


@inline
def interp(T, row, k, t, h, inv_h):
    """Cubic Hermite value and derivative of table ``row`` (values; ``row + 1`` holds
    derivatives) in cell k at local coordinate t; h is the grid step."""
    y0 = T[row, k]
    y1 = T[row, k + 1]
    m0 = T[row + 1, k] * h
    m1 = T[row + 1, k + 1] * h
    t2 = t * t
    t3 = t2 * t
    val = (2 * t3 - 3 * t2 + 1) * y0 + (t3 - 2 * t2 + t) * m0 + (3 * t2 - 2 * t3) * y1 + (t3 - t2) * m1
    der = ((6 * t2 - 6 * t) * (y0 - y1) + (3 * t2 - 4 * t + 1) * m0 + (3 * t2 - 2 * t) * m1) * inv_h
    return val, der


@inline
def hermite(T, row, P, q):
    """Cubic Hermite interpolation of table ``row`` at q: value and its exact derivative.

    Outside a non-periodic table the end values are held (derivative 0); periodic tables
    wrap.
    """
    k, t = cell(P, q)
    if P[PERIODIC] <= 0.0 and (t == 0.0 or t == 1.0) and (q <= P[TAB_LO] or k == P[TAB_N] - 2):
        return T[row, k + int(t)], 0.0
    return interp(T, row, k, t, P[TAB_H], P[INV_H])


__all__ = ["cell", "hermite", "interp"]


def frozen_tables(T) -> np.ndarray:
    """``T`` as a read-only C-contiguous float64 array (a copy only when it is not one): the
    type every compiled kernel is compiled for, so no table array compiles a kernel again."""
    if T.flags.writeable or not T.flags.c_contiguous or T.dtype != np.float64:
        T = np.array(T, dtype=np.float64, order="C")
        T.setflags(write=False)
    return T
