"""Start-up figures of a fresh install against the targets: ``import servo_toolkit`` and
``servo-toolkit --help`` (under 1 s), the first ``simulate`` on an empty compiled-code cache
against a warm one (at most 4x), and the first and a warm ``report``.

Each figure is the wall time of a new process, as a user meets it; "empty cache" runs use a
fresh ``NUMBA_CACHE_DIR``, "warm" ones run again on the same folder. Run it on an idle
machine: ``python benchmarks/bench_startup.py`` (4 to 8 minutes on 2 cores). The machine's load
(the 1-minute load average of ``os.getloadavg``, sampled every 5 s during the run, and its core
count) is printed with the figures: a figure measured while other jobs run is slower than on an
idle machine.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCENE = str(ROOT / "scenes" / "ema_reference.toml")
TARGET_HELP_S = 1.0
TARGET_COLD_OVER_WARM = 4.0


def timed(args, cache, repeats: int = 1) -> float:
    """Best wall time (s) of ``repeats`` new processes running ``args``."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache), "MPLBACKEND": "Agg"}
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        proc = subprocess.run([sys.executable, *args], env=env, capture_output=True, text=True, cwd=ROOT)
        best = min(best, time.perf_counter() - start)
        if proc.returncode != 0:
            raise SystemExit(f"{' '.join(args)} failed:\n{proc.stderr[-2000:]}")
    return best


def sample_load(samples: list, stop: threading.Event, every_s: float = 5.0) -> None:
    """Append the 1-minute load average to ``samples`` every ``every_s`` until ``stop``."""
    while not stop.is_set():
        samples.append(os.getloadavg()[0])
        stop.wait(every_s)


def main():
    cli = ["-m", "servo_toolkit"]
    loads, stop = [], threading.Event()
    sampler = threading.Thread(target=sample_load, args=(loads, stop), daemon=True)
    sampler.start()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        imp = timed(["-c", "import servo_toolkit"], tmp / "c0", repeats=5)
        hlp = timed([*cli, "--help"], tmp / "c0", repeats=5)
        sim_cold = timed([*cli, "simulate", SCENE, "--json"], tmp / "c1")
        sim_warm = timed([*cli, "simulate", SCENE, "--json"], tmp / "c1", repeats=3)
        rep_cold = timed([*cli, "report", "-o", str(tmp / "r1")], tmp / "c2")
        rep_warm = timed([*cli, "report", "-o", str(tmp / "r2")], tmp / "c2")
    stop.set()
    sampler.join()
    ratio = sim_cold / sim_warm
    rows = [("import servo_toolkit", imp, f"< {TARGET_HELP_S:g} s", imp < TARGET_HELP_S),
            ("servo-toolkit --help", hlp, f"< {TARGET_HELP_S:g} s", hlp < TARGET_HELP_S),
            ("simulate, empty cache", sim_cold, "", None),
            ("simulate, warm", sim_warm, "", None),
            ("simulate: empty / warm", ratio, f"<= {TARGET_COLD_OVER_WARM:g}x", ratio <= TARGET_COLD_OVER_WARM),
            ("report, empty cache", rep_cold, "", None),
            ("report, warm", rep_warm, "", None)]
    print(f"{'figure':<26}{'value':>10}  {'target':<10}")
    for name, value, target, ok in rows:
        unit = "x" if name.endswith("warm") and ":" in name else "s"
        verdict = "" if ok is None else ("PASS" if ok else "FAIL")
        print(f"{name:<26}{value:>9.2f}{unit}  {target:<10}{verdict}")
    print(f"machine: {os.cpu_count()} cores, 1-minute load average during the run {min(loads):.2f} to "
          f"{max(loads):.2f}, mean {sum(loads) / len(loads):.2f} (this benchmark's own process adds about 1)")


if __name__ == "__main__":
    main()
