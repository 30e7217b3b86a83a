"""What the drivetrain's play and the motor encoder let the speed loop do.

Two nonlinear effects the linear design does not see put a ceiling on the speed-loop gain:

**A backlash limit cycle.** The position is measured at the load, beyond the play: while the
motor side crosses the play, the loop is open at the load. With a load held by its friction
or damping (it stops when the motor side lets go of it), the play acts as the backlash
operator (hysteresis) from the motor side's position p to the load's q, whose describing
function for p = A sin(w t), half-play b, unit slope, is (Slotine & Li, Applied Nonlinear
Control, 1991, sec. 5.3; Gelb & Vander Velde, 1968)::

    N(A) = (b1 + j a1) / A,   u = 2 b / A - 1   (A > b)
    b1 = A / pi (pi / 2 - asin(u) - u sqrt(1 - u^2)),   a1 = 4 b / pi (b / A - 1)

a gain below 1 with a phase lag up to 90 deg. The rest of the loop, seen from the play, is the
motor side alone under its controller: with the load detached, p = -G(s) q with
``G = D Cy P1m / (1 + D Cw N s P1m)``, P1m the motor side's position per current command (its
inertia, friction and current loop), Cy and Cw the controller's position and speed paths, D
the sampling delay. Harmonic balance, ``1 + G(jw) N(A) = 0``, predicts a limit cycle where
G(jw) meets -1/N(A): its amplitude A (of the motor side, output units), its frequency w and
the current it costs, ``|Cy N(A) + Cw N j w| A``. It is stable (the one the loop settles in)
where the loop gain at the phase crossover, ``|G| |N(A)|``, falls through 1 as A grows. Since
G is linear and N depends on A / b alone, the amplitude and the current scale with the play.

**Encoder quantization.** A motor encoder of n counts per revolution reads the angle to
LSB = 2 pi / n; the quantization error, uniform with variance LSB^2 / 12 and white at the
sample rate, reaches the speed estimate through the difference over one sample, (z_k -
z_{k-1}) / Ts: variance 2 LSB^2 / 12 / Ts^2. Above the loop's bandwidth (sensitivity ~ 1) it
reaches the current through the speed path's high-frequency gain, the PI's proportional
gain Kv (A per motor rad/s), as ||K S|| bounds the control effort in robust tuning::

    i_rms = Kv LSB / (Ts sqrt(6))

Both currents are ripple the motion does not need; a ripple allowance bounds Kv.
"""

from __future__ import annotations

import cmath
import math
from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import brentq

def backlash_df(amplitude, half_play: float):
    """Describing function N(A) of the backlash operator (unit slope, half-play ``half_play``)
    for input amplitudes ``amplitude`` (same unit); 0 where A <= b (the play swallows it)."""
    a = np.asarray(amplitude, float)
    b = float(half_play)
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.clip(2.0 * b / a - 1.0, -1.0, 1.0)
        b1 = a / math.pi * (math.pi / 2 - np.arcsin(u) - u * np.sqrt(1.0 - u * u))
        a1 = 4.0 * b / math.pi * (b / a - 1.0)
        n = (b1 + 1j * a1) / a
    return np.where(a > b, n, 0.0 + 0.0j)


def detached_loop(s, p, motion, current_gains, delay):
    """G(s) the play sees: the motor side alone under the controller, from the measured load
    position to the motor side's position (output units), ``p = -G q``."""
    from .response import loop_response, plant_responses
    alone = replace(p, J2=0.0, K=math.inf, c=0.0, b2=0.0, kh=0.0)
    p1, _ = plant_responses(s, alone, *current_gains)
    cy, cw = motion.responses(s)
    return loop_response(s, p1, p1, delay, cy, cw, p.N)


@dataclass(frozen=True)
class LimitCycle:
    """A describing-function limit cycle of the play in the position loop.

    Attributes
    ----------
    amplitude : float
        Of the motor side's position, at the output (rad, or m for an output travel).
    load_amplitude : float
        Of the load's position (fundamental), |N(A)| A.
    frequency_hz : float
    current_amplitude : float
        Of the current command at the fundamental (A); rms = amplitude / sqrt(2).
    half_play : float
        b, at the output.
    """

    amplitude: float
    load_amplitude: float
    frequency_hz: float
    current_amplitude: float
    half_play: float

    @property
    def current_rms(self) -> float:
        return self.current_amplitude / math.sqrt(2.0)

    def to_dict(self) -> dict:
        """SI: output rad or m, Hz, A."""
        return {"amplitude": self.amplitude, "load_amplitude": self.load_amplitude,
                "frequency_Hz": self.frequency_hz, "current_amplitude_A": self.current_amplitude,
                "current_rms_A": self.current_rms, "half_play": self.half_play}


def _phase_crossing(w, ph, mag, target):
    """Lowest frequency where the unwrapped phase ``ph`` falls through ``target`` (rad):
    (w, magnitude there), log-interpolated; None where it never does."""
    idx = np.nonzero((ph[:-1] >= target) & (ph[1:] < target))[0]
    if idx.size == 0:
        return None
    k = idx[0]
    f = (target - ph[k]) / (ph[k + 1] - ph[k])
    lw = math.log(w[k]) + f * (math.log(w[k + 1]) - math.log(w[k]))
    return math.exp(lw), mag[k] ** (1 - f) * mag[k + 1] ** f


def backlash_limit_cycle(p, motion, current_gains, delay_response, half_play: float,
                         w_max: float = 2e4) -> LimitCycle | None:
    """The stable describing-function limit cycle of the play in the loop, or None.

    Parameters
    ----------
    p : PlantParameters
    motion : Motion
        The motion controller (its ``responses``).
    current_gains : (kp, ki)
    delay_response : callable
        s -> the sampling delay's response D(s).
    half_play : float
        b at the output (rad, or m).
    w_max : float
        Highest frequency searched (rad/s).
    """
    if not half_play > 0:
        return None
    w = np.logspace(-2, math.log10(w_max), 6000)
    s = 1j * w
    g = detached_loop(s, p, motion, current_gains, delay_response(s))
    ph = np.unwrap(np.angle(g))
    ph -= 2 * math.pi * round(ph[0] / (2 * math.pi))          # low-frequency phase in (-pi, pi]
    mag = np.abs(g)

    def crossing(x):  # N(A) and where G has the phase of -1/N(A), in [-pi, -pi/2), A = b e^x
        n = complex(backlash_df(half_play * math.exp(x), half_play))
        return n, _phase_crossing(w, ph, mag, -math.pi - cmath.phase(n))

    def excess(x):  # loop gain there less one (-1 where G never has that phase: no cycle)
        n, hit = crossing(x)
        return -1.0 if hit is None else hit[1] * abs(n) - 1.0

    xs = np.log1p(np.logspace(-6, 3, 400))                    # A / b from 1 + 1e-6 to 1001
    found = [crossing(x)[1] is not None for x in xs]
    vals = [excess(x) for x in xs]
    for k in range(len(xs) - 1):
        if found[k] and found[k + 1] and vals[k] > 0 >= vals[k + 1]:   # gain falls through 1: stable
            x = brentq(excess, xs[k], xs[k + 1], xtol=1e-12)
            amp = half_play * math.exp(x)
            n, (wc, _) = crossing(x)
            cy, cw = motion.responses(np.array([1j * wc]))
            cur = float(abs(cy[0] * n + cw[0] * p.N * 1j * wc)) * amp
            return LimitCycle(amplitude=amp, load_amplitude=abs(n) * amp, frequency_hz=wc / (2 * math.pi),
                              current_amplitude=cur, half_play=half_play)
    return None


def quantization_ripple(speed_gain: float, counts: int, sample_time: float) -> float:
    """rms current (A) of a motor encoder's quantization through the speed estimate's
    difference over one sample and the speed path's gain ``speed_gain`` (A per motor rad/s)."""
    if counts <= 0 or sample_time <= 0:
        return 0.0
    lsb = 2 * math.pi / counts
    return abs(speed_gain) * lsb / (sample_time * math.sqrt(6.0))


__all__ = ["LimitCycle", "backlash_df", "backlash_limit_cycle", "detached_loop",
           "quantization_ripple"]
