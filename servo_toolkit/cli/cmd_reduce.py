"""``servo-toolkit reduce``: what a study's model leaves out, why, and what that costs."""

from __future__ import annotations

import math
import sys

from ..errors import SceneError
from .common import add_force, add_json, add_scene, amplitudes_si, bounded, emit, load_scene
from ..core.files import check_figure_file, save_figure


def register(sub) -> None:
    """Register the command."""
    p = sub.add_parser("reduce", help="what the scene's model leaves out for a study, why, and the measured cost "
                                      "(of all together and of each effect on its own)")
    add_scene(p)
    p.add_argument("--study", metavar="NAME",
                   help="a frequency_sweep study (plus 8 Hz), or a kv or simulate (sine) study "
                   "(default: the scene's first sweep)")
    p.add_argument("--frequency", type=bounded(float, 0.0, 1e5, low_open=True, what="a frequency in Hz"), action="append", metavar="HZ",
                   help="frequency in Hz, repeatable: replaces a sweep study's frequencies (and its 8 Hz)")
    p.add_argument("--amplitude", action="append", metavar="AMP",
                   help="command amplitude with units, repeatable: replaces the study's (e.g. '2 deg', or "
                        "'1 mm' for an output travel; a bare number is in deg or mm)")
    p.add_argument("--tolerance", type=float, default=None, metavar="X",
                   help="a-priori bound on the relative response difference (default 0.02 = 0.17 dB / 1.15 deg)")
    p.add_argument("--estimate-only", action="store_true",
                   help="only the a-priori estimates and the choice (no full/reduced runs)")
    p.add_argument("--plot", metavar="FILE", help="save the measured difference per point")
    add_force(p)
    add_json(p)
    p.set_defaults(run=run)


def _check_budget(scene, args, amps, runs: int) -> None:
    """The dwells of a sweep study on ``runs`` models (the full, the reduced and the full
    without each effect left out), within the work budget unless ``--force`` (other studies
    run one short sine per model)."""
    from .cmd_sweep import check_sweep_budget
    from ..studies.sweep.kind import SWEEP
    study = scene.studies.get(args.study) if args.study else None
    if study is None or study.kind == SWEEP.name:
        if args.study is None and not scene.studies_of_kind(SWEEP.name) and not args.frequency:
            return
        check_sweep_budget(scene, args.study, args.frequency, amps, args.force, runs=runs)


def run(args) -> int:
    """Run the command."""
    from ..studies.reduce import DEFAULT_TOLERANCE, reduce, reduced_options
    tol = DEFAULT_TOLERANCE if args.tolerance is None else args.tolerance
    if not (math.isfinite(tol) and 0 < tol < 1):
        raise SceneError("--tolerance", f"must lie in (0, 1), a relative response difference (got {tol:g})")
    if args.frequency and not all(math.isfinite(f) and f > 0 for f in args.frequency):
        raise SceneError("--frequency", "must be positive and finite")
    scene = load_scene(args.scene)
    if args.plot:  # checked before any work
        check_figure_file(args.plot, "--plot", inputs=[args.scene, *scene.input_files])
    amps = amplitudes_si(scene, args.amplitude)  # a bad amplitude fails before any work
    if args.frequency:  # one the sampled loop cannot track fails before any work, with or without runs
        from ..sim.reference_checks import check_sine_frequency
        for f in args.frequency:
            check_sine_frequency(f, float(scene.sensors.sample_time), None, "--frequency")
    from ..sim.simulate import controller_for
    controller, source = controller_for(scene)  # designed once, here, and handed down
    _, plan = reduced_options(scene, args.study, tolerance=tol, frequencies=args.frequency, amplitudes=amps,
                              controller=controller)  # judged once, here, and handed down with the controller
    if args.estimate_only:
        lines = [f"A-priori reduction of {scene.name}" + (f" for study {args.study}" if args.study else "")]
        for e in plan.effects:
            lines += [f"{e.effect:34s} {e.estimate:9.2e}  {e.reason}"] + e.details(" " * 37)
        lines.append("left out: " + (", ".join(e.effect for e in plan.omitted) or "nothing"))
        emit(args, plan, "\n".join(lines))
        return 0
    alone = [e for e in plan.effects if e.switch is not None and (e.omitted or e.switch == "chain")]
    _check_budget(scene, args, amps, 2 + len(alone))
    res = reduce(scene, args.study, tolerance=tol, frequencies=args.frequency,
                 amplitudes=amps, controller=controller, controller_source=source, reduction=plan,
                 progress=not args.json and sys.stderr.isatty())
    if args.plot:
        import matplotlib
        matplotlib.use("Agg")
        save_figure(res.plot().figure, args.plot)
    emit(args, res, res.table())
    return 0
