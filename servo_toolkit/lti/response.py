"""The frequency response of a state-space block, every frequency in one batched solve."""

from __future__ import annotations

import numpy as np


def solved_response(A, B, C, D, s):
    """``C (s I - A)^-1 B + D`` at every ``s`` by one batched linear solve (as python-control
    evaluates a state-space system without Slycot): shape ``s.shape + (outputs, inputs)``.
    Where a point lies on a pole, the points are solved one by one and that point is
    ``inf`` (as python-control)."""
    s = np.asarray(s, complex)
    n = A.shape[0]
    M = s[..., None, None] * np.eye(n) - A
    try:
        X = np.linalg.solve(M, np.broadcast_to(B, M.shape[:-1] + B.shape[-1:]))
    except np.linalg.LinAlgError:
        out = np.empty(s.shape + D.shape, complex)
        for k in np.ndindex(s.shape):
            try:
                out[k] = C @ np.linalg.solve(M[k], B) + D
            except np.linalg.LinAlgError:
                out[k] = complex(np.inf, np.nan)
        return out
    return C @ X + D


def evaluate(A, B, C, D, s):
    """:func:`solved_response` of a block that may have no states: shape ``s.shape + (outputs, inputs)``."""
    s = np.asarray(s, complex)
    if A.shape[0] == 0:
        return np.broadcast_to(np.asarray(D, complex), s.shape + D.shape).copy()
    return solved_response(A, B, C, D, s)
