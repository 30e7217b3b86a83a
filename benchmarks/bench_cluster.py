"""The linear margin study of 100,000 variants on a dask cluster equals the run in one process.

Run: python3 benchmarks/bench_cluster.py [N] [--scheduler ADDRESS] [--cli]

N Monte Carlo variants (default 100,000) of load inertia (0..4 kg*m^2) and stiffness
(+-30 %) of the reference EMA's designed loop (``servo_toolkit.loop.robustness``): once in
this process, once in chunks on a dask cluster, through the executor the command line's
``--scheduler`` opens (:func:`servo_toolkit.core.cluster.open_cluster`). The cluster is the
one at ADDRESS (or ``DASK_SCHEDULER_ADDRESS``), else a local one of two worker processes of
one thread. The variants are drawn from the seed before they are cut into chunks, so where a
chunk runs does not change them. Prints both wall times, the chunks and the workers, and
whether every figure of every variant (gain, phase margin, sensitivity peak, bandwidth,
phase lag, rightmost pole, stability) and every worst case is bit for bit the same.

With ``--cli`` it also runs ``servo-toolkit check scenes/ema_robust.toml --linear-only
--samples N --json`` (a robust design, checked over N variants) with and without
``--scheduler`` and compares the two JSON outputs.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # run from a checkout

import servo_toolkit as st  # noqa: E402
from servo_toolkit.core.cluster import SchedulerAddress, open_cluster, scheduler_address  # noqa: E402
from servo_toolkit.loop.robustness import robustness  # noqa: E402

CHUNK = 2500  # the study's default chunk: the command line sends the same chunks


@contextlib.contextmanager
def _scheduler(option):
    """The scheduler to use: the option, the environment, else a local cluster of 2 processes."""
    given = scheduler_address(option)
    if given is not None:
        yield given
        return
    import distributed
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        yield SchedulerAddress(cluster.scheduler_address, "local cluster")


def _same(a, b) -> bool:
    figures = all(np.array_equal(a.figures[k], b.figures[k], equal_nan=True) for k in a.figures)
    values = all(np.array_equal(a.values[k], b.values[k]) for k in a.values)
    return figures and values and [c.to_dict() for c in a.requirements] == [c.to_dict() for c in b.requirements] \
        and a.worst == b.worst


def _cli(args, scheduler=None) -> tuple[float, dict]:
    env = {k: v for k, v in os.environ.items() if k != "DASK_SCHEDULER_ADDRESS"}
    env["PYTHONPATH"] = str(ROOT)
    cmd = [sys.executable, "-m", "servo_toolkit", *args, "--json"] + (["--scheduler", scheduler] if scheduler else [])
    t0 = time.perf_counter()
    done = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True)
    if done.returncode not in (0, 1):
        raise SystemExit(done.stderr)
    return time.perf_counter() - t0, json.loads(done.stdout)


def main(n: int, option: str | None, cli: bool) -> None:
    scene = st.load_scene()
    result = st.design(scene)
    robustness(scene, result, samples=10, seed=2, progress=False)  # warm caches
    t0 = time.perf_counter()
    here = robustness(scene, result, samples=n, seed=1, progress=False, chunk_size=CHUNK)
    t_here = time.perf_counter() - t0
    with _scheduler(option) as scheduler, open_cluster(scheduler) as cluster:
        t0 = time.perf_counter()
        there = robustness(scene, result, samples=n, seed=1, progress=False, chunk_size=CHUNK,
                           executor=cluster.executor)
        t_there = time.perf_counter() - t0
        print(f"variants: {n} ({here.unstable_count} unstable), {-(-n // CHUNK)} chunks of {CHUNK}")
        print(f"one process:        {t_here:7.2f} s")
        print(f"dask cluster:       {t_there:7.2f} s   ({cluster.threads} worker threads at {cluster.address}, "
              f"{scheduler.key})")
        print(f"identical figures and worst cases: {'yes' if _same(here, there) else 'NO'}")
        if cli:
            args = ["check", str(ROOT / "scenes" / "ema_robust.toml"), "--linear-only", "--samples", str(n)]
            t_a, a = _cli(args)
            t_b, b = _cli(args, cluster.address)
            print(f"servo-toolkit check --linear-only --samples {n}: {t_a:.1f} s here, {t_b:.1f} s with "
                  f"--scheduler; identical JSON: {'yes' if a == b else 'NO'}")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("n", nargs="?", type=int, default=100_000, help="variants (default 100000)")
    parser.add_argument("--scheduler", metavar="ADDRESS", help="an existing dask scheduler (default: a local cluster)")
    parser.add_argument("--cli", action="store_true", help="also compare servo-toolkit check with and without it")
    ns = parser.parse_args()
    main(ns.n, ns.scheduler, ns.cli)
