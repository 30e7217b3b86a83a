"""Report section on the exported controller: the coefficients the export writes."""

from __future__ import annotations

import json

from servo_toolkit import design, load_scene
from servo_toolkit.export import export
from servo_toolkit.report.builder import SECTIONS, run_section
from servo_toolkit.report.context import Context
from servo_toolkit.report.section import fmt

from .conftest import SCENES


def _section(name):
    key, title, builder = next(s for s in SECTIONS if s[0] == "export")
    return run_section(key, title, builder, Context(load_scene(SCENES / name)))


def test_section_lists_the_exported_coefficients():
    section = _section("ema_reference.toml")
    assert section.status == "info" and section.key == "export"
    scene = load_scene(SCENES / "ema_reference.toml")
    data = json.loads(export(design(scene, progress=False), scene).files["controller.json"])
    for block in data["blocks"]["position"] + [data["blocks"]["speed"]]:
        for v in block["b"] + block["a"][1:]:
            assert fmt(v, 10) in section.html
    assert "q31" in section.html and "q15" in section.html


def test_section_does_not_apply_without_a_sample_time():
    section = _section("cam_follower.toml")
    assert section.status == "n/a" and "sample time" in section.reason
    assert _section("deflection_platform.toml").status == "n/a"
