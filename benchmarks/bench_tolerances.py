"""The tolerance study against its speed targets, and the same results on a dask cluster.

Run: python3 benchmarks/bench_tolerances.py [N [N_TIME]] [--scheduler ADDRESS]

On the example scene ``scenes/examples/ema_tolerances.toml`` with six of its tolerances
(resistance, Kt, Coulomb friction, ball-screw efficiency, housing stiffness, load inertia),
its designed controller, prints:

- the margins of N variants (default 100,000): the sampling, the plant maps (their exact
  builds and verified error) and the vectorized figures, in this process and on two worker
  processes; target < 10 s on this 2-core machine;
- the nonlinear time runs of N_TIME variants (default 1000): the batched integration time per
  variant on one core (``integrate_variants`` on up to 500 variants, best of 3) against one
  single run of the nominal model, then with each variant's parameter row and
  stroke tables (CPU time per variant), each variant's step check at its start and snapshots
  (:func:`servo_toolkit.studies.montecarlo.variant_step.step_check`, CPU time per variant), and the
  end-to-end time with the rows' fit. The single run is ``sim.run`` of the rows' nominal
  model (the same reduced model, command, duration and dt as the variants), RK4, warm: its ``wall_s``, the compiled integration
  alone (compilation, the stability probe and the result's traces excluded, as the batch's
  figure excludes its own setup), best of 4;
- the same N margins and N_TIME time runs in chunks on a dask cluster (ADDRESS, or
  ``DASK_SCHEDULER_ADDRESS``, else a local cluster of two worker processes of one thread),
  and whether every figure of every variant is bit for bit the one of the run in one
  process (the variants are drawn before they are cut into chunks).

Every figure is wall time on this machine as it is: the load average is printed with them.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # run from a checkout

import servo_toolkit as st  # noqa: E402
from servo_toolkit.core.cluster import open_cluster  # noqa: E402
from bench_cluster import _scheduler  # noqa: E402 - the option, the environment, else a local cluster
from servo_toolkit.core.parallel import process_pool  # noqa: E402
from servo_toolkit.loop.robustness import variant_figures  # noqa: E402
from servo_toolkit.loop.sampling import sample_tolerances  # noqa: E402
from servo_toolkit.loop.variant_plants import keyed_plants  # noqa: E402
from servo_toolkit.sim import run  # noqa: E402
from servo_toolkit.sim.batch_run import integrate_variants, worker_threads  # noqa: E402
from servo_toolkit.sim.reference import initial_state  # noqa: E402
from servo_toolkit.studies.tolerances import tolerance_runs  # noqa: E402
from servo_toolkit.studies.montecarlo import step_check  # noqa: E402

SCENE = ROOT / "scenes" / "examples" / "ema_tolerances.toml"
KEYS = ("motor.resistance", "motor.torque_constant", "motor.coulomb_friction", "drivetrain[1].efficiency",
        "drivetrain[3].stiffness", "load.inertia")
REPEATS = 3


def _load() -> str:
    return f"load average {os.getloadavg()[0]:.2f}"


def margins(scene, design, n, executor=None):
    """(figures, plants, wall seconds, CPU seconds of this process) of n variants."""
    start, cpu = time.perf_counter(), time.process_time()
    values = sample_tolerances(scene.tolerances, n)
    p = design.parameters
    plants = keyed_plants(scene, p, values, 0.05)
    f_req = next(r.required for r in design.requirements if r.name == "bandwidth")
    # the study's chunks of 2500 variants stay in cache: chunks of 25,000 take twice the CPU time
    figs = variant_figures(scene, p, design.controller, values, f_req, plants=plants, executor=executor,
                           progress=False)
    return figs, plants, time.perf_counter() - start, time.process_time() - cpu


def main(n: int = 100_000, n_time: int = 1000, scheduler=None) -> None:
    scene = st.load_scene(SCENE)
    tol = scene.tolerances
    scene = replace(scene, tolerances=replace(tol, items=tuple(t for t in tol.items if t.key in KEYS)))
    design = st.design(scene, progress=False)
    print(f"{scene.name}: {len(KEYS)} tolerances; {worker_threads()} cores; {_load()} "
          "(a shared machine: other jobs slow every figure)")
    margins(scene, design, 2000)  # imports and caches outside the timing
    figs, plants, here, here_cpu = margins(scene, design, n)
    print(f"margins of {n} variants in one process: {here:.2f} s wall, {here_cpu:.2f} s CPU (plants {plants.method}, {plants.evaluations} exact "
          f"builds, verified to {plants.error:.2g}); {int(figs['stable'].sum())} stable")
    with process_pool(2) as pool:
        margins(scene, design, 4000, pool)  # the workers import and load
        figs2, _, two, _ = margins(scene, design, n, pool)
    same = all(np.array_equal(figs[k], figs2[k], equal_nan=True) for k in figs)
    print(f"margins of {n} variants on 2 worker processes: {two:.2f} s (target < 10 s: "
          f"{'met' if min(here, two) < 10 else 'NOT met'}); figures identical: {same}; {_load()}")

    values = sample_tolerances(scene.tolerances, n_time)
    start = time.perf_counter()
    runs = tolerance_runs(scene, values, design.controller, progress=False)
    total = time.perf_counter() - start
    rows = runs.rows
    single = min(run(rows.model, rows.reference, runs.duration_s, "rk4", dt=runs.dt_s).wall_s
                 for _ in range(REPEATS + 1))
    X = np.column_stack([values[k] for k in rows.names])[:min(n_time, 500)]
    P, T, tix = rows.rows(X)
    made = []
    for _ in range(REPEATS):  # the variants' parameter rows and stroke tables, CPU time per variant
        cpu = time.process_time()
        rows.rows(X)
        made.append((time.process_time() - cpu) / len(X))
    made = min(made)
    X0 = np.array([initial_state(replace(rows.model, T=T[t]), p) for p, t in zip(P, tix)])
    sub = int(round(rows.model.sample_time / runs.dt_s))
    per = min(integrate_variants(P, T, tix, X0, runs.dt_s, runs.steps_per_variant, sub, threads=1)[3]
              for _ in range(REPEATS)) / len(X)
    snaps = integrate_variants(P, T, tix, X0, runs.dt_s, runs.steps_per_variant, sub)[2]
    checked = []
    for _ in range(REPEATS):  # each variant's step check at its start and snapshots, CPU time per variant
        cpu = time.process_time()
        step_check(rows.model, P, T, tix, X0, snaps, runs.dt_s)
        checked.append((time.process_time() - cpu) / len(X))
    checked = min(checked)
    print(f"time runs: single run {single * 1e3:.2f} ms; batched on one core {per * 1e3:.2f} ms per variant = "
          f"{per / single:.2f} x; with its row and "
          f"tables ({made * 1e3:.2f} ms) {(per + made) / single:.2f} x; its step check {checked * 1e3:.3f} ms; "
          f"{n_time} variants "
          f"end to end {total:.1f} s (rows fitted from {rows.evaluations} exact models, verified to "
          f"{rows.error:.2g}); {_load()}")

    with _scheduler(scheduler) as address, open_cluster(address) as cluster:
        start = time.perf_counter()
        figs3 = margins(scene, design, n, cluster.executor)[0]
        far = time.perf_counter() - start
        runs3 = tolerance_runs(scene, values, design.controller, progress=False, executor=cluster.executor,
                               chunk_size=max(1, n_time // 4))
    same = all(np.array_equal(figs[k], figs3[k], equal_nan=True) for k in figs)
    same_runs = all(np.array_equal(getattr(runs, k), getattr(runs3, k)) for k in
                    ("tracking_error", "peak_current", "saturated", "failed"))
    print(f"on the cluster at {cluster.address} ({cluster.threads} threads): margins of {n} variants {far:.2f} s, "
          f"identical: {same}; {n_time} time runs identical: {same_runs}")
    if not (same and same_runs):
        raise SystemExit(1)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("n", nargs="?", type=int, default=100_000)
    parser.add_argument("n_time", nargs="?", type=int, default=1000)
    parser.add_argument("--scheduler", default=None)
    a = parser.parse_args()
    main(a.n, a.n_time, a.scheduler)
