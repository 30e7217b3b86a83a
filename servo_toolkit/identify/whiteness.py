"""Whether the residual of a time trace is the data's noise: a test of its block means.

A model that misses the physics leaves a residual that is smooth in time (a damping, a
friction model or a current loop the data do not have moves every sample of a stretch the
same way), while a sensor's noise changes from sample to sample. The RMS of the residual
cannot tell them apart when the miss is smaller than the noise: on the rotary flap of
``tests/test_identify_loop_coverage.py`` a model with 5 % structural damping instead of the data's
2 % and a smooth instead of a holding friction left a residual of 1.00 to 1.03 noise floors
(the right model 0.97 to 0.99), well inside the verdict's factor, and moved the stiffness by
0.6 to 1 % against 95 % intervals of +-0.3 %. Its means over blocks of a few milliseconds
showed it: 1.7 to 2.3 times what white noise leaves on the output, 1.15 to 1.27 times on the
current.

:func:`block_test` cuts a channel's residual into :data:`BLOCKS` blocks of equal length and
compares each block's mean with the standard deviation white noise of the residual's own
variance leaves it, ``s / sqrt(w)`` for ``w`` samples. A measurement rounded to a count
(an encoder) rounds alike while it rests on one count: its rounding error is one value along
each run of equal samples, independent from run to run, so a block's mean carries
``q^2 sum(L^2) / w^2`` of it (``q`` the count's rounding noise, ``L`` the lengths of the
block's runs), ``q^2 / w`` while the measurement moves a count or more per sample and ``q^2``
at rest. The sum of the squared block means over their variances is chi-squared with as
many degrees of freedom as blocks when the residual is white noise; a sum beyond its
``1 - ALPHA`` quantile says the residual is not (:data:`ALPHA` per channel).

Not every correlated residual is a model's miss. The fit's model of a closed loop leaves out
the counts of the encoders in the controller's feedback (:mod:`.loop_model`), and the loop's
answer to them is a dither of the output of a tenth of a count over some tens of
milliseconds: on the rotary flap its block means came out 1.0 to 1.4 times what white noise
leaves, in one log of twelve beyond the test's quantile. A residual whose block means are
within :data:`MAX_RATIO` of white noise's passes as noise correlated in time, and the fit's
intervals allow for it: they are at least the cluster-robust ones
(:func:`robust_inflation`, over :data:`CLUSTERS` stretches of the log). Beyond it the model
misses: the damping and friction above gave 1.7 to 2.3.

The test holds the intervals to their assumption as much as the model to the data: the
intervals of a fit, ``s^2 (J^T J)^-1``, are those of white noise, and a noise correlated
over the blocks (a current sensor's filter, a drive's ripple) makes them too narrow by as
much as the test finds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import stats

#: blocks a channel's residual is cut into (fewer when it has fewer than 4 samples per block)
BLOCKS = 200
#: fewest samples per block
MIN_WIDTH = 4
#: false alarm of the test on a white residual, per channel
ALPHA = 1e-3
#: RMS of the block means over their white-noise value up to which a residual correlated in
#: time is taken as noise (the intervals allow for it, :func:`robust_inflation`)
MAX_RATIO = 1.5
#: a block misses when its mean exceeds this many of its standard deviations
BLOCK_SIGMAS = 4.0
#: stretches of time of the intervals' covariance robust to a correlated residual
CLUSTERS = 25


@dataclass(frozen=True)
class BlockTest:
    """The test of one channel's residual.

    Attributes
    ----------
    width : int
        Samples per block.
    ratio : float
        RMS of the block means over their standard deviation for white noise (1 expected).
    p_value : float
        Probability of a sum of squares as large from white noise.
    missed : numpy.ndarray
        Per block: its mean exceeds :data:`BLOCK_SIGMAS` of its standard deviation.
    """

    width: int
    ratio: float
    p_value: float
    missed: np.ndarray

    @property
    def white(self) -> bool:
        """True when the residual passes as noise: white, or correlated in time by at most
        :data:`MAX_RATIO`."""
        return self.p_value >= ALPHA or self.ratio <= MAX_RATIO


def _run_squares(values, width: int, blocks: int) -> np.ndarray:
    """Per block: the sum of the squared lengths of its runs of equal samples."""
    v = np.asarray(values, float)[: blocks * width].reshape(blocks, width)
    out = np.empty(blocks)
    for b, row in enumerate(v):
        edges = np.flatnonzero(np.diff(row) != 0) + 1
        lengths = np.diff(np.concatenate([[0], edges, [width]]))
        out[b] = float(np.sum(lengths.astype(float) ** 2))
    return out


def block_test(residual, measured, quantum: float = 0.0, blocks: int = BLOCKS) -> BlockTest | None:
    """Test a channel's residual for whiteness by its block means.

    Parameters
    ----------
    residual : array_like
        Model minus measurement, one channel, in time order.
    measured : array_like
        The measurement (its runs of equal samples, for a rounded one).
    quantum : float
        Standard deviation of the measurement's rounding (its count over sqrt(12); 0 for a
        continuous one), in the residual's unit.
    blocks : int
        Blocks to cut the residual into.

    Returns
    -------
    BlockTest or None
        None with fewer than 2 blocks of :data:`MIN_WIDTH` samples, or a residual of zero.
    """
    r = np.asarray(residual, float)
    width = max(MIN_WIDTH, r.size // blocks)
    n = r.size // width
    s2 = float(np.mean(r ** 2))
    if n < 2 or not s2 > 0:
        return None
    means = r[: n * width].reshape(n, width).mean(axis=1)
    q2 = min(float(quantum) ** 2, s2)
    var = (s2 - q2) / width + q2 * _run_squares(measured, width, n) / width ** 2
    z2 = means ** 2 / var
    total = float(np.sum(z2))
    return BlockTest(width=width, ratio=math.sqrt(total / n), p_value=float(stats.chi2.sf(total, n)),
                     missed=z2 > BLOCK_SIGMAS ** 2)


def clusters(points: int, channels: int, count: int = CLUSTERS) -> np.ndarray:
    """The stretch of time (0 to ``count`` - 1) of each element of a residual vector of
    ``channels`` blocks of ``points`` samples: the samples of every channel at the same time
    share one."""
    one = np.minimum(np.arange(points) * count // max(points, 1), count - 1)
    return np.tile(one, channels)


def robust_inflation(jac, resid, groups) -> tuple[np.ndarray, int]:
    """Per parameter, the factor (at least 1) by which the standard error of a least-squares
    estimate grows when the residual is correlated within stretches of time.

    The sandwich ``(J^T J)^-1 (sum_g J_g^T r_g r_g^T J_g) (J^T J)^-1 G / (G - 1)`` over the
    stretches ``g`` (the cluster-robust covariance: the residual may be correlated within a
    stretch, not between two) against ``s^2 (J^T J)^-1``, the covariance of white noise.

    Returns
    -------
    factor : numpy.ndarray
        sqrt of the ratio of the two variances, at least 1 (nan where ``J^T J`` is singular).
    dof : int
        Degrees of freedom of the robust variance: stretches - 1.
    """
    jac, r = np.asarray(jac, float), np.asarray(resid, float)
    ids = np.unique(groups)
    g = np.array([jac[groups == k].T @ r[groups == k] for k in ids])
    inv = np.linalg.pinv(jac.T @ jac)
    robust = inv @ (g.T @ g) @ inv * ids.size / max(ids.size - 1, 1)
    s2 = float(r @ r) / max(r.size - jac.shape[1], 1)
    white = np.diag(inv) * s2
    with np.errstate(invalid="ignore", divide="ignore"):
        factor = np.sqrt(np.diag(robust) / white)
    return np.maximum(factor, 1.0), int(ids.size - 1)


__all__ = ["ALPHA", "BLOCKS", "BlockTest", "CLUSTERS", "MAX_RATIO", "block_test", "clusters", "robust_inflation"]
