"""``servo-toolkit sweep``: sine-dwell frequency response of the nonlinear loop vs the linear one."""

from __future__ import annotations

import math
import sys

from ..scene import load_scene
from .common import add_json, add_scene, emit


def register(sub) -> None:
    """Register the command."""
    p = sub.add_parser("sweep", help="nonlinear closed-loop sine-dwell sweep against the linear loop")
    add_scene(p)
    p.add_argument("--study", metavar="NAME", help="a frequency_sweep study (default: the scene's first, plus 8 Hz)")
    p.add_argument("--frequency", type=float, action="append", metavar="HZ",
                   help="drive frequency in Hz, repeatable (replaces the study's)")
    p.add_argument("--amplitude", type=float, action="append", metavar="DEG",
                   help="command amplitude in deg, repeatable: one curve each (replaces the study's)")
    p.add_argument("--full", action="store_true", help="run the full model (default: the reduced model)")
    p.add_argument("--workers", type=int, default=0, metavar="N", help="run the dwells in N processes")
    p.add_argument("--plot", metavar="FILE", help="save the Bode comparison (PNG/SVG/PDF)")
    add_json(p)
    p.set_defaults(run=run)


def run(args) -> int:
    """Run the command."""
    from ..studies.sweep import sweep
    scene = load_scene(args.scene)
    amps = [math.radians(a) for a in args.amplitude] if args.amplitude else None
    for name, values in (("--frequency", args.frequency), ("--amplitude", args.amplitude)):
        if values and (min(values) <= 0 or not all(math.isfinite(v) for v in values)):
            sys.stderr.write(f"error: {name} must be positive and finite\n")
            return 2
    kw = dict(frequencies=args.frequency, amplitudes=amps, full=args.full,
              progress=not args.json and sys.stderr.isatty())
    if args.workers > 1:
        from concurrent.futures import ProcessPoolExecutor
        with ProcessPoolExecutor(args.workers) as pool:
            res = sweep(scene, args.study, executor=pool, **kw)
    else:
        res = sweep(scene, args.study, **kw)
    if args.plot:
        import matplotlib
        matplotlib.use("Agg")
        ax = res.plot()
        ax[0].figure.savefig(args.plot, bbox_inches="tight")
    emit(args, res, res.table())
    return 0
