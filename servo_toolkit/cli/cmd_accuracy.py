"""``servo-toolkit accuracy``: error against run time of the fixed-step methods."""

from __future__ import annotations

from .common import add_force, add_json, add_scene, add_sine_options, amplitudes_si, emit, load_scene

#: accuracy runs are short: the reference restarts at every controller sample
ACCURACY_DURATION = 0.1


def register(sub) -> None:
    """Register the command."""
    p = sub.add_parser("accuracy", help="error against run time: RK4 step ladder vs the stiff reference")
    add_scene(p)
    p.add_argument("--study", metavar="NAME", help="a study of the scene (default: 8 Hz, 2 deg sine; 1 mm for "
                   "an output travel)")
    add_sine_options(p)
    add_force(p)
    add_json(p)
    p.set_defaults(run=run)


def _check_budget(scene, duration: float, force: bool) -> None:
    """The reference solve and the RK4 ladder within the work budget unless ``--force``."""
    from .budget import check_time, time_run_seconds
    ref, what, _ = time_run_seconds(scene, duration, None, "reference")
    rk4, _, _ = time_run_seconds(scene, duration, None, "rk4")
    check_time(ref + 4 * rk4, "sensors.sample_time", what, f"{scene.sensors.sample_time:g} s", force)


def run(args) -> int:
    """Run the command."""
    from ..sim import build_model, controller_for
    from ..studies.accuracy import accuracy_study
    from ..sim.reference import Reference
    from ..studies.time.reference import run_spec

    scene = load_scene(args.scene)
    reference, duration, voltage, _, _ = run_spec(scene, args.study, amplitude=amplitudes_si(scene, args.amplitude),
                                                  frequency=args.frequency)
    _check_budget(scene, min(duration, ACCURACY_DURATION), args.force)
    if voltage is not None:
        model = build_model(scene, None)
        reference = Reference.voltage(voltage)
    else:
        controller, _ = controller_for(scene)
        model = build_model(scene, controller)
    result = accuracy_study(model, reference, min(duration, ACCURACY_DURATION), progress=not args.json)
    emit(args, result, result.table())
    return 0
