"""Sizing figures of the reference EMA along its duty cycle (``scenes/ema_sizing.toml``), best
of several repeats after a first call that loads the libraries:

- ``servo-toolkit size scenes/ema_sizing.toml`` as a command, warm (a new process: import,
  scene, inverse dynamics, thermal, lives and the 50-ratio sweep; target: under 5 s);
- ``size(scene)`` in this process, with and without the sweep;
- the 50-ratio sweep alone (``ratio_sweep``: array arithmetic over the ratios, one small
  eigenproblem per ratio for the bandwidth estimate) against 50 inverse-dynamics runs of the
  cycle, what a sweep that re-ran the mechanics per ratio would cost at the least;
- ``size(scene, closed_loop=True)`` with the scene's design given (the simulations alone);
- the bandwidth estimate at the scene's ratio against the scene's design, and whether a design
  asked for 1.5 times the estimate meets every requirement.

Run it on an idle machine: ``python benchmarks/bench_size.py``. The test suite asserts no wall
time; these figures live here.
"""

from __future__ import annotations

import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

import servo_toolkit as st
from servo_toolkit.loop.design import design
from servo_toolkit.studies.sizing.cycle import sample_cycle
from servo_toolkit.studies.sizing.loads import cycle_loads
from servo_toolkit.studies.sizing.sweep import ratio_sweep

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "scenes" / "ema_sizing.toml"
TARGET_SIZE_S = 5.0


def best(function, repeats: int = 5) -> float:
    """Best wall time (s) of ``repeats`` calls."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return min(times)


def _command() -> None:
    subprocess.run([sys.executable, "-m", "servo_toolkit", "size", str(SCENE)], cwd=ROOT, check=False,
                   capture_output=True)


def main() -> None:
    scene = st.load_scene(SCENE)
    st.size(scene)                                   # loads the libraries
    _command()
    t_cli = best(_command, repeats=3)
    t_size = best(lambda: st.size(scene))
    t_plain = best(lambda: st.size(scene, sweep=False))
    duty, train = scene.duty_cycle, scene.drivetrain
    motion = sample_cycle(duty, train.mid_stroke, scene.load.hinge_moment)
    loads = cycle_loads(train, motion)
    factors = np.geomspace(duty.ratio_range[0], duty.ratio_range[1], duty.ratio_points)
    motors = (("scene motor", train.motor),) + tuple(duty.motors)
    t_sweep = best(lambda: ratio_sweep(train, motion, loads, motors, factors,
                                       required_bandwidth=scene.requirements.bandwidth))
    t_loads = best(lambda: cycle_loads(train, motion))
    print(f"servo-toolkit size (command, warm)   {t_cli:7.3f} s   target < {TARGET_SIZE_S:g} s   "
          f"{'ok' if t_cli < TARGET_SIZE_S else 'OVER'}")
    print(f"size(scene) in process               {t_size:7.3f} s   (without the sweep {t_plain:.3f} s)")
    print(f"ratio sweep, {factors.size} ratios, {len(motors)} motor(s)    {t_sweep * 1e3:7.1f} ms  "
          f"({t_sweep / factors.size * 1e3:.2f} ms per ratio); one inverse-dynamics run of the cycle "
          f"{t_loads * 1e3:.1f} ms, x {factors.size} = {t_loads * factors.size:.2f} s: "
          f"{t_loads * factors.size / t_sweep:.0f}x the sweep")
    result = design(scene)
    t_closed = best(lambda: st.size(scene, closed_loop=True, sweep=False, controller=result.controller), repeats=3)
    print(f"size(scene, closed_loop=True)         {t_closed:7.3f} s   (the scene's design given)")
    sweep = st.size(scene).sweep
    estimate = float(np.interp(1.0, sweep.factors, sweep.bandwidth[0]))
    achieved = result.margins.bandwidth_hz
    met = all(r.passed for r in result.requirements)
    higher = design(replace(scene, requirements=replace(scene.requirements, bandwidth=1.5 * estimate)))
    missed = [r.name for r in higher.requirements if not r.passed]
    print(f"bandwidth estimate at the scene ratio {estimate:7.3f} Hz; the design's {achieved:.3f} Hz "
          f"(every requirement {'met' if met else 'NOT met'}): estimate / design = {estimate / achieved:.3f}")
    print(f"design asked for 1.5 x the estimate ({1.5 * estimate:.2f} Hz): "
          f"{'misses ' + ', '.join(missed) if missed else 'meets every requirement'} "
          f"(reaches {higher.margins.bandwidth_hz:.3f} Hz)")


if __name__ == "__main__":
    main()
