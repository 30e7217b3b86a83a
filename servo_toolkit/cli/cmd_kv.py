"""``servo-toolkit kv``: dynamic-load factor Kv of the scene's kv studies (seed 000)."""

from __future__ import annotations

import sys

from ..errors import SceneError
from .common import add_force, add_json, add_scene, add_sine_options, amplitudes_si, emit, load_scene
from .hints import what_to_run


def register(sub) -> None:
    """Register the command."""
    p = sub.add_parser("kv", help="dynamic-load factor Kv (inverse dynamics along prescribed motions)")
    add_scene(p)
    p.add_argument("--study", metavar="NAME",
                   help="run only this study, or a seed-mechanism study (default: every study of kind kv)")
    add_sine_options(p, what="the Kv study's sine motion (replaces the scene's kv studies; default without "
                             "one: 8 Hz, 2 deg, or 1 mm for an output travel)")
    p.add_argument("--losses", choices=("directional", "none"), default="directional",
                   help="stage-loss model (default: directional efficiency)")
    add_force(p)
    add_json(p)
    p.set_defaults(run=run)


def _check_budget(scene, studies, force: bool) -> None:
    """Refuse Kv grids estimated beyond the work budget unless ``--force`` (before any work);
    the knob named is the drivetrain, whose length sets the cost of every case."""
    from .budget import check_time, kv_seconds
    from ..studies.kv.kind import KV
    from ..studies.kv.study import _motions
    cases = 0
    for study in studies:
        if getattr(study, "kind", None) == KV.name:
            inertias = study.get("load_inertias", [0.0, scene.load.inertia])
            cases += len(_motions(scene, study)[0]) * (len(inertias) + 1 if isinstance(inertias, (list, tuple)) else 2)
    if cases:
        seconds, what = kv_seconds(len(scene.stages), cases)
        check_time(seconds, "drivetrain", what, f"{len(scene.stages)} stages", force)


def run(args) -> int:
    """Run the command."""
    from ..studies.kv.kind import KV
    from ..studies.kv.study import default_kv_study, kv_study
    from ..studies.run import default_study, has_motor_drivetrain, is_mechanism_study, run_study, study_of
    scene = load_scene(args.scene)
    sine = args.amplitude is not None or args.frequency is not None
    if args.study and sine:
        raise SceneError("--study", "give a study or --amplitude/--frequency (a sine of its own), not both")
    progress = not args.json and sys.stderr.isatty()
    if not args.study and not has_motor_drivetrain(scene):
        name = default_study(scene)
        if name is None:
            raise SceneError("drivetrain", f"this scene has no motor-driven drivetrain; {what_to_run(scene, args.scene)}")
        print(f"servo-toolkit: note: {scene.name} has no motor-driven drivetrain; running its study {name!r}",
              file=sys.stderr)
        names = [name]
    elif args.study:
        study_of(scene, args.study)
        names = [args.study]
    else:
        names = [] if sine else [s.name for s in scene.studies_of_kind(KV.name)]
    if names:
        studies = [study_of(scene, n) for n in names]
        _check_budget(scene, studies, args.force)
        results = [run_study(scene, n, as_kind=KV.name, **({} if is_mechanism_study(scene, n) else
                                                         dict(losses=args.losses, progress=progress)))
                   for n in names]
    else:
        studies = [default_kv_study(scene, amplitudes_si(scene, args.amplitude), args.frequency)]
        _check_budget(scene, studies, args.force)
        names = [studies[0].name]
        results = [kv_study(scene, studies[0], losses=args.losses, progress=progress)]
    dicts = [r.to_dict() if hasattr(r, "to_dict") else dict(r) for r in results]
    cases = [dict(c, study=n) for n, d in zip(names, dicts) for c in d.get("cases", [])]
    payload = {"scene": scene.name, "studies": dicts, "cases": cases}
    text = "\n\n".join(r.table() if hasattr(r, "table") else str(r) for r in results)
    kv = all(getattr(st, "kind", None) == KV.name for st in studies)
    title = f"Kv dynamic-load studies of {scene.name}" if kv else f"Studies of {scene.name}: {', '.join(names)}"
    emit(args, payload, f"{title}\n{text}")
    return 0
