"""``servo-toolkit export``: the designed controller as controller.json and C99 sources."""

from __future__ import annotations

import sys

from ..errors import SceneError
from .cmd_design import add_design_options, design_from_args
from .common import add_json, add_scene, emit, load_scene

#: library keys that are command-line options here
OPTION_KEYS = {"current_sample_time": "--current-sample-time", "fixed_point": "--fixed-point",
               "sample_time": "--sample-time"}


def register(sub) -> None:
    """Register the command."""
    p = sub.add_parser("export", help="controller.json and C99 sources of the designed controller")
    add_scene(p)
    p.add_argument("-o", "--output", required=True, metavar="DIR",
                   help="output folder (created; controller.json, servo_controller.h/.c replaced atomically)")
    p.add_argument("--fixed-point", choices=("q15", "q31"), default=None,
                   help="quantize the motion controller and recompute the margins with it")
    p.add_argument("--sample-time", metavar="S", default=None,
                   help="motion-loop sample time, e.g. 0.2ms: replaces the scene's sensors.sample_time and "
                        "designs the loop at it (a scene with a continuous controller needs one)")
    p.add_argument("--current-sample-time", metavar="S", default=None,
                   help="current-loop sample time, e.g. 25us (default: an integer fraction of the motion "
                        "sample time with w_i Ts <= 0.2)")
    p.add_argument("--feedforward", choices=("off", "gains", "model"), default=None,
                   help="export the feedforward: its velocity and acceleration gains (the model-based one as its "
                        "designed gains at q0) and the ratio table of its speed reference (default: the design "
                        "file's, else off)")
    p.add_argument("--schedule", action="store_true",
                   help="export the gain schedule along the stroke (the table the drive interpolates)")
    p.add_argument("--shaper", choices=("off", "zv", "zvd"), default=None,
                   help="export a command shaper on the drivetrain mode (impulses at whole motion samples)")
    add_design_options(p)
    add_json(p)
    p.set_defaults(run=run)


def replace_controller(result, controller):
    """The design result with its controller replaced (the command options ride on it)."""
    from dataclasses import replace
    return replace(result, controller=controller)


def run(args) -> int:
    """Run the command: 0 exported, 1 the designed closed loop is unstable, the design misses a
    requirement of the scene or (``--fixed-point``) the quantized controller's loop misses one
    (each named); the files are written either way."""
    from ..core.units import parse_quantity
    from ..export import export
    from ..export.writer import check_directory
    from ..loop.requirements import parse_overrides

    parse_overrides(args.require)
    ts_i = None if args.current_sample_time is None else parse_quantity(args.current_sample_time, "s",
                                                                        "--current-sample-time")
    ts = None if args.sample_time is None else parse_quantity(args.sample_time, "s", "--sample-time")
    if ts is not None and not 1e-7 <= ts <= 1.0:
        raise SceneError("--sample-time", f"must lie in [0.1 us, 1 s] (got {args.sample_time!r})")
    if ts_i is not None and not ts_i >= 1e-7:  # the upper limit (the motion sample time) is the export's
        raise SceneError("--current-sample-time", f"must be at least 0.1 us (got {args.current_sample_time!r})")
    scene = load_scene(args.scene)
    inputs = [args.scene, args.design, *scene.input_files]
    check_directory(args.output, inputs=inputs)  # before any work
    if ts is not None:
        from dataclasses import replace
        scene = replace(scene, sensors=replace(scene.sensors, sample_time=ts))
    try:
        result = design_from_args(scene, args)
        if args.feedforward is not None or args.schedule or args.shaper is not None:
            from ..loop.feedforward import with_command
            result = replace_controller(result, with_command(result.controller, scene, feedforward=args.feedforward,
                                                             schedule=True if args.schedule else None,
                                                             shaper=args.shaper))
        result = export(result, scene, args.output, fixed_point=args.fixed_point, current_sample_time=ts_i,
                        inputs=inputs)
    except SceneError as exc:
        if exc.key in OPTION_KEYS:  # an option, not the scene: name the option
            raise SceneError(OPTION_KEYS[exc.key], exc.rule) from None
        raise (exc if exc.source else exc.with_source(str(args.scene))) from None
    emit(args, result, result.table())
    for reason in result.failures:
        print(f"servo-toolkit: export: {reason}", file=sys.stderr)
    return 0 if result.passed else 1
