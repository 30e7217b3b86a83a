"""``servo-toolkit design``: loop design and margins of one scene."""

from __future__ import annotations

from ..errors import SceneError
from .common import (add_force, add_json, add_scene, bounded, check_design_budget, check_robustness_budget, emit,
                     load_scene)
from .plant_frf import add_plant_frf_options, measured_mode_of, plant_frf_check, settle_plant_frf


def design(scene, **options):
    """:func:`servo_toolkit.loop.design.design`, imported when a design runs."""
    from ..loop.design import design as design_loop
    return design_loop(scene, **options)


def add_design_options(p) -> None:
    """Options shared by ``design`` and ``check``."""
    p.add_argument("--require", action="append", default=[], metavar="NAME=VALUE",
                   help="override a requirement, e.g. bandwidth=200Hz, phase_margin=50deg (repeatable)")
    p.add_argument("--structure", default="cascade", choices=("cascade", "pid", "lead_lag", "pi"),
                   help="controller structure (default cascade: current -> speed -> position)")
    p.add_argument("--filter", dest="resonance_filter", default="auto",
                   choices=("auto", "none", "notch", "lowpass"), help="drivetrain resonance filter")
    p.add_argument("--design", metavar="FILE",
                   help="evaluate the controller saved in FILE (a tuned design, written by the Jupyter tuner's "
                        "save() or servo_toolkit.loop.tuning.save_design) instead of designing one")
    p.add_argument("--current-ripple", type=bounded(float, 0.0, low_open=True, what="a current in A"),
                   default=None, metavar="A",
                   help="current ripple (A rms) the motor encoder's quantization and the play's limit cycle may "
                        "each cost; a cascade's speed-loop gain is lowered to keep within it (default the scene's "
                        "max_current_ripple, else 10%% of the continuous current or 5%% of the current limit)")
    mode = p.add_mutually_exclusive_group()
    mode.add_argument("--robust", dest="robust", action="store_const", const=True, default=None,
                      help="robust design over the scene's [robustness] ranges (when it has none: the load "
                           "inertia from 0 to four times the scene's, stiffness 0.7..1.3); the default when the scene has [robustness]")
    mode.add_argument("--nominal", dest="robust", action="store_const", const=False,
                      help="nominal design even when the scene has [robustness]")


def add_large_signal_option(p) -> None:
    """``--linear-only`` (``design`` and ``check``)."""
    p.add_argument("--linear-only", action="store_true",
                   help="skip the large-signal rows (the nonlinear closed loop on the requirement sine against "
                        "the linear loop, with the time at the voltage and current limits)")


def gate_result(scene, args, result):
    """``result`` with the large-signal rows unless ``--linear-only``: (result, LargeSignal or None)."""
    if getattr(args, "linear_only", False):
        return result, None
    from ..studies.gate import with_large_signal
    return with_large_signal(scene, result)


def design_from_args(scene, args, spec=None, executor=None, design_text=None):
    """Run the design with the command-line options; ``spec`` (a Robustness) replaces the
    scene's ``[robustness]`` for a robust design (``check --vary``); ``executor`` runs the
    chunks of its variants (``check --scheduler``); ``design_text``, the ``--design`` file's
    text already read, is not read again. With ``--plant-frf`` the drivetrain mode of the
    measured response places the notch (:mod:`servo_toolkit.loop.measured_mode`)."""
    from ..loop.requirements import parse_overrides
    require = parse_overrides(args.require)
    if getattr(args, "design", None):
        from ..loop.tuning import load_design
        return load_design(scene, args.design, require=require or None, text=design_text)
    robust = args.robust
    if spec is not None and (robust is True or (robust is None and scene.robustness is not None)):
        robust = spec
    return design(scene, structure=args.structure, resonance_filter=args.resonance_filter, require=require,
                  robust=robust, progress=False, executor=executor,
                  current_ripple=getattr(args, "current_ripple", None), measured_mode=measured_mode_of(args))


def register(sub) -> None:
    """Register the command."""
    p = sub.add_parser("design", help="loop design and margins",
                       description="Loop design and margins: judges the loop's rows (exit 0 met, 1 not met); a note "
                                   "names the rows servo-toolkit check judges besides.")
    add_scene(p)
    add_design_options(p)
    add_large_signal_option(p)
    add_plant_frf_options(p)
    add_force(p)
    add_json(p)
    p.set_defaults(run=run)


def run(args) -> int:
    """Run the command; exit 0 when every loop requirement (the large-signal and robustness
    rows included) is met and the closed loop is stable, 1 otherwise, 2 on bad input. The
    rows ``check`` adds (the nonlinear step and sine's, e.g. ``tracking_error``, the sizing
    of a ``[duty_cycle]``, a required yield, Monte Carlo requirements) are not judged here: a
    note names those the scene asks for (:func:`~servo_toolkit.studies.gate.left_to_check`);
    nor are the measured plant's (``--plant-frf``: its margins are printed beside the
    model's; ``check --plant-frf`` judges them)."""
    from ..loop.requirements import parse_overrides
    parse_overrides(args.require)  # a bad value: exit 2 before the scene is read
    if getattr(args, "plant_frf", None):
        settle_plant_frf(args)  # a bad file stops before any design
    scene = load_scene(args.scene)
    check_design_budget(scene, args.force)
    if not getattr(args, "design", None):
        from ..loop.design import robust_spec
        spec = robust_spec(scene, args.robust)
        check_robustness_budget(scene, spec, spec is not None, None, args.force)
    try:
        result = design_from_args(scene, args)  # reads and checks a --design file first
    except SceneError as exc:  # e.g. no motor-driven drivetrain: name the file (an option names itself)
        raise (exc if exc.source or exc.key.startswith("--") else exc.with_source(str(args.scene))) from None
    result, ls = gate_result(scene, args, result)
    from dataclasses import replace

    from ..studies.gate import left_to_check
    result = replace(result, notes=tuple(result.notes) + (left_to_check(scene, getattr(args, "linear_only", False)),))
    data = result.to_dict()
    if ls is not None:
        data["large_signal"] = ls.to_dict()
    from ..loop.command_design import command_design
    command = command_design(scene, result)
    data["command"] = command.to_dict()
    text = ""
    if getattr(args, "plant_frf", None):
        _, data["measured_plant"], text = plant_frf_check(args, scene, result, rows=False)
    emit(args, data, result.table() + ("\n" + text if text else "") + "\ncommand options (feedforward, gain schedule, shapers; "
                                             "servo-toolkit simulate --feedforward, --schedule, --shaper):\n"
         + "\n".join(command.lines()))
    return 0 if result.passed and result.margins.closed_loop_stable else 1
