"""A sampled position command inside the compiled kernels: the cubic Hermite interpolant of a
table of samples stored in P after the header, with its exact first and second time
derivatives (slots ``REF_TAB_*`` in :mod:`servo_toolkit.sim.layout`; the table is packed by
:mod:`servo_toolkit.sim.reference_table`).

On segment k (between samples k and k + 1, local coordinate u in [0, 1], spacing h)::

    r(u)  = h00 y_k + h h10 m_k + h01 y_k+1 + h h11 m_k+1
    r'    = (6u^2 - 6u)(y_k - y_k+1) / h + (3u^2 - 4u + 1) m_k + (3u^2 - 2u) m_k+1
    r''   = ((12u - 6)(y_k - y_k+1) / h + (6u - 4) m_k + (6u - 2) m_k+1) / h

With the slopes of a cubic spline through the samples (what the packer stores) r is that
spline: twice continuously differentiable. Outside a non-periodic table the end values are
held (r' = r'' = 0); a periodic table wraps.
"""

from __future__ import annotations

import math

from ..core.jit_cache import install as _install_cache

_install_cache()  # noqa: E402 - before any kernel below is decorated

from .layout import REF_OFF, REF_TAB_INV_DT, REF_TAB_N, REF_TAB_OFF, REF_TAB_T0, REF_TAB_WRAP  # noqa: E402
from .vmath import inline  # noqa: E402


@inline
def table_rates(t, P):
    """The sampled command and its first and second time derivatives at time t,
    ``(r, r', r'')``: REF_OFF plus the table's interpolant."""
    o = int(P[REF_TAB_OFF])
    n = int(P[REF_TAB_N])
    inv = P[REF_TAB_INV_DT]
    last = n - 1.0
    s = (t - P[REF_TAB_T0]) * inv
    moving = 1.0
    if P[REF_TAB_WRAP] > 0.0:
        s = s - last * math.floor(s / last)
    elif s <= 0.0:
        s, moving = 0.0, 0.0
    elif s >= last:
        s, moving = last, 0.0
    k = min(int(s), n - 2)
    u = s - k
    dy = P[o + k] - P[o + k + 1]
    m0 = P[o + n + k]
    m1 = P[o + n + k + 1]
    h = 1.0 / inv
    u2 = u * u
    val = P[o + k] + u2 * (2.0 * u - 3.0) * dy + h * ((u2 * u - 2.0 * u2 + u) * m0 + (u2 * u - u2) * m1)
    der = (6.0 * u2 - 6.0 * u) * dy * inv + (3.0 * u2 - 4.0 * u + 1.0) * m0 + (3.0 * u2 - 2.0 * u) * m1
    acc = ((12.0 * u - 6.0) * dy * inv + (6.0 * u - 4.0) * m0 + (6.0 * u - 2.0) * m1) * inv
    return P[REF_OFF] + val, moving * der, moving * acc


__all__ = ["table_rates"]
