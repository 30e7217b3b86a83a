"""The excitation's band, period and length (:class:`ExcitationPlan`), and the defaults a
scene's loop gives them.

The period sets the frequency resolution (its inverse); the lines are whole multiples of it
within the band; ``settle`` periods run first (the response's transient) and ``periods``
more are averaged. The signal is sampled at the drive's reference rate, whose eighth bounds
the band (harmonics up to the fourth of the highest line stay below the Nyquist rate).

Default band: a decade centred on the loop's gain crossover (crossover / sqrt(10) to
crossover x sqrt(10)), widened to twice the drivetrain's first mode when that lies above
it, so the mode's peak and the roll-off past it are measured. Default resolution: five lines
across the mode's half-power bandwidth 2 zeta f_r (a lightly damped peak is resolved),
at most the band's low end.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...errors import SceneError
from .signals import SIGNALS

#: the band's highest line at most this fraction of the drive's sample rate
MAX_BAND_FRACTION = 1 / 8
#: most samples in one period, and in the whole excitation (the file's rows)
MAX_PERIOD_SAMPLES = 200_000
MAX_SAMPLES = 400_000
#: the band beyond the first mode (its multiple) and the lines across its half-power bandwidth
PAST_MODE = 2.0
LINES_ACROSS_MODE = 5
#: a PRBS's clock rate at least this multiple of the highest line (its power is 2.6 dB down there)
PRBS_CLOCK_PER_HIGH = 2.5
#: PRBS register lengths the plan may choose
PRBS_BITS = (3, 24)
#: estimation periods by default
DEFAULT_PERIODS = 4


@dataclass(frozen=True, eq=False)
class ExcitationPlan:
    """What one excitation is made of.

    Attributes
    ----------
    signal : {"multisine", "prbs", "chirp"}
    band : (float, float)
        Lowest and highest frequency of interest (Hz).
    sample_time : float
        The drive's reference sample time (s).
    period_samples : int
    periods, settle : int
        Periods averaged, and run first.
    lines : numpy.ndarray
        The excited bins of the period's DFT within the band (the frequencies estimated).
    bits, clock : int
        PRBS: register length and samples per bit (0 and 1 for the other signals).
    """

    signal: str
    band: tuple
    sample_time: float
    period_samples: int
    periods: int
    settle: int
    lines: np.ndarray
    bits: int = 0
    clock: int = 1

    @property
    def period_s(self) -> float:
        """The period (s)."""
        return self.period_samples * self.sample_time

    @property
    def resolution_hz(self) -> float:
        """Spacing of the period's lines (Hz)."""
        return 1.0 / self.period_s

    @property
    def frequency_hz(self) -> np.ndarray:
        """The excited lines within the band (Hz)."""
        return self.lines * self.resolution_hz

    @property
    def samples(self) -> int:
        """Samples of the whole excitation, settling periods included."""
        return (self.settle + self.periods) * self.period_samples

    @property
    def duration_s(self) -> float:
        """The whole excitation's length (s)."""
        return self.samples * self.sample_time


def default_band(crossover_hz: float, mode_hz: float, sample_time: float) -> tuple[tuple, list]:
    """The default band (module doc) and notes on it; capped at the drive's rate."""
    notes = []
    lo, hi = crossover_hz / math.sqrt(10.0), crossover_hz * math.sqrt(10.0)
    if math.isfinite(mode_hz):
        if PAST_MODE * mode_hz > hi:
            hi = PAST_MODE * mode_hz
    else:
        notes.append("rigid drivetrain: no mode to reach past; the band is the decade around the crossover")
    top = MAX_BAND_FRACTION / sample_time
    if hi > top:
        notes.append(f"band capped at {top:.4g} Hz, an eighth of the drive's sample rate (it would reach "
                     f"{hi:.4g} Hz)")
        hi = top
    return (lo, hi), notes


def default_resolution(band, mode_hz: float, damping_ratio: float) -> float:
    """Five lines across the mode's half-power bandwidth, at most the band's low end (Hz)."""
    res = band[0]
    if math.isfinite(mode_hz) and band[0] < mode_hz < band[1] * 1.01 and damping_ratio > 0:
        res = min(res, 2 * damping_ratio * mode_hz / LINES_ACROSS_MODE)
    return res


def make_plan(signal: str, band, resolution: float, periods: int, settle: int, sample_time: float) -> ExcitationPlan:
    """The plan of a signal over ``band`` (Hz) at ``resolution`` (Hz; the period's samples
    rounded up, so the resolution is at most the one asked for).

    Raises
    ------
    SceneError
        Naming the option: a band outside (0, an eighth of the sample rate], a resolution
        that leaves fewer than two lines in the band or a period beyond
        :data:`MAX_PERIOD_SAMPLES`, an excitation beyond :data:`MAX_SAMPLES` samples.
    """
    if signal not in SIGNALS:
        raise SceneError("--signal", f"must be one of {', '.join(SIGNALS)} (got {signal!r})")
    lo, hi = (float(b) for b in band)
    fs = 1.0 / sample_time
    if not 0 < lo < hi < math.inf:
        raise SceneError("--band", f"must be LO:HI with 0 < LO < HI (got {lo:g}:{hi:g} Hz)")
    if hi > MAX_BAND_FRACTION * fs * (1 + 1e-9):
        raise SceneError("--band", f"the highest frequency {hi:.4g} Hz must be at most "
                         f"{MAX_BAND_FRACTION * fs:.4g} Hz, an eighth of the drive's sample rate {fs:.6g} Hz "
                         f"(the scene's sensors.sample_time)")
    if not resolution > 0:
        raise SceneError("--resolution", f"must be positive (got {resolution:g} Hz)")
    bits, clock = 0, 1
    n = resolution * sample_time
    if signal == "prbs":
        clock = max(1, int(fs / (PRBS_CLOCK_PER_HIGH * hi)))
        want = math.log2(1.0 / (n * clock) + 1.0) if n * clock > 0 else math.inf
        bits = max(PRBS_BITS[0], math.ceil(want - 1e-9))
        if bits > PRBS_BITS[1]:
            raise SceneError("--resolution", f"{resolution:g} Hz needs a PRBS of more than {PRBS_BITS[1]} bits: "
                             "a coarser resolution")
        samples = (2 ** bits - 1) * clock
    else:
        samples = math.ceil(1.0 / n - 1e-9) if 1.0 / n < 1e12 else math.inf
    if samples > MAX_PERIOD_SAMPLES:
        raise SceneError("--resolution", f"{resolution:g} Hz makes a period of {samples:.4g} samples at the drive's "
                         f"{fs:.4g} Hz, more than {MAX_PERIOD_SAMPLES}: a coarser resolution")
    samples = int(samples)
    res = 1.0 / (samples * sample_time)
    first, last = math.ceil(lo / res - 1e-9), math.floor(hi / res + 1e-9)
    if signal == "chirp" and (last - first) % 2:
        last -= 1  # the chirp's phase continuous where the period wraps
    if last - first < 1:
        raise SceneError("--resolution", f"{res:.4g} Hz leaves fewer than two lines in the band {lo:.4g}-{hi:.4g} Hz: "
                         "a finer resolution or a wider band")
    total = (settle + periods) * samples
    if total > MAX_SAMPLES:
        raise SceneError("--periods", f"{settle} settling + {periods} periods of {samples} samples are {total} "
                         f"samples, more than {MAX_SAMPLES} (the file's rows): fewer periods or a coarser "
                         "--resolution")
    return ExcitationPlan(signal, (lo, hi), float(sample_time), samples, int(periods), int(settle),
                          np.arange(first, last + 1), bits, clock)


def settle_periods(decay_rate: float, period_s: float) -> int:
    """Periods spanning five time constants of ``decay_rate`` (1/s), at least one."""
    if not decay_rate > 0 or not math.isfinite(5.0 / decay_rate / period_s):
        return 1
    return max(1, math.ceil(5.0 / decay_rate / period_s))


__all__ = ["DEFAULT_PERIODS", "ExcitationPlan", "default_band", "default_resolution", "make_plan", "settle_periods"]
