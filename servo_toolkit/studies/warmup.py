"""Compile (or load from the on-disk cache) the simulation kernels before timed work.

The first run after an installation or an update of the kernels compiles them (about 75 s on
an idle 2-core machine, ``benchmarks/bench_startup.py``; :mod:`servo_toolkit.core.jit_cache`
says where they are cached); later runs load them in well under a second. Reports and benchmarks call
:func:`compile_kernels` first, so that no section's time limit and no timing is charged
with compilation. The compiled code depends on the argument types alone, never on the
scene, so one short run of the built-in reference actuator compiles every kernel a
drivetrain scene's simulations use.
"""

from __future__ import annotations

import time

#: steps of the warm-up run
WARM_STEPS = 4
#: seconds a cold compilation of the RK4 loop takes on an idle 2-core machine, for the progress
#: message (``benchmarks/bench_startup.py``: the empty-cache ``simulate`` minus a warm one,
#: scaled to the share of the cores the run had)
TYPICAL_COMPILE_S = 75


def is_cached(paper: bool = False, batch: bool = False) -> bool:
    """True when the compiled RK4 loop (the paper scheme's too with ``paper``, the batched
    variants' with ``batch``) is in the on-disk cache, so :func:`compile_kernels` only
    loads it."""
    from ..core.jit_cache import cache_dir
    root = cache_dir()
    names = ["integrators._rk4"] + (["integrators._paper"] if paper else []) + (["batch_lanes.run_lanes"] if batch else [])
    return all(any(root.glob(f"**/{n}-*.nbi")) for n in names)


def compile_kernels(paper: bool = False, batch: bool = False) -> dict:
    """Compile or load every kernel a simulation of a drivetrain scene runs: the RK4 loop,
    the right-hand side called from Python (traces, Jacobians, the stiff reference solver),
    the table interpolation, with ``paper`` the cam paper's scheme and with ``batch`` the
    batched variants of the nonlinear Monte Carlo.

    Parameters
    ----------
    paper : bool
        Also the paper's frozen-configuration scheme (scenes ending in a cam).
    batch : bool
        Also :func:`servo_toolkit.studies.montecarlo.montecarlo`'s kernels (its lanes, the
        per-variant loop and the step check).

    Returns
    -------
    dict
        ``seconds`` spent, and ``compiled``: whether any kernel had to be compiled (False
        when every one came from the cache).
    """
    from ..scene.loader import load_scene
    from ..loop.default_controller import default_controller
    from ..sim.engine import run
    from ..sim.model import build_model
    from ..sim.reference import Reference
    cold = not is_cached(paper, batch)
    start = time.perf_counter()
    scene = load_scene()
    controller = default_controller(scene)
    model = build_model(scene, controller)
    dt = 1e-5
    for method in ("rk4", "paper") if paper else ("rk4",):
        run(model, Reference.sine(1e-3, 8.0), duration=WARM_STEPS * dt, method=method, dt=dt)
    if batch:
        from .montecarlo import montecarlo
        montecarlo(scene, {"load_inertia": (0.5, 1.5)}, samples=2, duration=WARM_STEPS * dt, dt=dt,
                   controller=controller, progress=False)
    return {"seconds": time.perf_counter() - start, "compiled": cold}
