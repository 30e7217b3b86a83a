"""``servo-toolkit simulate``: a time simulation of a scene (closed loop or open loop)."""

from __future__ import annotations

import sys

from ..errors import SceneError
from .common import (add_force, add_friction, add_json, add_scene, add_sine_options, amplitudes_si, bounded, emit,
                     load_scene)


def register(sub) -> None:
    """Register the command."""
    p = sub.add_parser("simulate", help="time simulation (compiled RK4, paper scheme or stiff reference)")
    add_scene(p)
    p.add_argument("--study", metavar="NAME", help="a study of the scene (default: 8 Hz, 2 deg sine, 1 s; "
                   "1 mm for an output travel)")
    add_sine_options(p)
    p.add_argument("--method", choices=("rk4", "paper", "reference", "auto"), default=None,
                   help="integration method: 'auto' (the default unless the study names one) runs fixed-step "
                        "RK4 at a step it picks from the fastest eigenvalue (|lambda dt| = 1) and hands a run "
                        "needing more than 2e7 steps to the stiff solver; 'rk4' fixed-step RK4 at --dt or the "
                        "study's sample_time; 'paper' the cam paper's frozen-configuration scheme (fixed step); "
                        "'reference' scipy's stiff solve_ivp at tight tolerances (slow, the accuracy reference)")
    p.add_argument("--dt", type=bounded(float, 1e-9, 1.0, what="a step in seconds"), metavar="S",
                   help="fixed step (s), 1e-9 to 1, of the fixed-step methods (rk4, paper); without --method it "
                        "runs rk4 at that step; refused with --method auto or reference")
    p.add_argument("-o", "--output", metavar="FILE", help="write the traces (.csv or .npz)")
    p.add_argument("--feedforward", choices=("off", "gains", "model"), default="off",
                   help="feedforward from the command (default off): 'gains' adds the designed velocity and "
                        "acceleration gains' current (Kv = (b N^2 + c_load) / (N Kt), Ka = J / (N Kt) at q0), "
                        "'model' the current the drivetrain's inverse dynamics needs along the stroke; both give "
                        "the speed loop the commanded motor speed; outside the loop, the margins are unchanged")
    p.add_argument("--shaper", choices=("off", "zv", "zvd"), default="off",
                   help="command shaper on the drivetrain mode the command excites (the closed loop's pole pair "
                        "of the mode): ZV delays the command by half its damped period, ZVD by a whole one "
                        "(default off)")
    add_friction(p)
    p.add_argument("--schedule", action="store_true",
                   help="schedule the loop's gains along the stroke (speed gains with the motor-side inertia, "
                        "position gain with the ratio), interpolated at the measured output angle each sample")
    add_force(p)
    p.add_argument("--full", action="store_true",
                   help="run the full model (default: a closed-loop sine runs the reduced model and says what it "
                        "left out)")
    add_json(p)
    p.set_defaults(run=run)


def _mechanism_dispatch(scene, args):
    """The mechanism studies' own runner when it handles this study (by default, a scene
    without a motor-driven drivetrain runs its first mechanism study), else None."""
    from ..studies.run import default_study, is_mechanism_study, run_study
    name = args.study or default_study(scene)
    if not name:
        return None
    if not args.study:
        print(f"servo-toolkit: note: {scene.name} has no motor-driven drivetrain; running its study "
              f"{name!r} (--study NAME for another)", file=sys.stderr)
    if not is_mechanism_study(scene, name):
        return None
    given = [opt for opt, value in (("--amplitude", args.amplitude), ("--frequency", args.frequency),
                                    ("--full", args.full), ("--feedforward", args.feedforward != "off"),
                                    ("--shaper", args.shaper != "off"), ("--schedule", args.schedule),
                                    ("--friction", args.friction))
             if value]
    if given:
        raise SceneError(f"studies.{name}", f"is a seed-mechanism study; "
                         f"{', '.join(given)} {'applies' if len(given) == 1 else 'apply'} to closed-loop sine runs only")
    return run_study(scene, name, method=args.method, dt=args.dt)


def check_budget(scene, args, amplitude, spec=None) -> None:
    """Refuse (exit 2, naming the knob) a run estimated beyond the work budget, unless
    ``--force``: checked before any work. ``spec``: the study's
    :func:`~servo_toolkit.studies.time.reference.run_spec`, when the caller has it."""
    from .budget import LONG_RUN_S, check_time, time_run_seconds
    if spec is None:
        from ..studies.time.reference import run_spec
        spec = run_spec(scene, args.study, amplitude=amplitude, frequency=args.frequency)
    _, duration, _, study_method, study_dt = spec
    method = args.method or study_method
    dt = args.dt or (study_dt if method in ("rk4", "paper") else None)
    seconds, what, _ = time_run_seconds(scene, duration, dt, method)
    if duration > LONG_RUN_S or not (dt or scene.sensors.sample_time):
        knob, got = (f"studies.{args.study}.duration" if args.study else "duration"), duration
    elif args.dt:
        knob, got = "--dt", args.dt
    elif dt:
        knob, got = f"studies.{args.study}.sample_time", dt
    else:
        knob, got = "sensors.sample_time", scene.sensors.sample_time
    got = f"{got:g} s"
    check_time(seconds, knob, what, got, args.force)


def run(args) -> int:
    """Run the command."""
    from ..sim.result import check_trace_path
    from ..studies.run import run_study
    from ..studies.time.kind import SIMULATE
    from ..studies.time.run import simulate_study

    scene = load_scene(args.scene)
    check_trace_path(args.output, inputs=[args.scene, *scene.input_files])  # a bad -o fails before the run, exit 2
    amplitude = amplitudes_si(scene, args.amplitude)
    result = _mechanism_dispatch(scene, args)
    if result is None:
        from ..studies.time.reference import run_spec
        from ..studies.time.run import resolve_method
        # a bad frequency or a --dt the method would ignore: one line, before any work; the run
        # is resolved here once and handed down
        spec = run_spec(scene, args.study, amplitude=amplitude, frequency=args.frequency)
        reference, duration, voltage, study_method, study_dt = spec
        method, dt = resolve_method(args.method, study_method, args.dt, study_dt, key="--dt")
        check_budget(scene, args, amplitude, spec)
        controller = source = None
        if voltage is None:  # a closed loop: its controller is designed once, here
            from ..sim.simulate import controller_for
            controller, source = controller_for(scene)
        options = dict(method=args.method, dt=args.dt, full=args.full, amplitude=amplitude, frequency=args.frequency,
                       feedforward=args.feedforward, shaper=args.shaper, schedule=args.schedule or None,
                       friction=args.friction, controller=controller, controller_source=source,
                       spec=(reference, duration, voltage, method, dt))
        result = (run_study(scene, args.study, as_kind=SIMULATE.name, **options) if args.study
                  else simulate_study(scene, None, **options))
        text = f"Simulation of {scene.name}\n" + result.table()
        if args.dt is not None:
            step = "adaptive" if result.dt_s is None else f"{result.dt_s:.4g} s"
            print(f"servo-toolkit: note: ran method {result.method} at step {step} (--dt {args.dt:g} s"
                  f"{', no --method: fixed-step RK4' if args.method is None and study_method is None else ''})",
                  file=sys.stderr)
    else:
        text = result.table() if hasattr(result, "table") else str(result.to_dict())
    if args.output:
        if not hasattr(result, "save"):
            print("servo-toolkit: this study writes no traces", file=sys.stderr)
            return 2
        path = result.save(args.output, inputs=[args.scene, *scene.input_files])
        print(f"traces written to {path}", file=sys.stderr)
    from ..sim.simulate import UNSTABLE_SOURCE
    if UNSTABLE_SOURCE in str(getattr(result, "controller", "")):
        print("servo-toolkit: warning: no stable controller was found for this scene; the run shows the "
              "design's unstable closed loop (see servo-toolkit design)", file=sys.stderr)
    emit(args, result, text)
    return 0
