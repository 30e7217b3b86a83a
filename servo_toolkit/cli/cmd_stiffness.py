"""``servo-toolkit stiffness``: the stiffness chain at the output, per angle."""

from __future__ import annotations

from ..scene import load_scene
from ..studies.stiffness import DEFAULT_ANGLES_DEG, stiffness_study
from .common import add_json, add_scene, emit


def register(sub) -> None:
    """Register the command."""
    p = sub.add_parser("stiffness", help="series stiffness chain and compliance shares")
    add_scene(p)
    p.add_argument("--angle", type=float, action="append", metavar="DEG",
                   help="output angle in deg (repeatable; default -30 0 10 30)")
    add_json(p)
    p.set_defaults(run=run)


def run(args) -> int:
    """Run the command."""
    scene = load_scene(args.scene)
    result = stiffness_study(scene, args.angle or DEFAULT_ANGLES_DEG)
    emit(args, result, f"Stiffness chain of {scene.name}, referred to the output\n" + result.table())
    return 0
