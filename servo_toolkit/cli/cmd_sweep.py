"""``servo-toolkit sweep``: frequency response of the nonlinear loop vs the linear one, by sine
dwell or (``--method multisine``, :mod:`.sweep_multisine`) by a periodic multisine."""

from __future__ import annotations

import sys

from ..errors import SceneError
from .common import (add_force, add_json, add_scene, add_scheduler, add_sine_options, amplitudes_si, bounded, emit,
                     load_scene, scheduler_of, study_executor)
from ..core.files import check_figure_file, save_figure
from . import sweep_multisine


def register(sub) -> None:
    """Register the command."""
    p = sub.add_parser("sweep", help="nonlinear closed-loop frequency response (sine dwell or multisine) against the "
                                     "linear loop")
    add_scene(p)
    p.add_argument("--study", metavar="NAME",
                   help="a frequency_sweep study, plus 8 Hz (default: the scene's first), or a "
                   "seed-mechanism study (run as simulate runs it)")
    add_sine_options(p, repeat=True, what="the dwell (replaces the study's)")
    p.add_argument("--full", action="store_true", help="run the full model (default: the reduced model)")
    p.add_argument("--workers", type=bounded(int, 1, 256, what="a number of processes"), default=0, metavar="N",
                   help="run the dwells in N processes (at least 1; default: in this process)")
    add_scheduler(p, what="the dwells (or a seed-mechanism study's cases)")
    p.add_argument("--plot", metavar="FILE", help="save the Bode comparison (PNG/SVG/PDF)")
    sweep_multisine.register(p)
    add_force(p)
    add_json(p)
    p.set_defaults(run=run)


def _run_mechanism(scene, name, args, scheduler) -> int:
    """A seed-mechanism study: its own runner; the sine-dwell options do not apply."""
    import numpy as np

    from ..studies.run import run_study
    given = [opt for opt, value in (("--frequency", args.frequency), ("--amplitude", args.amplitude),
                                    ("--full", args.full), ("--method", args.method != "sine")) if value]
    if given:
        raise SceneError(f"studies.{name}", f"is a seed-mechanism study; {', '.join(given)} "
                         f"{'applies' if len(given) == 1 else 'apply'} to frequency_sweep studies only")
    with study_executor(scheduler, args.workers) as (executor, _):
        res = run_study(scene, name, executor=executor)
    if args.plot and hasattr(res, "plot"):
        import matplotlib
        matplotlib.use("Agg")
        ax = np.ravel(res.plot())[0]
        save_figure(ax.figure, args.plot)
    emit(args, res, res.table() if hasattr(res, "table") else str(res))
    return 0


def _sweep(scene, name, **options):
    """The sweep of study ``name``, or of the scene's first frequency_sweep study (and 8 Hz)."""
    if name:
        from ..studies.run import run_study
        from ..studies.sweep.kind import SWEEP
        return run_study(scene, name, as_kind=SWEEP.name, **options)
    from ..studies.sweep.compute import sweep
    return sweep(scene, None, **options)


def check_sweep_budget(scene, study, frequencies, amplitudes, force: bool, runs: int = 1, option="--frequency"):
    """Refuse sine dwells estimated beyond the work budget unless ``force`` (before any work);
    the knob named is ``--frequency`` when given, else the study's ``frequencies``."""
    from .budget import check_time, sweep_seconds
    from ..studies.sweep.points import study_points
    name, freqs, amps = study_points(scene, study)
    freqs = frequencies or freqs
    amps = amplitudes or amps
    seconds, what = sweep_seconds(scene, freqs, amps, runs)
    knob = option if frequencies else f"studies.{name}.frequencies" if name else option
    from ..studies.sine_dwell import DwellPlan
    from ..studies.sweep.points import check_sweep_frequencies
    check_sweep_frequencies(scene, freqs, knob, DwellPlan())  # a frequency no dwell resolves: its own rule first
    check_time(seconds, knob, what, f"{len(freqs)} frequencies x {len(amps)} amplitudes", force)


def run(args) -> int:
    """Run the command."""
    from ..studies.run import default_study, is_mechanism_study
    scheduler = scheduler_of(args)  # before the scene is read
    sweep_multisine.check_options(args)
    scene = load_scene(args.scene)
    if args.plot:  # checked before any work
        check_figure_file(args.plot, "--plot", inputs=[args.scene, *scene.input_files])
    name = args.study or default_study(scene)
    if name:
        if not args.study:
            print(f"servo-toolkit: note: {scene.name} has no motor-driven drivetrain (no loop to sweep); "
                  f"running its study {name!r} as simulate does", file=sys.stderr)
        if is_mechanism_study(scene, name):
            return _run_mechanism(scene, name, args, scheduler)
    amps = amplitudes_si(scene, args.amplitude)
    if args.method == "multisine":
        return sweep_multisine.run(args, scene, amps, scheduler)
    check_sweep_budget(scene, args.study, args.frequency, amps, args.force)
    from ..sim.simulate import controller_for
    controller, source = controller_for(scene)  # designed once, here, and handed down
    kw = dict(frequencies=args.frequency, amplitudes=amps, full=args.full, controller=controller,
              controller_source=source, progress=not args.json and sys.stderr.isatty())
    try:
        with study_executor(scheduler, args.workers) as (executor, _):
            res = _sweep(scene, args.study, executor=executor, **kw)
    except SceneError as exc:
        if exc.key == "frequencies":  # the option, not the scene
            raise SceneError("--frequency", exc.rule) from None
        raise
    if args.plot:
        import matplotlib
        matplotlib.use("Agg")
        ax = res.plot()
        save_figure(ax[0].figure, args.plot)
    emit(args, res, res.table())
    return 0
