"""Coverage of the measured margins' 95 % intervals when an encoder rounds the logged angle.

The rig is the reference EMA's model response on 25 lines per decade from 1 to 200 Hz (the
log of ``tests/test_measured_interval.py``: 1024 samples/s, a period of 4096 samples, 5
periods of which 4 are averaged). Each log is a multisine of its own random phases whose motor
angle is rounded to a step of ``std(angle) / STEPS`` on a grid of random offset, optionally
with white noise of ``NOISE`` steps besides; ``frf``'s periodic H1 gives the response with
the rounding's error (``resolution=(0, step)``), and ``check --plant-frf``'s loop
(``measured_loop``) its margins and intervals, once without and once with that error.

Printed per figure (gain margin, phase margin, Ms): how many of the logs' intervals contain
the unrounded loop's figure, without and with the rounding's part, the figures' scatter and
their mean error.

``python benchmarks/bench_rounding_coverage.py [STEPS] [NOISE] [LOGS]`` (default 30 steps of
RMS, no noise, 50 logs): 30, 10, 3, 1 and 0.5 steps are the rounding the model describes,
0.25 one it does not (``identify.resolution.MIN_RMS_STEPS``).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from servo_toolkit import design, load_scene  # noqa: E402
from servo_toolkit.identify.frf import estimate_frf  # noqa: E402
from servo_toolkit.loop.measured import measured_loop, model_response  # noqa: E402

FS, PERIOD, PERIODS = 1024.0, 4096, 5
BINS = np.unique(np.round(np.geomspace(1.0, 200.0, 59) / (FS / PERIOD)).astype(int))
FIGURES = (("gain margin", "gm"), ("phase margin", "pm"), ("sensitivity peak Ms", "ms"))


def figures(m) -> dict:
    return {"gm": m.gain_margin_db, "pm": m.phase_margin_deg, "ms": m.sensitivity_peak[0]}


def rig_log(h, seed):
    """One period of a random-phase multisine current whose angle has the same power at every
    line, tiled over the periods: ``(t, u, y)``."""
    u_lines = np.zeros(PERIOD // 2 + 1, complex)
    u_lines[BINS] = np.exp(2j * np.pi * np.random.default_rng(seed).uniform(size=BINS.size)) / np.abs(h)
    y_lines = np.zeros_like(u_lines)
    y_lines[BINS] = u_lines[BINS] * h
    u, y = np.fft.irfft(u_lines, PERIOD), np.fft.irfft(y_lines, PERIOD)
    return np.arange(PERIOD * PERIODS) / FS, np.tile(u, PERIODS), np.tile(y, PERIODS)


def main():
    steps = float(sys.argv[1]) if len(sys.argv) > 1 else 30.0
    noise = float(sys.argv[2]) if len(sys.argv) > 2 else 0.0
    logs = int(sys.argv[3]) if len(sys.argv) > 3 else 50
    scene = load_scene()
    r = design(scene, progress=False)
    f = BINS * FS / PERIOD
    h = model_response(r, 2 * np.pi * f, "motor_angle_rad")
    truth = figures(measured_loop(r, scene.motor, f, h, np.ones_like(f)))
    covered = {k: [0, 0] for _, k in FIGURES}
    values = {k: [] for _, k in FIGURES}
    for seed in range(logs):
        t, u, y = rig_log(h, seed)
        step = float(np.std(y)) / steps
        rng = np.random.default_rng(500 + seed)
        angle = step * np.round((y + rng.normal(0.0, noise * step, y.size)) / step + rng.uniform())
        data = estimate_frf(t, u, angle, window="periodic", period=PERIOD, lines=BINS, resolution=(0.0, step))
        for with_rounding in (0, 1):
            m = measured_loop(r, scene.motor, data.frequency_hz, data.complex, data.coherence,
                              averages=data.averages, resolution_sd=data.resolution_sd if with_rounding else None)
            spans = m.intervals()
            for name, k in FIGURES:
                lo, hi = spans[name] or (math.nan, math.nan)
                covered[k][with_rounding] += lo <= truth[k] <= hi
            if with_rounding:
                for k, v in figures(m).items():
                    values[k].append(v)
    print(f"reference EMA, {logs} logs, angle RMS {steps:g} steps, noise {noise:g} steps")
    print(f"{'figure':22s} {'unrounded':>10s} {'covered without':>16s} {'with rounding':>14s} {'scatter':>9s} "
          f"{'mean error':>11s}")
    for name, k in FIGURES:
        v = np.asarray(values[k])
        print(f"{name:22s} {truth[k]:10.4g} {covered[k][0]:>10d} of {logs} {covered[k][1]:>8d} of {logs} "
              f"{np.std(v, ddof=1):9.3g} {np.mean(v) - truth[k]:11.3g}")


if __name__ == "__main__":
    main()
