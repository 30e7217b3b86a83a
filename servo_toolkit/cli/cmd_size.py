"""``servo-toolkit size``: the motor and the screw along the scene's ``[duty_cycle]``.

Exit 0 when every margin holds (peak and RMS torque, current, voltage, winding temperature,
screw and bearing life), 1 when one is exceeded, 2 for bad input (a scene without a duty
cycle, a bad segment: one line naming the key).
"""

from __future__ import annotations

import sys
from pathlib import Path

from ..core.files import check_figure_file, save_figure
from ..errors import SceneError
from .common import add_json, add_scene, emit, load_scene

HELP = "size motor and screw along the scene's duty cycle: envelope, RMS, thermal, life, ratio sweep"


def register(sub) -> None:
    """Register the command."""
    p = sub.add_parser("size", help=HELP)
    add_scene(p)
    p.add_argument("--closed-loop", action="store_true",
                   help="take the motor's torque and speed from the nonlinear closed-loop simulation of the "
                        "cycle (the designed loop, limits included) instead of the inverse dynamics")
    p.add_argument("--losses", choices=("directional", "none"), default="directional",
                   help="stage-loss model of the inverse dynamics (default: efficiency by direction of power flow)")
    p.add_argument("--no-sweep", action="store_true", help="leave out the ratio sweep")
    p.add_argument("--plot", metavar="FILE",
                   help="save the torque-speed, thermal, ratio-sweep and torque plots (.png, .svg or .pdf)")
    p.add_argument("--sweep-plot", metavar="FILE",
                   help="save the ratio sweep's figure: RMS current, peak torque and speed, winding temperature, "
                        "bandwidth estimate, output stiffness (and a swept lead's L10) over the ratio, limits "
                        "dashed, feasible ratios shaded (.png, .svg or .pdf)")
    add_json(p)
    p.set_defaults(run=run)


def run(args) -> int:
    """Run the command."""
    from ..studies.sizing import size
    if args.sweep_plot and args.no_sweep:
        raise SceneError("--sweep-plot", "needs the ratio sweep: leave out --no-sweep")
    scene = load_scene(args.scene)
    for key, path in (("--plot", args.plot), ("--sweep-plot", args.sweep_plot)):   # checked before any work
        if path:
            check_figure_file(path, key, inputs=[args.scene, *scene.input_files])
    if args.plot and args.sweep_plot and Path(args.plot).resolve() == Path(args.sweep_plot).resolve():
        raise SceneError("--sweep-plot", f"must be another file than --plot (got {args.sweep_plot!r} for both)")
    result = size(scene, closed_loop=args.closed_loop, losses=args.losses, sweep=not args.no_sweep,
                  progress=not args.json and sys.stderr.isatty())
    if args.plot or args.sweep_plot:
        import matplotlib
        matplotlib.use("Agg")
    if args.plot:
        save_figure(result.plot()[0].figure, args.plot)
    if args.sweep_plot:
        save_figure(result.plot_sweep()[0].figure, args.sweep_plot)
    emit(args, result, result.table())
    return 0 if result.passed else 1
