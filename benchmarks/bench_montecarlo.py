"""Nonlinear Monte Carlo timing against its two targets.

Run: python3 benchmarks/bench_montecarlo.py [N [N_ONE_CORE [N_EXACT]]]   (default 10000, 1000 and 0 variants)

On the reference EMA (scenes/ema_reference.toml), its designed controller and simulate's
default command (8 Hz, 2 deg sine for 1 s, reduced model), prints:

- the integration time of one single run (``servo_toolkit.sim.run``, best of ``REPEATS``) and
  the batch's integration time per variant (``N_ONE_CORE`` variants of load inertia 0..4
  kg*m^2 and stiffness +-30 %, best of ``REPEATS``) on one thread and on every core: target
  on every core (2) <= 1/2 of the single run;
- N variants on every core: the integration time and the end-to-end time of
  ``montecarlo()`` (variant rows, initial states, step checks; the design excluded):
  target < 10 s for 10,000 variants. A short call before it imports what the study needs
  (its time is printed apart).

- N_EXACT > 0: ``montecarlo()`` of N_EXACT variants with every variant built by
  ``build_model`` (the path taken when the fitted rows do not verify), and of the same
  variants with the fitted rows, for the cost per variant of each.

Every figure is wall time on this machine as it is: the load average is printed with them
(other jobs on a shared machine slow every figure).
"""

from __future__ import annotations

import math
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout

from servo_toolkit.loop.robustness import sample_variants  # noqa: E402
from servo_toolkit.scene.loader import load_scene  # noqa: E402
from servo_toolkit.sim import controller_for, run  # noqa: E402
from servo_toolkit.sim.batch_run import integrate_variants, worker_threads  # noqa: E402
from servo_toolkit.sim.reference import fill, initial_state  # noqa: E402
from servo_toolkit.studies.time.reference import run_spec  # noqa: E402
from servo_toolkit.sim.variants import VariantBuilder  # noqa: E402
from servo_toolkit.studies.montecarlo import montecarlo  # noqa: E402
from servo_toolkit.studies.time.run import sine_run_options  # noqa: E402

REPEATS = 5
RANGES = {"load_inertia": (0.0, 4.0), "stiffness": (0.7, 1.3)}


def main(n: int = 10_000, n_one: int = 1000, n_exact: int = 0) -> None:
    scene = load_scene(Path(__file__).resolve().parents[1] / "scenes" / "ema_reference.toml")
    controller, _ = controller_for(scene)
    reference, duration, *_ = run_spec(scene, None)
    options, _ = sine_run_options(scene, controller, reference)
    builder = VariantBuilder.create(scene, controller, options)
    single = [run(builder.model, reference, duration, "auto") for _ in range(REPEATS + 1)]
    dt, steps = single[0].dt_s, single[0].steps
    t_single = min(r.wall_s for r in single[1:])
    cores = worker_threads()
    print(f"reference EMA, {duration:g} s of the {reference.describe()}, dt {dt:.3g} s, {steps} steps; "
          f"{cores} cores; load average {os.getloadavg()[0]:.2f} (a shared machine: other jobs slow every figure)")
    print(f"single run (sim.run, integration only, best of {REPEATS}): {t_single * 1e3:.2f} ms")

    values = sample_variants(RANGES, n_one, False, 0)
    P0 = fill(builder.model, reference)
    P, T, tix = builder.rows(P0, values, None)
    X0 = np.array([initial_state(builder.model, p) for p in P])
    sub = int(round(builder.model.sample_time / dt))
    for threads in (1, cores):
        walls = [integrate_variants(P, T, tix, X0, dt, steps, sub, threads=threads)[3] for _ in range(REPEATS)]
        per = min(walls) / n_one
        target = "" if threads == 1 else (f" (target <= 0.5 on 2 cores: "
                                          f"{'met' if per <= t_single / 2 else 'NOT met'})")
        print(f"batch, {threads} thread{'s' if threads > 1 else ''}, {n_one} variants: {per * 1e3:.2f} ms per "
              f"variant = {per / t_single:.2f} x the single run{target}")

    start = time.perf_counter()
    montecarlo(scene, RANGES, samples=2, controller=controller, progress=False, duration=0.01)
    print(f"first montecarlo() call (imports): {time.perf_counter() - start:.1f} s")
    start = time.perf_counter()
    result = montecarlo(scene, RANGES, samples=n, controller=controller, progress=False)
    total = time.perf_counter() - start
    print(f"montecarlo(), {n} variants on {cores} cores: integration {result.wall_s:.2f} s, end to end {total:.2f} s "
          f"(target < 10 s for 10000: {'met' if total < 10 * n / 10_000 else 'NOT met'}); load average "
          f"{os.getloadavg()[0]:.2f}")
    print(f"  {result.summary()}")
    print(f"  {[note for note in result.notes if 'variant' in note and 'rows' in note or 'one by one' in note]}")
    if n_exact > 0:
        import servo_toolkit.studies.montecarlo.run as mc
        default, runs = mc.FIT_OVERHEAD, []
        for label, overhead in (("fitted rows", -10**9), ("build_model per variant", 10**9)):
            mc.FIT_OVERHEAD = overhead  # fit even a few variants / never fit
            start = time.perf_counter()
            r = montecarlo(scene, RANGES, samples=n_exact, controller=controller, progress=False)
            total = time.perf_counter() - start
            print(f"montecarlo(), {n_exact} variants, {label}: integration {r.wall_s:.2f} s, end to end "
                  f"{total:.2f} s; load average {os.getloadavg()[0]:.2f}")
            runs.append(r)
        mc.FIT_OVERHEAD = default
        fitted, exact = runs
        ok = ~exact.failed
        print(f"  fitted against exact: the same failed variants {np.array_equal(fitted.failed, exact.failed)} "
              f"({int(np.sum(exact.failed))}); largest relative difference of the others' tracking error "
              f"{np.max(np.abs(fitted.tracking_error - exact.tracking_error)[ok] / exact.tracking_error[ok]):.2g}, "
              f"peak current {np.max(np.abs(fitted.peak_current - exact.peak_current)[ok] / exact.peak_current[ok]):.2g}")
    if not math.isfinite(result.wall_s):
        raise SystemExit(1)


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:4]))
