"""``servo-toolkit simulate``: a time simulation of a scene (closed loop or open loop)."""

from __future__ import annotations

import sys

from ..scene import load_scene
from . import mechanism_dispatch as dispatch
from .common import add_json, add_scene, bounded, emit, prepare_kernels


def register(sub) -> None:
    """Register the command."""
    p = sub.add_parser("simulate", help="time simulation (compiled RK4, paper scheme or stiff reference)")
    add_scene(p)
    p.add_argument("--study", metavar="NAME", help="a study of the scene (default: 8 Hz, 2 deg sine, 1 s)")
    p.add_argument("--method", choices=("rk4", "paper", "reference", "auto"), default=None)
    p.add_argument("--dt", type=bounded(float, 1e-9, 1.0, what="a step in seconds"), metavar="S",
                   help="fixed step (s), 1e-9 to 1")
    p.add_argument("-o", "--output", metavar="FILE", help="write the traces (.csv or .npz)")
    p.add_argument("--full", action="store_true",
                   help="run the full model (default: a closed-loop sine runs the reduced model and says what it "
                        "left out)")
    add_json(p)
    p.set_defaults(run=run)


def _mechanism_dispatch(scene, args):
    """The mechanism studies' own runner when it handles this study, else None."""
    if not args.study:
        return None
    dispatch.require(scene, args.study)
    study = scene.studies.get(args.study, args.study)
    if not dispatch.handled(scene, study):
        return None
    return dispatch.run_mechanism(scene, study, method=args.method, dt=args.dt)


def run(args) -> int:
    """Run the command."""
    from ..sim.result import check_trace_path
    from ..studies.time_run import simulate_study

    scene = load_scene(args.scene)
    check_trace_path(args.output)  # a bad -o name fails before the run, exit 2
    result = _mechanism_dispatch(scene, args)
    if result is None:
        prepare_kernels(scene, paper=args.method == "paper")
        result = simulate_study(scene, args.study, method=args.method, dt=args.dt, full=args.full)
        text = f"Simulation of {scene.name}\n" + result.table()
    else:
        text = result.table() if hasattr(result, "table") else str(result.to_dict())
    if args.output:
        if not hasattr(result, "save"):
            print("servo-toolkit: this study writes no traces", file=sys.stderr)
            return 2
        path = result.save(args.output)
        print(f"traces written to {path}", file=sys.stderr)
    if "UNSTABLE" in str(getattr(result, "controller", "")):
        print("servo-toolkit: warning: no stable controller was found for this scene; the run shows the "
              "design's unstable closed loop (see servo-toolkit design)", file=sys.stderr)
    emit(args, result, text)
    return 0
