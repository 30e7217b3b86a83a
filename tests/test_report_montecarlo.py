"""The report's nonlinear Monte Carlo section: its worst variants and requirement rows
against the result's own figures and against each worst variant run again by the single-run
loop; it does not apply without ``[robustness]``."""

from __future__ import annotations

import math
import re
import tomllib

import numpy as np
import pytest

from servo_toolkit import load_scene
from servo_toolkit.report.builder import SECTIONS
from servo_toolkit.report.context import Context
from servo_toolkit.report.section import NotApplicable
from servo_toolkit.report.sections_requirements import requirement_rows
from servo_toolkit.report.sections_montecarlo import WORST, montecarlo_results, montecarlo_section
from servo_toolkit.scene.loader import scene_from_dict

from .conftest import SCENES


def _context(**robustness):
    data = tomllib.loads((SCENES / "ema_robust.toml").read_text())
    data["robustness"].update({"samples": 16, **robustness})
    return Context(scene_from_dict(data, "ema_robust.toml"))


@pytest.fixture(scope="module")
def bounded():
    """Bounds on either side of what the variants reach: tracking error fails, current passes."""
    return _context(max_tracking_error="0.5 deg", max_peak_current="200 A")


def test_worst_variants_and_requirements(bounded):
    section = montecarlo_section(bounded)
    result, checks = montecarlo_results(bounded)
    assert section.key == "montecarlo" and len(section.figures) == 1
    assert not result.failed.any() and result.count == 16
    # the worst rows are the largest tracking errors, in order
    listed = [int(i) for i in re.findall(r"<td>#(\d+)</td>", section.html)]
    assert listed == list(np.argsort(result.error_display)[::-1][:WORST])
    # each worst variant run again with every step recorded reaches the batched figures
    for i in listed[:1]:
        tr = result.trace(i)
        err = np.max(np.abs(tr.output_angle - tr.reference_angle))
        assert math.degrees(err) == pytest.approx(result.error_display[i], rel=1e-9)
        assert np.max(np.abs(tr.motor_current)) == pytest.approx(result.peak_current[i], rel=1e-9)
    by_name = {c.name: c for c in checks}
    worst_err = float(np.max(result.error_display))
    assert by_name["tracking_error"].achieved == pytest.approx(worst_err) and not by_name["tracking_error"].passed
    assert by_name["peak_current"].passed and worst_err > 0.5
    assert section.status == "fail" and "not judged" not in section.html
    rows = [r for r in requirement_rows(bounded) if "nonlinear time runs" in r.detail]
    assert [(r.id, r.status) for r in rows] == [("robust_tracking_error", "fail"), ("robust_peak_current", "pass")]
    assert rows[0].achieved == f"{worst_err:.4g} deg"


def test_without_monte_carlo_bounds_the_section_informs_and_adds_no_row():
    c = _context(samples=8)
    section = montecarlo_section(c)
    assert section.status == "info"
    assert "the variants are shown here, not judged" in section.html and "nominal actuator alone" in section.html
    assert not [r for r in requirement_rows(c) if "nonlinear time runs" in r.detail]


def test_does_not_apply_without_variations():
    with pytest.raises(NotApplicable, match="robustness"):
        montecarlo_section(Context(load_scene()))
    assert "montecarlo" in [key for key, _, _ in SECTIONS]
