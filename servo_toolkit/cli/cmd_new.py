"""``servo-toolkit new SCENE.toml --output angle|travel``: a commented scene to start from.

Every section, the keys a motor-driven actuator needs with their units and typical values,
the optional keys commented out (:mod:`servo_toolkit.scene.template`); the file loads and
passes ``check`` as written. An existing file is never overwritten (exit 2); the file is
written atomically.
"""

from __future__ import annotations

import sys
from pathlib import Path

from ..errors import SceneError

#: the outputs a starting scene can have: those of :data:`servo_toolkit.scene.template.OUTPUTS`
#: (whose package loads the scene reader and its unit parser; the parser is built without them)
OUTPUTS = ("angle", "travel")


def register(sub) -> None:
    """Register the command."""
    p = sub.add_parser("new", help="write a commented scene to start from (an output angle or travel)")
    p.add_argument("scene", help="the scene file to write (.toml; never an existing file)")
    p.add_argument("--output", choices=OUTPUTS, default="angle",
                   help="the actuator's output: 'angle' a gearmotor turning an output shaft (default), 'travel' "
                        "a gearmotor driving a ball screw and a carriage")
    p.set_defaults(run=run)


def _refuse_existing(path: Path) -> None:
    if path.exists() or path.is_symlink():
        raise SceneError("SCENE", f"{path} exists: new never overwrites a file; give another name")


def run(args) -> int:
    """Run the command."""
    from ..core.files import check_output_file, write_text
    from ..scene.template import scene_template
    path = Path(args.scene)
    _refuse_existing(path)
    check_output_file(path, "SCENE", suffixes=(".toml",))
    text = scene_template(args.output, name=path.stem, file=path.name)
    write_text(path, text, "SCENE", check=lambda _: _refuse_existing(path))  # a file made meanwhile stays
    print(f"scene written to {path}: edit it, then servo-toolkit check {path}", file=sys.stderr)
    return 0
