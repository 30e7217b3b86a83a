"""Names that say what they mean: one module owns the angle conversions."""

from __future__ import annotations

import ast
import math
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "servo_toolkit"


def _module_constants(path):
    tree = ast.parse(path.read_text(encoding="utf-8"))
    for node in tree.body:
        if isinstance(node, ast.Assign) and all(isinstance(t, ast.Name) for t in node.targets):
            try:
                value = eval(compile(ast.Expression(node.value), str(path), "eval"), {"math": math})  # noqa: S307
            except Exception:
                continue
            if isinstance(value, float):
                yield node.targets[0].id, value


def test_angle_conversions_are_defined_once():
    """A module-level 180/pi or pi/180 lives in core/angles.py only (the name DEG once meant
    either, in different modules)."""
    found = [(str(p.relative_to(PACKAGE)), name) for p in PACKAGE.rglob("*.py") if p.name != "angles.py"
             for name, v in _module_constants(p)
             if math.isclose(v, 180 / math.pi) or math.isclose(v, math.pi / 180)]
    assert found == []


def test_the_conversions_go_the_way_their_names_say():
    from servo_toolkit.core.angles import DEG_PER_RAD, RAD_PER_DEG
    assert math.isclose(math.pi * DEG_PER_RAD, 180.0) and math.isclose(180.0 * RAD_PER_DEG, math.pi)
