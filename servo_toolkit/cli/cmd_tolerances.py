"""``servo-toolkit tolerances``: the yield of a design over the scene's ``[tolerances]`` and
which tolerance drives each figure.

Exit 0 when the required yield (``min_yield``) is met by the lower end of its confidence
interval (or the scene requires none), 1 when it is not, 2 on bad input or a variant whose
time run could not be carried out.
"""

from __future__ import annotations

import sys

from ..errors import SceneError
from .cmd_design import add_design_options, design_from_args
from .common import (add_force, add_json, add_scene, add_scheduler, bounded, emit, load_scene,
                     scheduler_of, study_executor)

#: the sampling methods of ``--method``: those of a scene's ``[tolerances] method``
#: (:data:`servo_toolkit.scene.tolerances.METHODS`, whose module loads the scene reader and
#: its unit parser; the parser is built without them)
METHODS = ("lhs", "sobol", "random")


def register(sub) -> None:
    """Register the command."""
    p = sub.add_parser("tolerances", help="yield over the scene's [tolerances] and which tolerance drives it")
    add_scene(p)
    add_design_options(p)
    p.add_argument("--samples", type=bounded(int, 2, 1_000_000, what="a number of variants"), default=None,
                   help="variants (default: the scene's [tolerances] samples, 1024)")
    p.add_argument("--method", choices=METHODS, default=None,
                   help="sampling: Latin hypercube, scrambled Sobol or independent draws (default: the "
                        "scene's [tolerances] method, lhs; random draws, as [robustness]'s Monte Carlo, "
                        "when the scene gives only [robustness])")
    p.add_argument("--seed", type=bounded(int, 0, 2**63 - 1, what="a seed"), default=None,
                   help="seed of the draws (default: the scene's, 0)")
    mode = p.add_mutually_exclusive_group()
    mode.add_argument("--nonlinear", dest="nonlinear", action="store_const", const=True, default=None,
                      help="run every variant in time on the nonlinear model too (default: when the scene bounds "
                           "the tracking error or the peak current)")
    mode.add_argument("--linear-only", dest="nonlinear", action="store_const", const=False,
                      help="margins only, no time runs (the time requirements are then not judged)")
    p.add_argument("--sobol-runs", type=bounded(int, 0, 1_000_000, what="a number of runs"), default=0, metavar="N",
                   help="base sample of Sobol indices of a time figure regression does not explain (N (d + 2) "
                        "further time runs; default 0: ranked by regression, stated)")
    p.add_argument("--duration", type=bounded(float, 0.0, 3600.0, low_open=True, what="seconds"), default=None,
                   metavar="S", help="seconds of each time run (default: simulate's, 1 s)")
    p.add_argument("--workers", type=bounded(int, 1, 256, what="a number of processes"), default=None, metavar="N",
                   help="worker processes for chunks of variants (default: this process)")
    add_scheduler(p, what="chunks of variants (margins and time runs)")
    add_force(p)
    add_json(p)
    p.set_defaults(run=run)


def run(args) -> int:
    """Run the command."""
    from ..loop.requirements import parse_overrides
    from ..studies.tolerances import tolerance_study
    parse_overrides(args.require)
    scheduler = scheduler_of(args)  # every option is checked before the scene is read
    scene = load_scene(args.scene)
    if scene.tolerances is None:
        raise SceneError("tolerances", "the scene sets no [tolerances] (nor [robustness] ranges) to vary")
    from ..scene.tolerances import check_ends
    check_ends(scene.tolerances)
    progress = not args.json and sys.stderr.isatty()
    timed = args.nonlinear or (args.nonlinear is None and (scene.tolerances.max_tracking_error is not None
                                                             or scene.tolerances.max_peak_current is not None))
    from .budget import check_time, tolerance_seconds
    samples = args.samples or scene.tolerances.samples
    seconds, what = tolerance_seconds(scene, samples, timed, args.duration or 1.0, args.sobol_runs or 0)
    knob = ("--duration" if args.duration and args.duration > 1.0 else
            "--samples" if args.samples else "tolerances.samples")
    check_time(seconds, knob, what, f"{args.duration:g} s" if knob == "--duration" else samples, args.force)
    with study_executor(scheduler, args.workers) as (executor, _):
        result = design_from_args(scene, args, executor=executor)  # reads and checks a --design file first
        if args.nonlinear is False and (scene.tolerances.max_tracking_error is not None
                                        or scene.tolerances.max_peak_current is not None):
            print("servo-toolkit: note: --linear-only: the tracking-error and peak-current requirements are not "
                  "judged", file=sys.stderr)
        study = tolerance_study(scene, result, samples=args.samples, method=args.method, seed=args.seed,
                                nonlinear=args.nonlinear, executor=executor, progress=progress,
                                sobol_runs=args.sobol_runs, duration=args.duration)
    emit(args, study, f"Tolerances of {scene.name}\n" + study.table())
    return 0 if study.passed else 1
