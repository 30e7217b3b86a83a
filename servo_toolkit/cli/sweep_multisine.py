"""``servo-toolkit sweep --method multisine``: the options and the run (the sine dwell is
:mod:`.cmd_sweep`'s).

The band and the number of lines come from ``--band`` and ``--lines``, else from the
``--frequency`` values (lowest to highest, one line each), else from the study's
frequencies. ``-o`` writes the response as the CSV ``fit`` reads (``fit --response`` the
same as ``--response`` here), ``--log`` the run's records as a log ``frf`` reads.
"""

from __future__ import annotations

import sys
from pathlib import Path

from ..core.files import check_stamped_file, save_figure, write_text
from ..core.marks import stamp
from ..errors import SceneError, SimulationError
from .common import bounded, emit, parse_band, study_executor

#: options that only the multisine reads, with their defaults
OPTIONS = {"response": None, "band": None, "lines": None, "periods": None, "settle": None, "out": None, "log": None}


def register(p) -> None:
    """Add the multisine's options to the ``sweep`` parser."""
    p.add_argument("--method", choices=("sine", "multisine"), default="sine",
                   help="sine: a sine dwell per frequency (default); multisine: one periodic multisine over the "
                        "band (Schroeder phases), estimated period by period with rectangular windows, as frf "
                        "estimates a rig's log")
    p.add_argument("--response", choices=("closed_loop", "plant"),
                   help="multisine: closed_loop, position command -> output position (default); plant, motor "
                        "current -> motor speed in the running loop (what fit --response reads)")
    p.add_argument("--band", metavar="LO:HI",
                   help="multisine: lowest and highest line in Hz (default: the --frequency values' or the study's "
                        "range); the lowest is the period's fundamental")
    p.add_argument("--lines", type=bounded(int, 2, 10000, what="a number of lines"), metavar="N",
                   help="multisine: lines, log-spaced over the band (default: as many as frequencies; with --band "
                        "alone, 10 per decade of it)")
    p.add_argument("--periods", type=bounded(int, 1, 1000, what="a number of periods"), metavar="N",
                   help="multisine: periods estimated from (default 4)")
    p.add_argument("--settle", type=bounded(int, 0, 1000, what="a number of periods"), metavar="K",
                   help="multisine: periods run first and left out (default: five time constants of the linear "
                        "loop's slowest pole, at least one)")
    p.add_argument("-o", "--out", dest="out", metavar="FRF.csv",
                   help="multisine: write the response as the CSV fit reads (one --amplitude)")
    p.add_argument("--log", metavar="LOG.csv",
                   help="multisine: write the run's records as a log frf reads (one --amplitude)")


def check_options(args) -> None:
    """Refuse a multisine option with the sine dwell (one line naming it)."""
    if args.method == "multisine":
        return
    given = [f"--{k.replace('_', '-')}" if k != "out" else "-o" for k, d in OPTIONS.items()
             if getattr(args, k, None) is not d]
    if given:
        raise SceneError(given[0], "applies to --method multisine")


def run(args, scene, amps, scheduler) -> int:
    """The multisine sweep of ``sweep``."""
    from ..sim.simulate import controller_for
    from ..studies.multisine import DEFAULT_PERIODS, multisine_spec, multisine_sweep
    from .budget import check_time, time_run_seconds
    for option, path, suffixes in (("-o", args.out, (".csv",)), ("--log", args.log, (".csv",))):
        if path is not None:
            check_stamped_file(path, option, "sweep", suffixes, inputs=[args.scene, *scene.input_files])
    if args.out and args.log and Path(args.out).resolve() == Path(args.log).resolve():
        raise SceneError("--log", "must be another file than -o")
    if (args.out or args.log) and amps is not None and len(amps) > 1:
        raise SceneError("-o" if args.out else "--log", "writes one response: give one --amplitude")
    band = parse_band(args.band, low_open=True)
    lines = args.lines
    if band is None and args.frequency:
        if len(set(args.frequency)) < 2:
            raise SceneError("--frequency", "a multisine needs a band: two or more --frequency values, or --band LO:HI")
        band = (min(args.frequency), max(args.frequency))
        lines = lines or len(set(args.frequency))
    periods = args.periods or DEFAULT_PERIODS
    if band is not None:
        seconds, what, _ = time_run_seconds(scene, (periods + (args.settle or 1)) / band[0], None, "rk4")
        check_time(seconds * (len(amps) if amps else 1), "--band", what, f"a period of {1 / band[0]:g} s",
                   args.force)
    spec = multisine_spec(scene, args.study, band=band, lines=lines, amplitudes=amps, periods=periods,
                          settle=args.settle, response=args.response or "closed_loop")  # before any work
    controller, source = controller_for(scene)  # designed once, here, and handed down
    with study_executor(scheduler, args.workers) as (executor, _):
        res = multisine_sweep(scene, spec=spec, controller=controller, controller_source=source, full=args.full,
                              executor=executor, progress=not args.json and sys.stderr.isatty())
    if (args.out or args.log) and res.errors[0] is not None:
        raise SimulationError(f"the multisine run failed, nothing written: {res.errors[0]}")
    if args.out:
        write_text(args.out, stamp(res.csv(0), "sweep"), "-o")
    if args.log:
        write_text(args.log, stamp(res.log_csv(0), "sweep"), "--log")
    if args.plot:
        import matplotlib
        matplotlib.use("Agg")
        axes = res.plot()
        save_figure(axes[0].figure, args.plot)
    emit(args, res, res.table() + "".join(f"\nwritten to {p}" for p in (args.out, args.log) if p))
    return 0


__all__ = ["check_options", "register", "run"]
