"""The report's section on control that uses the model: the tracking error with and without
feedforward at operating points along the stroke, the schedule's crossover, the shapers."""

from __future__ import annotations

import re

from servo_toolkit.report.builder import SECTIONS, run_section
from servo_toolkit.report.context import Context
from servo_toolkit.scene.loader import load_scene

from .conftest import SCENES


def test_command_section_on_the_reference_ema():
    scene = load_scene(SCENES / "ema_reference.toml")
    key, title, builder = next(s for s in SECTIONS if s[0] == "command")
    sec = run_section(key, title, builder, Context(scene, light=True))
    assert sec.status == "info", sec.reason
    assert len(sec.figures) == 1
    body = sec.html.split('id="feedforward-table"')[1].split("</table>")[0]
    assert body.count("<tr>") == 1 + 3  # three operating points along the stroke
    gains = [float(x) for x in re.findall(r">([0-9.]+)x<", body)]
    assert len(gains) == 3 and min(gains) >= 5.0  # the 5x, at every operating point
    assert "ZV shaper" in sec.html and "crossover spread" in sec.html
