"""``servo-toolkit kv``: dynamic-load factor Kv of the scene's kv studies (seed 000)."""

from __future__ import annotations

import sys

from ..errors import SceneError
from ..scene import load_scene
from ..studies.kv import kv_study
from . import mechanism_dispatch as dispatch
from .common import add_json, add_scene, emit


def register(sub) -> None:
    """Register the command."""
    p = sub.add_parser("kv", help="dynamic-load factor Kv (inverse dynamics along prescribed motions)")
    add_scene(p)
    p.add_argument("--study", metavar="NAME",
                   help="run only this study, or a seed-mechanism study (default: every study of kind kv)")
    p.add_argument("--losses", choices=("directional", "none"), default="directional",
                   help="stage-loss model (default: directional efficiency)")
    add_json(p)
    p.set_defaults(run=run)


def _run_one(scene, study, args):
    if dispatch.handled(scene, study):
        return dispatch.run_mechanism(scene, study)
    if study.kind != "kv":
        raise SceneError(study.key("kind"), f"is {study.kind!r}; the kv command runs studies of kind 'kv'")
    return kv_study(scene, study, losses=args.losses, progress=not args.json and sys.stderr.isatty())


def run(args) -> int:
    """Run the command."""
    scene = load_scene(args.scene)
    if args.study:
        dispatch.require(scene, args.study)
        studies = [scene.studies.get(args.study, args.study)]
    else:
        studies = scene.studies_of_kind("kv")
        if not studies:
            raise SceneError("studies", f"the scene has no study of kind 'kv' (studies: {dispatch.available(scene)})")
    results = [_run_one(scene, s, args) for s in studies]
    names = [getattr(s, "name", s) for s in studies]
    dicts = [r.to_dict() if hasattr(r, "to_dict") else dict(r) for r in results]
    cases = [dict(c, study=n) for n, d in zip(names, dicts) for c in d.get("cases", [])]
    payload = {"scene": scene.name, "studies": dicts, "cases": cases}
    text = "\n\n".join(r.table() if hasattr(r, "table") else str(r) for r in results)
    emit(args, payload, f"Kv dynamic-load studies of {scene.name}\n{text}")
    return 0
