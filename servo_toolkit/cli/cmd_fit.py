"""``servo-toolkit fit``: fit scene parameters to a measured response of the rig.

DATA.csv is a frequency response (``frequency_hz,gain_db,phase_deg[,coherence]``; what it
measured is ``--response``), time traces of the voltage-driven rig
(``time_s,voltage_V,current_A,motor_angle_rad,output_angle_rad``) or of the rig in closed
loop (``time_s,command_m,output_m,current_A``, ``_rad`` for an output angle), which the
nonlinear simulation with the scene's designed controller is compared with. ``-o`` writes the scene
file with the fitted values in place, each with a comment giving the old value.

The search is global over each parameter's physical range; the verdict compares the
residual with the data's own noise floor. Exit 0 when the model fits to the noise (or the
data cannot tell), 1 on a model mismatch (the frequencies or times where it misses are
named on stderr), 2 on bad input.
"""

from __future__ import annotations

import sys
from pathlib import Path

from ..errors import SceneError
from .common import add_force, add_json, add_scene, emit, load_scene
from ..core.files import check_stamped_file, write_text
from ..core.marks import stamp


def register(sub) -> None:
    """Register the command."""
    p = sub.add_parser("fit", help="fit scene parameters to a measured frequency response or time traces")
    add_scene(p)
    p.add_argument("data", metavar="DATA.csv",
                   help="measured frequency response (frequency_hz,gain_db,phase_deg[,coherence]), time traces "
                        "(time_s,voltage_V,current_A,motor_angle_rad,output_angle_rad) or closed-loop traces "
                        "(time_s,command_m,output_m,current_A; _rad for an output angle)")
    p.add_argument("--response", choices=("plant", "closed_loop"), default=None,
                   help="what a frequency response measured: plant = motor current -> motor speed (default), "
                        "closed_loop = position command -> output position with the scene's designed controller")
    p.add_argument("--param", action="append", required=True, metavar="KEY",
                   help="scene key to fit, as error messages name it, e.g. load.inertia, drivetrain[3].stiffness, "
                        "motor.resistance (repeatable; a positive scalar quantity, or a nonzero signed one such as "
                        "load.hinge_moment)")
    p.add_argument("-o", "--output", metavar="TOML",
                   help="write the calibrated scene here: the scene file with each fitted value in place and a "
                        "comment '# fitted: was ...' (never the input file); not at a model mismatch unless "
                        "--write-mismatch")
    p.add_argument("--write-mismatch", action="store_true",
                   help="write -o's calibrated scene even when the verdict is a model mismatch (its values are the "
                        "model's best at the data, whose intervals do not hold; without it -o is left unwritten)")
    add_force(p)
    add_json(p)
    p.set_defaults(run=run)


#: why -o is left unwritten at a model mismatch
NOT_WRITTEN = ("not written: the model does not fit the data (model mismatch), so its values are no calibration; "
               "--write-mismatch writes them all the same")


def _check_written(keys, values):
    """A check for :func:`write_text`: the written scene loads and gives the fitted values back."""
    def check(path):
        from ..identify.params import SceneTemplate
        back = SceneTemplate(load_scene(path), keys).initial
        for key, want, got in zip(keys, values, back):
            if abs(got - want) > 1e-5 * abs(want):
                raise SceneError(key, f"the calibrated scene reads back {got:g}, not the fitted {want:g}")
    return check


def _check_points_files(scene, output) -> None:
    """SceneError naming ``-o`` when the calibrated scene, written at ``output``, would not
    find a points file the scene names by a path relative to its own folder."""
    from ..core.files import same_file
    folder = Path(output).absolute().parent
    for i, seg in enumerate(getattr(scene.duty_cycle, "segments", ())):
        if seg.path and not Path(seg.file).is_absolute() and not same_file(folder / seg.file, seg.path):
            raise SceneError("-o", f"the scene's duty_cycle.segments[{i}].file {seg.file!r} is relative to the "
                                   f"scene's folder, and the calibrated scene in {str(folder)!r} would not read it: "
                                   f"write it beside the scene, or give the points file's absolute path")


def _check_signal(args, data) -> None:
    """A frequency response whose ``# signal:`` line names another signal than ``--response``
    compares (the motor speed for ``plant``, the output for ``closed_loop``): one SceneError."""
    signal = getattr(data, "signal", None)
    if signal is None:
        return
    response = args.response or "plant"
    if response == "plant" and signal != "motor_speed_rad_s":
        raise SceneError("DATA.csv", f"records the response to {signal} (its '# signal:' line); --response plant "
                         "compares the motor speed's: estimate it with frf LOG --derivative -o FRF.csv", str(args.data))
    if response == "closed_loop" and signal.startswith("motor_"):
        raise SceneError("DATA.csv", f"records the response to {signal} (its '# signal:' line); --response "
                         "closed_loop compares the output's", str(args.data))


def run(args) -> int:
    """Run the command."""
    from ..identify import calibrated_text, fit, read_data
    from ..identify.data import LoopData
    from ..scene import read_scene_text
    scene = load_scene(args.scene)
    if args.output is not None:  # checked before any work
        check_stamped_file(args.output, "-o", "fit", (".toml",), inputs=(args.scene, args.data, *scene.input_files))
        _check_points_files(scene, args.output)
    data = read_data(args.data)
    _check_signal(args, data)
    if isinstance(data, LoopData):  # the nonlinear closed loop runs over the whole log per evaluation
        from .budget import check_time, fit_seconds
        rows = int(data.time_s.size)
        seconds, what = fit_seconds(rows, len(args.param))
        check_time(seconds, "DATA.csv", what, f"{rows} rows in {args.data}: fit a shorter window of the log",
                   args.force)
    result = fit(scene, data, args.response, args.param, progress=not args.json and sys.stderr.isatty())
    write = args.output is not None and (not result.mismatch or args.write_mismatch)
    if write:
        text = calibrated_text(read_scene_text(Path(scene.source)), result)
        ok = [(k, v) for k, v, (_, hi) in zip(result.keys, result.values, result.ci95) if hi != float("inf")]
        write_text(args.output, stamp(text, "fit"), "-o", _check_written([k for k, _ in ok], [v for _, v in ok]))
    out = result.to_dict()
    if write:
        out["output"] = str(args.output)
    elif args.output is not None:
        out["output_not_written"] = NOT_WRITTEN
    tail = (f"\ncalibrated scene written to {args.output}" if write
            else f"\n{args.output}: {NOT_WRITTEN}" if args.output is not None else "")
    emit(args, out, result.table() + tail)
    if result.mismatch:
        print(f"servo-toolkit: {result.verdict_text()}", file=sys.stderr)
        return 1
    return 0
