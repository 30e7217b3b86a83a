"""The figures an engineer reads off a closed-loop step and sine of the actuator.

Pure functions of sampled traces (times in s, positions in the output's SI unit, currents in
A, voltages in V), so each one is tested against a closed form:

- :func:`step_figures`: overshoot (fraction of the step) and the settling time into a band
  about the final value (infinite when the run ends outside it);
- :func:`limit_cycle`: a sustained oscillation of a signal over a window, its amplitude (half
  the peak-to-peak) and its frequency (from the crossings of its mean), or none below a
  resolution;
- :func:`ripple`: the rms of a current the motion does not need: its part above a cutoff
  (:data:`HARMONICS` times the command's frequency, above the motion's own content);
- :func:`time_at_limit`: the time a signal spends within a band of its limit (a current
  pinned at 99 % of its limit is at the limit).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: a signal within this fraction of its limit is at the limit (a drive's current loop
#: settles a little inside its clamp: 99 % of the limit is pinned there)
LIMIT_BAND = 0.01
#: the ripple's cutoff, in multiples of the command's frequency (the required bandwidth): a
#: friction or a backlash turns a sine's current into a square-ish wave, whose odd harmonics up
#: to the ninth carry 96 % of its power
HARMONICS = 10


@dataclass(frozen=True)
class LimitCycle:
    """A sustained oscillation over a window.

    Attributes
    ----------
    amplitude : float
        Half the peak-to-peak over the window (the signal's unit).
    frequency : float
        Hz, from the crossings of the window's mean (NaN when it crosses fewer than twice).
    """

    amplitude: float
    frequency: float

    def to_dict(self) -> dict:
        return {"amplitude": self.amplitude, "frequency_Hz": self.frequency}


def step_figures(t, y, size: float, band: float) -> tuple[float, float]:
    """Overshoot and settling time of a step response.

    Parameters
    ----------
    t, y : numpy.ndarray
        Times from the step (s) and the response's change from its start.
    size : float
        The step (nonzero).
    band : float
        Half-width of the settling band about ``size`` (the signal's unit, positive).

    Returns
    -------
    overshoot : float
        How far the response goes past the step, as a fraction of it (0 when it does not).
    settling : float
        The time (s) after which the response stays within the band; ``inf`` when it ends
        outside it, ``t[0]`` when it never leaves it.
    """
    t, y = np.asarray(t, float), np.asarray(y, float)
    yn = y / size
    over = max(0.0, float(np.max(yn) - 1.0))
    outside = np.nonzero(np.abs(y - size) > band)[0]
    if not outside.size:
        return over, float(t[0])
    last = outside[-1]
    return over, (math.inf if last + 1 >= t.size else float(t[last + 1]))


def limit_cycle(t, y, resolution: float) -> LimitCycle | None:
    """The oscillation of ``y`` over the window ``t``, or None when its half peak-to-peak is
    within ``resolution`` or it crosses its mean fewer than four times (no cycle to speak of:
    a drift or a creep to rest)."""
    t, y = np.asarray(t, float), np.asarray(y, float)
    amplitude = 0.5 * float(np.max(y) - np.min(y))
    if not amplitude > resolution:
        return None
    s = np.sign(y - 0.5 * (np.max(y) + np.min(y)))
    s = s[s != 0]
    crossings = int(np.count_nonzero(np.diff(s)))
    if crossings < 4:
        return None
    return LimitCycle(amplitude, 0.5 * crossings / float(t[-1] - t[0]))


def ripple(t, i, cutoff: float) -> float:
    """The rms of the part of a current ``i`` (evenly sampled at ``t``) above ``cutoff`` (Hz):
    the current a motion does not need when the motion's own content lies below it (a sine's
    first harmonics, a step's transient, a load held still).

    The line joining the window's first and last samples is taken off first, so the window
    repeats without a jump and a slow motion leaks nothing above the cutoff; the spectrum
    above the cutoff is transformed back and its rms taken (Parseval).
    """
    t, i = np.asarray(t, float), np.asarray(i, float)
    if i.size < 4:
        return 0.0
    x = i - (i[0] + (i[-1] - i[0]) * (t - t[0]) / (t[-1] - t[0]))
    spectrum = np.fft.rfft(x)
    freqs = np.fft.rfftfreq(x.size, d=(t[-1] - t[0]) / (x.size - 1))
    high = np.fft.irfft(np.where(freqs > cutoff, spectrum, 0.0), x.size)
    return rms(high)


def time_at_limit(t, x, limit: float, band: float = LIMIT_BAND) -> float:
    """Seconds ``|x|`` spends at or above ``(1 - band) * limit`` (0 for an infinite limit);
    each record stands for the interval to the next."""
    if not math.isfinite(limit):
        return 0.0
    t = np.asarray(t, float)
    dt = np.diff(t, append=t[-1])
    return float(np.sum(dt[np.abs(np.asarray(x, float)) >= (1.0 - band) * limit]))


def rms(x) -> float:
    """Root mean square."""
    x = np.asarray(x, float)
    return float(np.sqrt(np.mean(x * x)))


__all__ = ["HARMONICS", "LIMIT_BAND", "LimitCycle", "limit_cycle", "ripple", "rms", "step_figures", "time_at_limit"]
