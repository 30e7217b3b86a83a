"""``servo-toolkit stiffness``: the stiffness chain at the output, per angle or position.

A rotary output takes ``--angle DEG`` (default -30 0 10 30), a linear output (a chain that
ends in a screw, q = nut travel) takes ``--position MM`` (default mid-stroke). A value that
is not finite, outside the drivetrain's stroke, or of the wrong kind exits 2.
"""

from __future__ import annotations

from .common import add_json, add_scene, emit, load_scene


def register(sub) -> None:
    """Register the command."""
    p = sub.add_parser("stiffness", help="series stiffness chain and compliance shares")
    add_scene(p)
    p.add_argument("--angle", type=float, action="append", metavar="DEG",
                   help="output angle in deg, rotary outputs (repeatable; default -30 0 10 30 when they lie in the stroke, else its ends and middle)")
    p.add_argument("--position", type=float, action="append", metavar="MM",
                   help="output travel in mm, linear outputs (repeatable; default mid-stroke)")
    add_json(p)
    p.set_defaults(run=run)


def run(args) -> int:
    """Run the command."""
    from ..studies.stiffness import stiffness_study
    scene = load_scene(args.scene)
    result = stiffness_study(scene, args.angle, args.position)
    emit(args, result, f"Stiffness chain of {scene.name}, referred to the output\n" + result.table())
    return 0
