"""Compile (or load from the on-disk cache) every simulation kernel before timed work.

The first run after an installation or an update of the kernels compiles them (about a
minute and a half on a 2-core machine; :mod:`servo_toolkit.core.jit_cache` says where they are cached);
later runs load them in well under a second. Reports and benchmarks call
:func:`compile_kernels` first, and a command does when a kernel is not cached yet, so that
no section's time limit and no timing is charged with compilation, and so that one warm-up
serves every command a user meets next (with every kernel cached, a command loads only those
it calls, when it calls them): the
single run's RK4 loop, the cam paper's scheme, the right-hand side that the reference
solver, Jacobians and traces call, and the nonlinear Monte Carlo's batch (its SIMD lanes and
per-variant loop). The compiled code depends on the argument types alone, never on the
scene, so short runs of the built-in reference actuator compile every kernel any drivetrain
scene uses.

The batch compiles in a second process while this one compiles the single run's kernels
(numba compiles one function at a time per process): on two cores the whole warm-up takes
about as long as the single run's kernels alone.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time

#: steps of the warm-up runs
WARM_STEPS = 4
#: seconds a cold compilation of every kernel takes on a 2-core machine, for the message
#: (``benchmarks/bench_startup.py``: the empty-cache ``simulate`` less a warm one, about 90 s)
TYPICAL_COMPILE_S = 90
#: the entry points whose cached code means the warm-up has nothing to compile
ENTRY_POINTS = ("integrators._rk4", "integrators._paper", "batch_lanes.run_lanes")


def is_cached() -> bool:
    """True when every kernel's entry point is in the on-disk cache, so
    :func:`compile_kernels` only loads them."""
    from ..core.jit_cache import cache_dir
    root = cache_dir()
    return all(any(root.glob(f"**/{n}-*.nbi")) for n in ENTRY_POINTS)


def _batch_cached() -> bool:
    from ..core.jit_cache import cache_dir
    return any(cache_dir().glob("**/batch_lanes.run_lanes-*.nbi"))


def _warm_batch() -> None:
    """Compile (or load) the nonlinear Monte Carlo's kernels: its lanes, the per-variant loop
    and the step check's Jacobians."""
    from ..loop.default_controller import default_controller
    from ..scene.loader import load_scene
    from .montecarlo import montecarlo
    scene = load_scene()
    dt = 1e-5
    montecarlo(scene, {"load_inertia": (0.5, 1.5)}, samples=2, duration=WARM_STEPS * dt, dt=dt,
               controller=default_controller(scene), progress=False)


def _warm_single() -> None:
    """Compile (or load) the single run's kernels: RK4, the paper's scheme, the right-hand
    side called from Python and the controller sample."""
    from ..loop.default_controller import default_controller
    from ..scene.loader import load_scene
    from ..sim.engine import run
    from ..sim.model import build_model
    from ..sim.reference import Reference
    scene = load_scene()
    model = build_model(scene, default_controller(scene))
    dt = 1e-5
    for method in ("rk4", "paper"):
        run(model, Reference.sine(1e-3, 8.0), duration=WARM_STEPS * dt, method=method, dt=dt)


def _start_batch_process():
    """A child process compiling the batch into the same cache (None where none can start)."""
    if (os.cpu_count() or 1) < 2:
        return None
    try:
        return subprocess.Popen([sys.executable, "-c", "from servo_toolkit.studies.warmup import _warm_batch; "
                                 "_warm_batch()"], stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                stderr=subprocess.DEVNULL, env=dict(os.environ))
    except OSError:
        return None


def compile_kernels() -> dict:
    """Compile or load every kernel a simulation of a drivetrain scene runs (the RK4 loop, the
    cam paper's scheme, the right-hand side called from Python, the controller sample and
    the nonlinear Monte Carlo's batch); a cold batch compiles in a second process meanwhile.

    Returns
    -------
    dict
        ``seconds`` spent, and ``compiled``: whether any kernel had to be compiled (False
        when every one came from the cache).
    """
    cold = not is_cached()
    start = time.perf_counter()
    child = None if _batch_cached() else _start_batch_process()
    try:
        _warm_single()
    except BaseException:  # interrupted or failed: the child's compilation goes too
        if child is not None:
            child.terminate()
            child.wait()
        raise
    if child is not None:
        child.wait()
    _warm_batch()  # loads what the child compiled (or compiles here when it could not)
    return {"seconds": time.perf_counter() - start, "compiled": cold}
