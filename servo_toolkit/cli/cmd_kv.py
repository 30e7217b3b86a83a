"""``servo-toolkit kv``: dynamic-load factor Kv of the scene's kv studies (seed 000)."""

from __future__ import annotations

import sys

from ..errors import SceneError
from ..scene import load_scene
from ..studies.kv import default_kv_study, kv_study
from . import mechanism_dispatch as dispatch
from .common import add_force, add_json, add_scene, add_sine_options, amplitudes_si, emit
from .hints import default_mechanism_study, has_motor_drivetrain, what_to_run


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


def _run_one(scene, study, args):
    if dispatch.handled(scene, study):
        return dispatch.run_mechanism(scene, study)
    if study.kind != "kv":
        raise SceneError(study.key("kind"), f"is {study.kind!r}; the kv command runs studies of kind 'kv'")
    return kv_study(scene, study, losses=args.losses, progress=not args.json and sys.stderr.isatty())


def _check_budget(scene, studies, force: bool) -> None:
    """Refuse Kv grids estimated beyond the work budget unless ``--force`` (before any work);
    the knob named is the drivetrain, whose length sets the cost of every case."""
    from ..budget import check_time, kv_seconds
    from ..studies.kv import _motions
    cases = 0
    for study in studies:
        if getattr(study, "kind", None) == "kv":
            inertias = study.get("load_inertias", [0.0, scene.load.inertia])
            cases += len(_motions(scene, study)[0]) * (len(inertias) + 1 if isinstance(inertias, (list, tuple)) else 2)
    if cases:
        seconds, what = kv_seconds(len(scene.stages), cases)
        check_time(seconds, "drivetrain", what, f"{len(scene.stages)} stages", force)


def run(args) -> int:
    """Run the command."""
    scene = load_scene(args.scene)
    sine = args.amplitude is not None or args.frequency is not None
    if args.study and sine:
        raise SceneError("--study", "give a study or --amplitude/--frequency (a sine of its own), not both")
    if not args.study and not has_motor_drivetrain(scene):
        name = default_mechanism_study(scene)
        if name is None:
            raise SceneError("drivetrain", f"this scene has no motor-driven drivetrain; {what_to_run(scene, args.scene)}")
        print(f"servo-toolkit: note: {scene.name} has no motor-driven drivetrain; running its study {name!r}",
              file=sys.stderr)
        studies = [scene.studies.get(name, name)]
    elif args.study:
        dispatch.require(scene, args.study)
        studies = [scene.studies.get(args.study, args.study)]
    else:
        studies = [] if sine else scene.studies_of_kind("kv")
        if not studies:
            studies = [default_kv_study(scene, amplitudes_si(scene, args.amplitude), args.frequency)]
    _check_budget(scene, studies, args.force)
    results = [_run_one(scene, s, args) for s in studies]
    names = [getattr(s, "name", s) for s in studies]
    dicts = [r.to_dict() if hasattr(r, "to_dict") else dict(r) for r in results]
    cases = [dict(c, study=n) for n, d in zip(names, dicts) for c in d.get("cases", [])]
    payload = {"scene": scene.name, "studies": dicts, "cases": cases}
    text = "\n\n".join(r.table() if hasattr(r, "table") else str(r) for r in results)
    kv = all(getattr(st, "kind", None) == "kv" for st in studies)
    title = f"Kv dynamic-load studies of {scene.name}" if kv else f"Studies of {scene.name}: {', '.join(names)}"
    emit(args, payload, f"{title}\n{text}")
    return 0
