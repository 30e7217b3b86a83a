"""Stability margins and bandwidth of a continuous SISO block, in numpy.

Both follow python-control 0.10's arithmetic step by step: the margins on the polynomials
of the block's transfer function (``control.margins``), the bandwidth on its frequency
response with a bisection (``LTI.bandwidth``), so the figures are the same numbers and
the same errors are raised where the polynomials overflow.
"""

from __future__ import annotations

import numpy as np

from .convert import ss2tf
from .system import StateSpace


def _check_siso_continuous(sys: StateSpace, what: str) -> None:
    if not sys.issiso():
        raise NotImplementedError(f"{what} of a block with one input and one output only")
    if not sys.isctime():
        raise NotImplementedError(f"{what} of a continuous-time block only")


def _tf_eval(num, den, s, warn: bool = True) -> np.ndarray:
    """``num(s) / den(s)`` by ``numpy.polyval`` (python-control's ``TransferFunction.horner``)."""
    s = np.atleast_1d(s).astype(complex, copy=False)
    with np.errstate(all='ignore' if not warn else 'warn'):
        return np.polyval(num, s) / np.polyval(den, s)


def _poly_iw_sqr(pol_iw):
    return np.real(np.polymul(pol_iw, pol_iw.conj()))


def _real_crossing(num_iw, den_iw, epsw):
    test_w = np.polysub(np.polymul(num_iw.imag, den_iw.real), np.polymul(num_iw.real, den_iw.imag))
    w = np.roots(test_w)
    w = np.real(w[np.isreal(w)])
    return w[w >= epsw]


def _mag1_crossing(num_iw, den_iw, epsw):
    w = np.roots(np.polysub(_poly_iw_sqr(num_iw), _poly_iw_sqr(den_iw)))
    w = np.real(w[np.isreal(w)])
    return w[w > epsw]


def _wstab(num_iw, den_iw, epsw):
    test_wstabn = _poly_iw_sqr(np.polyadd(num_iw, den_iw))
    test_wstabd = _poly_iw_sqr(den_iw)
    test_wstab = np.polysub(np.polymul(np.polyder(test_wstabn), test_wstabd),
                            np.polymul(np.polyder(test_wstabd), test_wstabn))
    wstab = np.roots(test_wstab)
    wstab = np.real(wstab[np.isreal(wstab)])
    wstab = wstab[wstab > epsw]
    wstabplus = np.polyval(np.polyder(test_wstab), wstab)
    return wstab[wstabplus > 0.]


def stability_margins(sys: StateSpace, returnall: bool = False, epsw: float = 0.0):
    """Gain, phase and stability margins of a loop and their frequencies.

    Reproduces ``control.stability_margins(sys, returnall, epsw)`` (method 'poly') for a
    continuous SISO block: the transfer function by :func:`.convert.ss2tf`, the
    crossings as the positive real roots of python-control's polynomials in ``w``.

    Parameters
    ----------
    sys : StateSpace
        Loop transfer function (one input, one output, continuous).
    returnall : bool
        True: every crossing, sorted by frequency; False: python-control's choice of
        the smallest margins.
    epsw : float
        Frequencies (rad/s) below this are static gain, not crossings.

    Returns
    -------
    gm, pm, sm, wpc, wgc, wms
        Gain margin (factor), phase margin (deg), stability margin (distance of the
        Nyquist curve from -1), phase-crossover, gain-crossover and stability-margin
        frequencies (rad/s); arrays when ``returnall``.

    Raises
    ------
    numpy.linalg.LinAlgError, ValueError
        Where the polynomials overflow (as python-control).
    NotImplementedError
        For a block that is not SISO or not continuous.
    """
    _check_siso_continuous(sys, "stability margins")
    num, den = ss2tf(sys)
    num_iw = (1J) ** np.arange(len(num) - 1, -1, -1) * num
    den_iw = (1J) ** np.arange(len(den) - 1, -1, -1) * den

    w_180 = _real_crossing(num_iw, den_iw, epsw)
    w180_resp = _tf_eval(num, den, 1J * w_180, warn=False)
    wc = _mag1_crossing(num_iw, den_iw, epsw)
    wc_resp = _tf_eval(num, den, 1J * wc)
    wstab = _wstab(num_iw, den_iw, epsw)
    ws_resp = _tf_eval(num, den, 1J * wstab)

    w_180 = w_180[w180_resp <= 0.]
    w180_resp = w180_resp[w180_resp <= 0.]
    idx = np.argsort(w_180)
    w_180, w180_resp = w_180[idx], w180_resp[idx]
    idx = np.argsort(wc)
    wc, wc_resp = wc[idx], wc_resp[idx]
    idx = np.argsort(wstab)
    wstab, ws_resp = wstab[idx], ws_resp[idx]

    with np.errstate(all='ignore'):
        GM = 1. / np.abs(w180_resp)
    PM = np.remainder(np.angle(wc_resp, deg=True), 360.) - 180.
    SM = np.abs(ws_resp + 1.)
    if returnall:
        return GM, PM, SM, w_180, wc, wstab
    if GM.shape[0] and not np.isinf(GM).all():
        with np.errstate(all='ignore'):
            gmidx = np.where(np.abs(np.log(GM)) == np.min(np.abs(np.log(GM))))
    else:
        gmidx = -1
    if PM.shape[0]:
        pmidx = np.where(np.abs(PM) == np.amin(np.abs(PM)))[0]
    return (
        (not gmidx != -1 and float('inf')) or GM[gmidx][0],
        (not PM.shape[0] and float('inf')) or PM[pmidx][0],
        (not SM.shape[0] and float('inf')) or np.amin(SM),
        (not gmidx != -1 and float('nan')) or w_180[gmidx][0],
        (not wc.shape[0] and float('nan')) or wc[pmidx][0],
        (not wstab.shape[0] and float('nan')) or wstab[SM == np.amin(SM)][0])


def default_frequencies(sys: StateSpace, number_of_samples: int = 1000) -> np.ndarray:
    """python-control's default frequency grid of a continuous block (rad/s): 1000 points
    log-spaced from a decade below its slowest to a decade above its fastest pole or zero
    (``freqplot._default_frequency_range``)."""
    features = np.array(())
    try:
        features_ = np.concatenate((np.abs(sys.poles()), np.abs(sys.zeros())))
        toreplace = np.isclose(features_, 0.0)
        if np.any(toreplace):
            features_ = features_[~toreplace]
        features = np.concatenate([features, features_])
    except NotImplementedError:
        pass
    if features.shape[0] == 0:
        features = np.array([1.])
    features = np.log10(features)
    lsp_min = np.rint(np.min(features) - 1)
    lsp_max = np.rint(np.max(features) + 1)
    return np.logspace(lsp_min, lsp_max, num=number_of_samples, endpoint=True)


def bandwidth(sys: StateSpace, dbdrop: float = -3):
    """The first frequency (rad/s) where the gain falls ``dbdrop`` dB below the DC gain.

    Reproduces ``control.bandwidth(sys, dbdrop)`` for a continuous SISO block: the first
    point of python-control's default grid below the level brackets a bisection
    (``scipy.optimize.root_scalar``) on ``|G(jw)|``.

    Returns
    -------
    float
        ``nan`` for an infinite DC gain, ``inf`` when the grid never falls below the level.

    Raises
    ------
    TypeError
        For a block that is not SISO (as python-control).
    ValueError
        For a ``dbdrop`` that is not a negative number.
    """
    if not sys.issiso():
        raise TypeError("system should be a SISO system")
    if not sys.isctime():
        raise NotImplementedError("bandwidth of a continuous-time block only")
    if (not np.isscalar(dbdrop)) or dbdrop >= 0:
        raise ValueError("expecting dbdrop be a negative scalar in dB")
    dcgain = sys.dcgain()
    if np.isinf(dcgain):
        return np.nan
    omega = np.sort(np.array(default_frequencies(sys), ndmin=1))
    mag = np.abs(sys(1j * omega))
    idx_dropped = np.nonzero(mag - dcgain * 10 ** (dbdrop / 20) < 0)[0]
    if idx_dropped.shape[0] == 0:
        return np.inf
    from scipy.optimize import root_scalar
    result = root_scalar(lambda w: np.abs(sys(w * 1j)) - np.abs(dcgain) * 10 ** (dbdrop / 20),
                         bracket=[omega[idx_dropped[0] - 1], omega[idx_dropped[0]]], method='bisect')
    if result.converged:
        return np.abs(result.root)
    raise ArithmeticError(result.message)

