"""Start-up figures of a fresh install against the targets: ``import servo_toolkit`` and
``servo-toolkit --help`` (under 1 s), every command's ``--help`` (under 0.5 s), a warm
``check`` of the reference EMA (under 3 s), and the first ``check``, ``simulate`` and
``report`` of a fresh user against warm ones (at most 1.5x).

Each figure is the wall time of a new process, as a user meets it, with the CPU time it used
beside it (user + system, its child processes included): on a busy machine the wall time grows
with the other jobs, the CPU time much less, so the warm ``check`` is judged on both (its CPU
time is what an idle machine's wall time comes near). A "first" run is a fresh user's: empty
user cache and matplotlib configuration folders (``XDG_CACHE_HOME``, ``MPLCONFIGDIR``: pint's
parsed units and matplotlib's font list are built there on the first run; the physics comes
compiled with the package, there is nothing else to build); "warm" ones run again on the same
folders. Run it on an idle machine: ``python benchmarks/bench_startup.py`` (2 to 4 minutes on 2
cores); ``--warm`` measures the figures that need no fresh user (imports, every ``--help``, the
warm ``check``, with the user's own folders) in under a minute. The machine's load (the 1-minute load average of
``os.getloadavg``, sampled every 5 s during the run, and its core count) is printed with the
figures: a figure measured while other jobs run is slower than on an idle machine.
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
sys.path.insert(0, str(ROOT))
from servo_toolkit.cli import COMMANDS  # noqa: E402 - the command table alone, no numerical library

SCENE = str(ROOT / "scenes" / "ema_reference.toml")
TARGET_HELP_S = 1.0
TARGET_COMMAND_HELP_S = 0.5
TARGET_WARM_CHECK_S = 3.0
TARGET_FIRST_OVER_WARM = 1.5


def _children_cpu() -> float:
    """CPU seconds (user + system) of the finished child processes so far (0 where the
    platform does not say)."""
    try:
        import resource
    except ImportError:
        return 0.0
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def timed(args, cache, repeats: int = 1) -> tuple:
    """(wall s, CPU s) of the fastest of ``repeats`` new processes running ``args``; ``cache``
    is the user's folder for caches and matplotlib's configuration (None: the user's own)."""
    user = {} if cache is None else {"XDG_CACHE_HOME": str(cache / "cache"), "MPLCONFIGDIR": str(cache / "mpl")}
    env = {**os.environ, "MPLBACKEND": "Agg", **user}
    best = (float("inf"), float("nan"))
    for _ in range(repeats):
        cpu0, start = _children_cpu(), time.perf_counter()
        proc = subprocess.run([sys.executable, *args], env=env, capture_output=True, text=True, cwd=ROOT)
        wall, cpu = time.perf_counter() - start, _children_cpu() - cpu0
        if proc.returncode != 0:
            raise SystemExit(f"{' '.join(args)} failed:\n{proc.stderr[-2000:]}")
        best = min(best, (wall, cpu))
    return best


def sample_load(samples: list, stop: threading.Event, every_s: float = 5.0) -> None:
    """Append the 1-minute load average to ``samples`` every ``every_s`` until ``stop``."""
    while not stop.is_set():
        samples.append(os.getloadavg()[0])
        stop.wait(every_s)


def _row(name, figure, target="", limit=None, on_cpu=False):
    """A table row: (name, wall s, CPU s, target text, PASS/FAIL or None), judged on the wall
    time or, ``on_cpu``, on the CPU time (what an idle machine's wall time comes near)."""
    wall, cpu = figure
    return name, wall, cpu, target, None if limit is None else (cpu if on_cpu else wall) < limit


def start_up_rows(cli, cache) -> list:
    """The figures that need no fresh user: imports, every command's ``--help`` and a warm
    ``check`` of the reference EMA (a first ``check`` before it fills the user's folders)."""
    rows = [_row("import servo_toolkit", timed(["-c", "import servo_toolkit"], cache, repeats=5),
                 f"< {TARGET_HELP_S:g} s", TARGET_HELP_S),
            _row("servo-toolkit --help", timed([*cli, "--help"], cache, repeats=5), f"< {TARGET_HELP_S:g} s",
                 TARGET_HELP_S)]
    for name in COMMANDS:
        rows.append(_row(f"{name} --help", timed([*cli, name, "--help"], cache, repeats=3),
                         f"< {TARGET_COMMAND_HELP_S:g} s", TARGET_COMMAND_HELP_S))
    timed([*cli, "check", SCENE], cache)  # a first run fills the user's folders
    check = timed([*cli, "check", SCENE], cache, repeats=3)
    rows.append(_row("check, warm (reference EMA)", check, f"< {TARGET_WARM_CHECK_S:g} s", TARGET_WARM_CHECK_S))
    rows.append(_row("  the same, judged on CPU", check, f"< {TARGET_WARM_CHECK_S:g} s CPU", TARGET_WARM_CHECK_S,
                     on_cpu=True))
    return rows


def print_rows(rows, loads) -> None:
    """The table, then the machine's load during the run."""
    print(f"{'figure':<30}{'wall':>9}{'CPU':>9}  {'target':<10}")
    for name, wall, cpu, target, ok in rows:
        verdict = "" if ok is None else ("PASS" if ok else "FAIL")
        if name.endswith("first / warm"):
            print(f"{name:<30}{wall:>8.2f}x{'':>9}  {target:<10}{verdict}")
        else:
            print(f"{name:<30}{wall:>8.2f}s{cpu:>8.2f}s  {target:<10}{verdict}")
    print(f"machine: {os.cpu_count()} cores, 1-minute load average during the run {min(loads):.2f} to "
          f"{max(loads):.2f}, mean {sum(loads) / len(loads):.2f} (this benchmark's own process adds about 1)")


def main():
    cli = ["-m", "servo_toolkit"]
    warm_only = "--warm" in sys.argv[1:]
    loads, stop = [], threading.Event()
    sampler = threading.Thread(target=sample_load, args=(loads, stop), daemon=True)
    sampler.start()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        if warm_only:
            rows = start_up_rows(cli, None)
        else:
            rows = []
            runs = (("check", [*cli, "check", SCENE], 3), ("simulate", [*cli, "simulate", SCENE, "--json"], 3),
                    ("report", [*cli, "report", "-o", str(tmp / "r{}")], 1))
            for k, (name, args, repeats) in enumerate(runs):
                user = tmp / f"user{k}"
                first = timed([a.format(1) for a in args], user)
                warm = timed([a.format(2) for a in args], user, repeats=repeats)
                ratio = first[0] / warm[0]
                rows += [_row(f"{name}, first run", first), _row(f"{name}, warm", warm),
                         (f"{name}: first / warm", ratio, float("nan"), f"<= {TARGET_FIRST_OVER_WARM:g}x",
                          ratio <= TARGET_FIRST_OVER_WARM)]
            rows += start_up_rows(cli, tmp / "user0")
    stop.set()
    sampler.join()
    print_rows(rows, loads)


if __name__ == "__main__":
    main()
