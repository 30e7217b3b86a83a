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
    """``C (s I - A)^-1 B + D`` at every ``s``, shape ``s.shape + (outputs, inputs)``, with
    python-control's arithmetic: a block without states is ``D``, one with a single state
    ``C / (s - a) * B + D`` (a point on its pole ``inf``), a larger one
    :func:`solved_response`."""
    s = np.asarray(s, complex)
    A, B, C, D = (np.asarray(m, float) for m in (A, B, C, D))
    if A.shape[0] == 0:
        return np.broadcast_to(D.astype(complex), s.shape + D.shape).copy()
    if A.shape[0] == 1:
        with np.errstate(divide="ignore", invalid="ignore"):
            out = C[:, :, None] / (s.reshape(-1) - A[0, 0]) * B[:, :, None] + D[:, :, None]
        out[np.isnan(out)] = complex(np.inf, np.nan)
        return np.moveaxis(out, -1, 0).reshape(s.shape + D.shape)
    return solved_response(A, B, C, D, s)
