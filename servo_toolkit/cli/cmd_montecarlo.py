"""``servo-toolkit montecarlo``: nonlinear closed-loop variants of a scene, batched.

The variations are those of ``check --vary`` and the scene's ``[robustness]``; the command
is ``simulate``'s (8 Hz, 2 deg sine for 1 s) on the same reduced (or ``--full``) model.
"""

from __future__ import annotations

import math
import sys

from ..errors import SceneError
from .common import (add_force, add_friction, add_json, add_scene, add_scheduler, add_sine_options, amplitudes_si, emit,
                     load_scene, scheduler_of, study_executor)

#: most variants of one run (as ``check --samples`` and a scene's ``[robustness] samples``)
MAX_SAMPLES = 1_000_000


def register(sub) -> None:
    """Register the command."""
    p = sub.add_parser("montecarlo", help="nonlinear closed-loop variants (load inertia, stiffness), batched")
    add_scene(p)
    p.add_argument("--vary", action="append", default=[], metavar="NAME=LO:HI",
                   help="vary load_inertia (kg*m^2, kg for a travel output: 0 or 1e-12..1e6) or stiffness (a factor, 1e-3..1e3), e.g. load_inertia=0:4 "
                        "(repeatable; default: the scene's [robustness] ranges, else the load inertia from 0 to four "
                        "times the scene's and stiffness=0.7:1.3; a positive range over a decade is sampled logarithmically, and the "
                        "corners of the ranges are always among the variants)")
    p.add_argument("--samples", type=int, default=None,
                   help="variants (default: the scene's [robustness] samples, else 1000)")
    p.add_argument("--seed", type=int, default=None, help="seed of the Monte Carlo draws")
    p.add_argument("--duration", type=float, default=None, metavar="S", help="seconds (default: simulate's, 1 s)")
    add_sine_options(p)
    p.add_argument("--full", action="store_true", help="run the full model (default: simulate's reduced model)")
    p.add_argument("--feedforward", choices=("off", "gains", "model"), default="off",
                   help="feedforward from the command, as simulate's (default off); a variant's feedforward keeps "
                        "the nominal scene's load inertia, as a drive's would")
    add_friction(p)
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="worker processes for chunks of variants (default: this process, every core)")
    add_scheduler(p, what="chunks of variants")
    add_force(p)
    add_json(p)
    p.set_defaults(run=run)


def _check_args(args):
    from ..loop.vary import parse_vary
    varies = dict(parse_vary(text) for text in args.vary)
    if args.samples is not None and args.samples < 1:
        raise SceneError("--samples", f"must be at least 1 (got {args.samples})")
    if args.samples is not None and args.samples > MAX_SAMPLES:
        raise SceneError("--samples", f"must be at most {MAX_SAMPLES} (got {args.samples})")
    if args.seed is not None and args.seed < 0:
        raise SceneError("--seed", f"must not be negative (got {args.seed})")
    if args.duration is not None and not args.duration > 0:
        raise SceneError("--duration", f"must be positive (got {args.duration:g} s)")
    if args.duration is not None and not math.isfinite(args.duration):
        raise SceneError("--duration", f"must be finite (got {args.duration:g} s)")
    if args.workers is not None and args.workers > 256:
        raise SceneError("--workers", f"must be at most 256 (got {args.workers})")
    if args.workers is not None and args.workers < 1:
        raise SceneError("--workers", f"must be at least 1 (got {args.workers})")
    return varies, scheduler_of(args)


def _check_budget(scene, args) -> None:
    """Refuse a run estimated beyond the work budget unless ``--force`` (before any work)."""
    from .budget import LONG_RUN_S, batch_seconds, check_time
    from ..studies.time.reference import run_spec
    samples = args.samples or (scene.robustness.samples if scene.robustness is not None else 1000)
    duration = args.duration if args.duration is not None else run_spec(scene, None)[1]
    seconds, what = batch_seconds(scene, samples, duration)
    if args.duration is not None and args.duration > LONG_RUN_S:
        knob, got = "--duration", f"{args.duration:g} s"
    else:
        knob, got = ("--samples" if args.samples is not None else "robustness.samples"), samples
    check_time(seconds, knob, what, got, args.force)


def run(args) -> int:
    """Run the command."""
    from ..studies.montecarlo import CHUNK_SIZE, montecarlo
    varies, scheduler = _check_args(args)  # every option is checked before the scene is read
    scene = load_scene(args.scene)
    reference = None
    if args.amplitude is not None or args.frequency is not None:
        from ..studies.time.reference import run_spec
        reference = run_spec(scene, None, amplitude=amplitudes_si(scene, args.amplitude),
                             frequency=args.frequency, duration=args.duration)[0]
    _check_budget(scene, args)
    variants = None
    if varies:
        base = dict(scene.robustness.ranges) if scene.robustness is not None else {}
        variants = {**base, **varies}
    progress = not args.json and sys.stderr.isatty()
    kwargs = dict(samples=args.samples, seed=args.seed, duration=args.duration, full=args.full, progress=progress,
                  reference=reference, feedforward=None if args.feedforward == "off" else args.feedforward,
                  friction=args.friction)
    n = args.samples or (scene.robustness.samples if scene.robustness is not None else 1000)
    with study_executor(scheduler, args.workers) as (executor, slots):  # a cluster that is not there: before any work
        chunk_size = CHUNK_SIZE if slots is None else min(CHUNK_SIZE, -(-n // slots))
        result = montecarlo(scene, variants, executor=executor, chunk_size=chunk_size, **kwargs)
    emit(args, result, f"Monte Carlo of {scene.name}\n" + result.table())
    return 0
