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


def test_each_stage_carries_its_own_facts_and_they_agree():
    """A stage's kind, what it takes and gives, its coordinates' units, ratio keys and report
    units live on its class; what it gives (rotary or travel) is the unit of its output
    coordinate (rad or m), and a key it displays in its own unit is one of its fields."""
    import dataclasses

    from servo_toolkit.components.base import Stage
    from servo_toolkit.components.stages import STAGE_IO, STAGE_KINDS, STAGES
    assert len(STAGE_KINDS) == len(STAGES) and all(issubclass(c, Stage) and c.KIND for c in STAGES)
    unit_of = {"rotary": "rad", "travel": "m", None: None}
    for cls in STAGES:
        take, give = STAGE_IO[cls.KIND]
        assert (unit_of[take], unit_of[give]) == cls.UNITS[:2], cls.__name__
        fields = {f.name for f in dataclasses.fields(cls)}
        assert all(name in fields for name, _, _ in cls.DISPLAY_UNITS), cls.__name__
        assert cls.RATIO_KEYS is None or cls.RATIO_KEYS.split("/")[0].split("[")[0].split(",")[0] in fields | {"stages"}


def test_dt_is_a_time_step_never_the_drivetrain():
    """``dt`` always means a time step (the architecture page's names): no name ``dt`` is
    bound to a drivetrain."""
    import re
    bound = re.compile(r"\bdt\b[^=\n]*=\s*[\w.]*drivetrain\b|\bdt\s*:\s*Drivetrain|, dt = [\w.]+, [\w.]*drivetrain\b")
    found = [f"{p.relative_to(PACKAGE)}:{i}" for p in PACKAGE.rglob("*.py")
             for i, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1) if bound.search(line)]
    assert found == []
