"""Coverage of the identification's 95 % intervals from voltage-driven time traces.

``ema`` (default): the rig is the reference EMA with load inertia x1.3, housing stiffness x0.8 and resistance
x1.1 (the rig of ``tests/test_identify.py``), driven by a 4 V multisine for 0.4 s at 5 kHz;
its current carries 0.05 A of white noise and its angles the rounding of the encoders (motor
4096 counts per rev, output 16 bits). Each repeat draws a new noise and new multisine phases
(seed), fits the three parameters from the truth (``starts=0``: the bias and the spread of
the estimate, not the global search, are the question) and records each parameter's
z-score, ``(ln estimate - ln truth) / SE`` with SE the interval's log half-width over its
Student t quantile.

``emps``: the rig of ``tests/test_identify_coverage.py`` (the EMPS cart, mass x1.2 and
viscous friction x1.1, 0.1 s of a 1 V-per-tone multisine), the same two parameters fitted.

Printed per parameter: the mean z with its standard error (a bias shows as a mean beyond about
three of them), the SD of z (1 when the intervals are as wide as the estimates scatter), the
misses of the 95 % interval with the binomial 95 % range of misses for the repeats.

``python benchmarks/bench_identify_coverage.py [REPEATS] [PROCESSES] [ema|emps]`` (default 200,
1 and ema; two processes only on an idle machine). Small matrices run several times faster with
``OPENBLAS_NUM_THREADS=1`` on a busy machine. The test suite asserts no wall time.
"""

from __future__ import annotations

import math
import sys
import time
from multiprocessing import Pool
from pathlib import Path

import numpy as np
from scipy import stats

ROOT = Path(__file__).resolve().parents[1]
KEYS = ["load.inertia", "drivetrain[3].stiffness", "motor.resistance"]
FACTORS = np.array([1.3, 0.8, 1.1])
EMPS_KEYS = ["load.inertia", "load.damping"]
EMPS_FACTORS = np.array([1.2, 1.1])


def _truth(rig: str):
    import servo_toolkit as st
    from servo_toolkit.identify.params import SceneTemplate
    if rig == "emps":
        keys, factors, name = EMPS_KEYS, EMPS_FACTORS, "emps.toml"
    else:
        keys, factors, name = KEYS, FACTORS, "ema_reference.toml"
    template = SceneTemplate(st.load_scene(ROOT / "scenes" / name), keys)
    values = np.array(template.initial) * factors
    return template.scene(values), values, keys


def one(job) -> np.ndarray:
    """z-scores of the parameters for one noise draw ``(rig, seed)``."""
    import servo_toolkit as st
    rig, seed = job
    scene, values, keys = _truth(rig)
    sys.path.insert(0, str(ROOT))  # the rigs of the tests
    if rig == "emps":
        from tests.test_identify_coverage import emps_traces
        data = emps_traces(scene, seed)
    else:
        from tests.test_identify import rig_traces
        data = rig_traces(scene, seed)
    r = st.fit(scene, data, None, keys, starts=0)
    lo, hi = np.log(r.ci95[:, 0]), np.log(r.ci95[:, 1])
    se = 0.5 * (hi - lo) / stats.t.ppf(0.975, r.dof)
    return (np.log(r.values) - np.log(values)) / se


def main() -> None:
    repeats = int(sys.argv[1]) if len(sys.argv) > 1 else 200
    processes = int(sys.argv[2]) if len(sys.argv) > 2 else 1
    rig = sys.argv[3] if len(sys.argv) > 3 else "ema"
    keys = EMPS_KEYS if rig == "emps" else KEYS
    start = time.perf_counter()
    seeds = [(rig, s) for s in range(1000, 1000 + repeats)]
    if processes > 1:
        with Pool(processes) as pool:
            z = np.array(pool.map(one, seeds))
    else:
        z = np.array([one(s) for s in seeds])
    wall = time.perf_counter() - start
    lo, hi = stats.binom.ppf([0.025, 0.975], repeats, 0.05)
    per_fit = wall / repeats * processes
    print(f"{rig}: {repeats} fits of time traces, {wall:.0f} s ({per_fit:.2f} s per fit per process)")
    print(f"{'parameter':<26}{'mean z':>8}{'+-SE':>7}{'SD z':>7}{'misses':>8}   "
          f"(95 % range of misses {lo:.0f}-{hi:.0f})")
    for k, key in enumerate(keys):
        col = z[:, k]
        mean, sd = col.mean(), col.std(ddof=1)
        miss = int(np.sum(np.abs(col) > stats.norm.ppf(0.975)))
        print(f"{key:<26}{mean:8.3f}{sd / math.sqrt(repeats):7.3f}{sd:7.3f}{miss:8d}")


if __name__ == "__main__":
    main()
