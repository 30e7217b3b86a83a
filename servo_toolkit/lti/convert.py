"""Conversions between transfer functions and state-space blocks, the Pade delay and Tustin
sampling, in numpy (and ``scipy.linalg`` for sampling).

Each function follows the arithmetic python-control 0.10 uses without Slycot (which hands
the work to ``scipy.signal``), so the matrices and polynomials are the same numbers.
"""

from __future__ import annotations

import warnings

import numpy as np

from .system import StateSpace


class BadCoefficientsWarning(UserWarning):
    """A numerator whose leading coefficients vanish after normalisation (as
    ``scipy.signal.BadCoefficients``)."""


def _trim_leading(poly: np.ndarray) -> np.ndarray:
    """``poly`` without its exactly-zero leading coefficients; ``[0.]`` when all are zero
    (python-control's ``TransferFunction._truncatecoeff``)."""
    nonzero = np.flatnonzero(poly)
    return poly[nonzero[0]:] if nonzero.size else np.zeros(1)


def clean_tf(num, den) -> tuple[np.ndarray, np.ndarray]:
    """The numerator and denominator python-control's ``TransferFunction`` stores for a
    SISO ``tf(num, den)``: 1-D arrays, exactly-zero leading coefficients removed, a zero
    numerator given the denominator ``[1.]``.

    Raises
    ------
    ValueError
        For a zero denominator (as python-control).
    """
    num = np.atleast_1d(np.asarray(num, dtype=float)).reshape(-1)
    den = np.atleast_1d(np.asarray(den, dtype=float)).reshape(-1)
    if not np.any(den):
        raise ValueError("Input 1, output 1 has a zero denominator.")
    if not np.any(num):
        den = np.ones(1)
    return _trim_leading(num), _trim_leading(den)


def _normalize(num: np.ndarray, den: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``scipy.signal.normalize`` for one numerator: leading zeros of ``den`` trimmed, both
    divided by its first coefficient, numerator columns at most 1e-14 dropped (with a warning)."""
    den = np.atleast_1d(den)
    num = np.atleast_2d(num)
    if np.all(den == 0):
        raise ValueError("Denominator must have at least on nonzero element.")
    first = 0
    for c in den:
        if c != 0.:
            break
        first += 1
    den = den[first:]
    num, den = num / den[0], den / den[0]
    leading = 0
    for j in range(num.shape[-1]):
        if np.all(np.abs(num[:, j]) <= 1e-14):
            leading += 1
        else:
            break
    if leading > 0:
        warnings.warn("Badly conditioned filter coefficients (numerator): the results may be "
                      "meaningless", BadCoefficientsWarning, stacklevel=3)
        if leading == num.shape[1]:
            leading -= 1
        num = num[:, leading:]
    return num, den


def tf2ss(num, den, *, inputs=None, outputs=None, states=None, name: str = "") -> StateSpace:
    """The controllable-canonical state-space block of ``num(s)/den(s)``.

    Reproduces ``control.ss(control.tf(num, den))`` without Slycot: python-control's
    transfer-function cleaning, its static-gain case, then ``scipy.signal.tf2ss`` on the
    normalised polynomials; the matrices are the same numbers.

    Parameters
    ----------
    num, den : array_like
        Polynomial coefficients in descending powers of ``s``.
    inputs, outputs, states, name
        Signal names of the block (python-control's defaults ``u[0]``, ``y[0]``, ``x[k]``).

    Returns
    -------
    StateSpace

    Raises
    ------
    ValueError
        For a zero denominator or an improper transfer function.
    """
    num, den = clean_tf(num, den)
    if len(num) > len(den):
        raise ValueError("transfer function is non-proper; can't convert to StateSpace system")
    if len(num) == 1 and len(den) == 1:
        return StateSpace(np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), [[num[0] / den[0]]],
                          inputs=inputs, outputs=outputs, states=states, name=name)
    num2, den = _normalize(num, den)
    M, K = num2.shape[1], len(den)
    num2 = np.hstack((np.zeros((num2.shape[0], K - M), dtype=num2.dtype), num2))
    D = np.atleast_2d(num2[:, 0])
    A = np.r_[-np.array([den[1:]]), np.eye(K - 2, K - 1)]
    B = np.eye(K - 1, 1)
    C = num2[:, 1:] - np.outer(num2[:, 0], den[1:])
    D = D.reshape((C.shape[0], B.shape[1]))
    return StateSpace(A, B, C, D, inputs=inputs, outputs=outputs, states=states, name=name)


def _numerator(A, B, C, D, den) -> np.ndarray:
    """``scipy.signal.ss2tf``'s numerator of a SISO block, ``den`` its ``numpy.poly(A)``:
    ``poly(A - B C) + (D - 1) den``."""
    type_test = A[:, 0] + B[:, 0] + C[0, :] + D + 0.0
    num = np.empty((1, A.shape[0] + 1), type_test.dtype)
    num[0] = np.poly(A - np.dot(B, np.atleast_2d(C[0, :]))) + (D[0] - 1) * den
    return num[0]


def ss2tf(sys: StateSpace) -> tuple[np.ndarray, np.ndarray]:
    """Numerator and denominator (descending powers) of a SISO block.

    Reproduces ``control.ss2tf(sys)`` without Slycot (``tf.num[0][0]``, ``tf.den[0][0]``):
    ``scipy.signal.ss2tf`` (characteristic polynomials by ``numpy.poly``), then
    python-control's cleaning of exactly-zero leading coefficients.

    Raises
    ------
    NotImplementedError
        For a block that is not SISO.
    """
    if not sys.issiso():
        raise NotImplementedError("ss2tf of a block with one input and one output only")
    A, B, C, D = (np.asarray(m) for m in (sys.A, sys.B, sys.C, sys.D))
    if sys.nstates == 0:
        return clean_tf([D[0, 0]], [1.])
    den = np.poly(A)
    return clean_tf(_numerator(A, B, C, D, den), den)


def ss2zpk_zeros(A, B, C, D) -> np.ndarray:
    """Zeros of the SISO block ``(A, B, C, D)`` (``B`` one column, ``C`` one row) as
    ``scipy.signal.ss2zpk`` finds them: the roots of the numerator of ``ss2tf``, normalised
    (near-zero leading coefficients dropped with a warning) and made monic; the same numbers."""
    A, B, C, D = (np.atleast_2d(np.asarray(m, float)) for m in (A, B, C, D))
    den = np.poly(A)
    b = _normalize(_numerator(A, B, C, D, den), den)[0][0]
    return np.roots(b / b[0])


def pade(T: float, n: int = 1, numdeg: int | None = None) -> tuple[list, list]:
    """Pade approximation of a delay of ``T`` s: numerator and denominator coefficient lists.

    The same numbers as ``control.pade(T, n, numdeg)`` (Golub and van Loan, Alg. 11.3.1).

    Parameters
    ----------
    T : float
        Delay (s), >= 0.
    n : int
        Denominator degree.
    numdeg : int, optional
        Numerator degree (default ``n``; negative counts from ``n``).
    """
    if numdeg is None:
        numdeg = n
    elif numdeg < 0:
        numdeg += n
    if not T >= 0:
        raise ValueError("require T >= 0")
    if not n >= 0:
        raise ValueError("require n >= 0")
    if not (0 <= numdeg <= n):
        raise ValueError("require 0 <= numdeg <= n")
    if T == 0:
        return [1, ], [1, ]
    num = [0. for _ in range(numdeg + 1)]
    num[-1] = 1.
    cn = 1.
    for k in range(1, numdeg + 1):
        cn *= -T * (numdeg - k + 1) / (numdeg + n - k + 1) / k
        num[numdeg - k] = cn
    den = [0. for _ in range(n + 1)]
    den[-1] = 1.
    cd = 1.
    for k in range(1, n + 1):
        cd *= T * (n - k + 1) / (numdeg + n - k + 1) / k
        den[n - k] = cd
    return [c / den[0] for c in num], [c / den[0] for c in den]


def sample_tustin(sys: StateSpace, Ts: float) -> StateSpace:
    """The Tustin (bilinear) sampling of a continuous block every ``Ts`` s.

    Reproduces ``control.sample_system(sys, Ts, method="tustin")``: the generalized
    bilinear transform with ``alpha = 0.5`` of ``scipy.signal.cont2discrete``, with the
    same ``scipy.linalg.solve`` calls. Signal names are kept; the block's name gets
    python-control's ``$sampled`` suffix.

    Raises
    ------
    ValueError
        For a block that is already sampled.
    """
    if not sys.isctime():
        raise ValueError("System must be continuous-time system")
    from scipy import linalg
    a, b, c, d = (np.array(m) for m in (sys.A, sys.B, sys.C, sys.D))
    alpha, dt = 0.5, Ts
    ima = np.eye(a.shape[0]) - alpha * dt * a
    ad = linalg.solve(ima, np.eye(a.shape[0]) + (1.0 - alpha) * dt * a)
    bd = linalg.solve(ima, dt * b)
    cd = linalg.solve(ima.transpose(), c.transpose()).transpose()
    dd = d + alpha * np.dot(c, bd)
    return StateSpace(ad, bd, cd, dd, inputs=sys.inputs, outputs=sys.outputs, states=sys.states,
                      name=f"{sys.name}$sampled" if sys.name else "", dt=Ts)
