"""One period of a rig's excitation signal: a multisine with a low crest factor, a
maximum-length binary sequence (PRBS) or a periodic linear chirp, sampled at the drive's
reference rate, zero mean, peak 1.

The crest factor (peak over rms) says how much of the drive's range a signal spends on its
peaks instead of on power at its lines: a sine's is sqrt(2), a binary sequence's 1, and N
equal cosines in phase sqrt(2 N).

Multisine
    Equal cosines on consecutive lines of the period, Schroeder's phases
    ``-pi n (n - 1) / N`` for the n-th of N lines (:func:`servo_toolkit.studies.multisine.run.schroeder`;
    M. R. Schroeder, "Synthesis of low-peak-factor signals and binary sequences with low
    autocorrelation", IEEE Trans. Information Theory 16, 1970): the phase grows
    quadratically with frequency, so the signal is nearly a chirp sweeping the band once a
    period with a nearly constant envelope, and its crest factor tends to a chirp's, sqrt(2),
    as the lines grow in number (for an odd N the analytic signal's magnitude is exactly
    sqrt(N) at the N instants k T / N: a quadratic-phase Gauss sum). The envelope's ripple
    between those instants leaves it near 1.7-1.9; time-frequency swapping (P. Van der
    Ouderaa, J. Schoukens and J. Renneboog, "Peak factor minimization using a time-frequency
    domain swapping algorithm", IEEE Trans. Instrumentation and Measurement 37, 1988;
    Pintelon and Schoukens, System Identification, 2nd ed., 2012, sec. 5.4) then clips the
    peaks, restores the amplitude spectrum and keeps the new phases, which brings it near 1.5.
    The lowest crest factor found from Schroeder's phases and from a few random ones (drawn
    with the seed) is kept: never above Schroeder's.
PRBS
    A maximum-length sequence of n bits (scipy.signal.max_len_seq; the seed sets the shift
    register's start), 2^n - 1 bits a period, each held ``clock`` samples: power flat within
    the clock rate's sinc^2 (-3 dB at 0.443 of it), crest factor 1 (its one-bit mean removed).
Chirp
    ``sin(2 pi (k_lo t / T + (k_hi - k_lo) t^2 / (2 T^2)))`` over one period T: the
    frequency sweeps from line k_lo to k_hi and wraps, the phase continuous at the wrap
    (k_hi - k_lo even); crest factor sqrt(2).
"""

from __future__ import annotations

import math

import numpy as np

from ..multisine import schroeder

SIGNALS = ("multisine", "prbs", "chirp")
#: time-frequency swapping: the clip level, a fraction of the current peak
CLIP_LEVEL = 0.9
#: swapping iterations from each start (fewer for a long period: ITERATION_WORK samples x
#: iterations at most)
SWAP_ITERATIONS = 200
ITERATION_WORK = 30_000_000
#: random-phase starts besides Schroeder's
RESTARTS = 3


def crest_factor(x) -> float:
    """Peak over rms of ``x`` (its mean removed)."""
    x = np.asarray(x, float) - float(np.mean(x))
    rms = math.sqrt(float(np.mean(x * x)))
    return float(np.max(np.abs(x))) / rms if rms > 0 else math.inf


def _equal_lines(phases, lines, samples: int) -> np.ndarray:
    """One period of unit cosines on bins ``lines`` with ``phases``."""
    spectrum = np.zeros(samples // 2 + 1, complex)
    spectrum[lines] = np.exp(1j * np.asarray(phases, float))
    return np.fft.irfft(spectrum, samples)


def _swap(x, lines, iterations: int) -> np.ndarray:
    """Time-frequency swapping from ``x``: the lowest crest factor met (amplitudes equal)."""
    best, best_cf = x, crest_factor(x)
    for _ in range(iterations):
        peak = float(np.max(np.abs(x)))
        clipped = np.fft.rfft(np.clip(x, -CLIP_LEVEL * peak, CLIP_LEVEL * peak))
        x = _equal_lines(np.angle(clipped[lines]), lines, x.size)
        cf = crest_factor(x)
        if cf < best_cf:
            best, best_cf = x, cf
    return best


def multisine(lines, samples: int, seed: int = 0) -> np.ndarray:
    """One period (``samples``) of equal cosines on the bins ``lines`` (whole multiples of
    the period's fundamental, below ``samples / 2``), crest factor lowered from Schroeder's
    phases (module doc), peak 1."""
    lines = np.asarray(lines, int)
    iterations = max(10, min(SWAP_ITERATIONS, ITERATION_WORK // max(samples, 1)))
    rng = np.random.default_rng(seed)
    starts = [schroeder(lines, samples)]
    starts += [_equal_lines(rng.uniform(0, 2 * math.pi, lines.size), lines, samples) for _ in range(RESTARTS)]
    found = [_swap(x, lines, iterations) for x in starts]
    best = min(found, key=crest_factor)  # each search keeps its start when it finds nothing lower
    return _from_quietest(best / np.max(np.abs(best)))


def _from_quietest(x) -> np.ndarray:
    """The period started at its sample nearest zero (a periodic signal's start is a choice:
    the drive then starts the excitation without a step)."""
    return np.roll(x, -int(np.argmin(np.abs(x))))


def prbs(bits: int, clock: int, seed: int = 0) -> np.ndarray:
    """One period of a maximum-length sequence of ``bits`` bits, each held ``clock``
    samples, mean removed, peak 1."""
    from scipy.signal import max_len_seq
    rng = np.random.default_rng(seed)
    state = rng.integers(0, 2, bits)
    if not state.any():
        state[0] = 1
    seq = 2.0 * max_len_seq(bits, state=state)[0] - 1.0
    x = np.repeat(seq - seq.mean(), clock)
    return x / np.max(np.abs(x))


def chirp(first: int, last: int, samples: int) -> np.ndarray:
    """One period (``samples``) of a linear chirp from bin ``first`` to bin ``last``
    (``last - first`` even: the phase is continuous where the period wraps), mean removed,
    peak 1."""
    t = np.arange(samples) / samples
    x = np.sin(2 * math.pi * (first * t + 0.5 * (last - first) * t * t))
    x = x - x.mean()
    return x / np.max(np.abs(x))


__all__ = ["SIGNALS", "chirp", "crest_factor", "multisine", "prbs"]
