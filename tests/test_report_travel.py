"""The report of a scene whose output is a travel (a ball screw driving a carriage): every
output figure in mm or m, never an angle."""

from __future__ import annotations

import html as _html
import re
import tomllib

import pytest

from servo_toolkit import load_scene
from servo_toolkit.scene.loader import scene_from_dict
from servo_toolkit.report import run_section
from servo_toolkit.report.context import Context

from .carriage_scene import carriage_scene

#: the carriage with a small Kv study
TRAVEL_SCENE = carriage_scene(extra='''
[studies.kv_small]
kind = "kv"
trajectory = "sine"
frequency = "5 Hz"
amplitudes = ["1 mm"]
load_inertias = ["0 kg", "15 kg"]
''')


@pytest.fixture(scope="module")
def travel(tmp_path_factory):
    path = tmp_path_factory.mktemp("travel") / "carriage.toml"
    path.write_text(TRAVEL_SCENE)
    scene = load_scene(path)
    assert scene.drivetrain.output_is_linear
    return scene


@pytest.fixture(scope="module")
def ctx(travel):
    return Context(travel)


def _section(ctx, key):
    """The report's section ``key`` alone, built as the report builds it."""
    from servo_toolkit.report.builder import sections_of
    key_, title, builder = next(s for s in sections_of(None, ctx.scene) if s[0] == key)
    section = run_section(key_, title, builder, ctx)
    assert section.status not in ("unavailable", "n/a"), section.reason
    return section


def plain(html: str) -> str:
    """The text of an HTML fragment."""
    return _html.unescape(re.sub(r"<[^>]+>", " ", html))


def _rows(html: str) -> list[tuple[str, ...]]:
    """The table rows of a section's HTML, each cell as text."""
    return [tuple(plain(c).strip() for c in re.findall(r"<t[dh][^>]*>(.*?)</t[dh]>", row, re.S))
            for row in re.findall(r"<tr[^>]*>(.*?)</tr>", html, re.S)]


def test_solver_accuracy_runs_the_accuracy_command_default_for_a_travel(ctx, travel):
    """The section's sine is servo-toolkit accuracy's default, 1 mm at 8 Hz for a travel (not
    the 2 deg of an angle read as 34.9 mm), and its error is said to be one of the travel."""
    from servo_toolkit.studies.time.reference import run_spec
    section = _section(ctx, "accuracy")
    text = plain(section.html)
    default = run_spec(travel)[0]
    assert default.amplitude == pytest.approx(1e-3)
    assert "sine 1 mm at 8 Hz" in text and "34.9 mm" not in text
    assert "output travel" in text and "output-angle" not in text and "output angle" not in text
    assert "over the motion amplitude of 1 mm" in text


def test_scene_summary_shows_a_ball_screw_stroke_in_mm(ctx):
    """stroke = ["0 mm", "200 mm"] is shown as [0, 200] mm, not 0.2 rad read as 11.459 deg."""
    rows = _rows(_section(ctx, "scene").html)
    assert ("stroke_range", "[0, 200]", "mm") in rows
    assert not any(r[0] == "stroke_range" and r[2] == "deg" for r in rows)


def test_gear_stroke_stays_in_degrees():
    from servo_toolkit.components.gear import GearTrain
    from servo_toolkit.report.units_table import rows
    gear = GearTrain(name="g", ratio=10.0, stroke_range=(-0.5, 0.5))
    assert ("stroke_range", "[-28.648, 28.648]", "deg") in rows(gear)


def test_constant_series_stiffness_is_one_value(ctx, travel):
    """A ball screw's stiffness does not change along the stroke: one value, not a range
    from a value to the same value."""
    text = plain(_section(ctx, "stiffness").html)
    assert "runs from" not in text
    total = travel.drivetrain.stiffness([0.1]).total[0]
    from servo_toolkit.display.html import fmt
    assert f"the series stiffness is constant at {fmt(total)} N/m." in text


def test_varying_series_stiffness_is_a_range():
    from servo_toolkit.report.sections_drivetrain import _along_stroke
    assert _along_stroke("1.2e6", "1.2e6", "N/m", "+0 mm", "+200 mm") == \
        "Along the stroke the series stiffness is constant at 1.2e6 N/m."
    assert _along_stroke("1000", "2000", "N*m/rad", "-30 deg", "+30 deg") == \
        "Along the stroke the series stiffness runs from 1000 N*m/rad at -30 deg to 2000 N*m/rad at +30 deg."


def test_ratio_carries_its_unit(ctx, travel):
    """The plant table's ratio N is motor rad per output m (rad/m) for a travel, as the
    inertia section's row."""
    plant_rows = _rows(_section(ctx, "plant").html)
    n = float(travel.drivetrain.ratio([0.1])[0][0])
    row = next(r for r in plant_rows if r[0].startswith("ratio N"))
    assert row[0] == "ratio N (motor rad per output m)" and row[2] == "rad/m"
    assert float(row[1]) == pytest.approx(n, rel=1e-3)
    assert n == pytest.approx(5 * 2 * 3.141592653589793 / 0.01)
    inertia_rows = _rows(_section(ctx, "inertia").html)
    assert any(r[0] == row[0] and r[-1] == "rad/m" for r in inertia_rows)


def test_the_plant_names_the_two_mass_models_stiffness_beside_the_series_stiffness(ctx, travel):
    """The design plant's K is the two-mass reduction's (K = w_a^2 J2), not the springs' series
    stiffness: the screw's inertia between the gearhead's and the screw's springs takes part
    in the lowest modes, and the two differ by a factor 3.8 on the carriage."""
    import math
    import numpy as np
    from scipy import linalg
    from servo_toolkit.display.html import fmt
    from servo_toolkit.plant.linear import plant_parameters
    plant_rows = _rows(_section(ctx, "plant").html)
    text = plain(_section(ctx, "plant").html)
    p = plant_parameters(travel)
    series = float(travel.drivetrain.stiffness([p.q0]).total[0])
    labels = [r[0] for r in plant_rows]
    assert not any("series stiffness K" in lab for lab in labels)
    assert ["two-mass model's stiffness K = w_a^2 J2", fmt(p.K), "N/m"] in [list(r) for r in plant_rows]
    assert ["chain's series stiffness (stiffness chain)", fmt(series), "N/m"] in [list(r) for r in plant_rows]
    # the series stiffness is the springs' compliances summed; K differs from it
    k = travel.drivetrain.chain.spring_stiffness([p.q0])[:, 0]
    assert series == pytest.approx(1 / np.sum(1 / k), rel=1e-9)
    assert p.K / series == pytest.approx(3.8, abs=0.05)
    assert f"here it is {p.K / series:.3g} times it" in text
    # outside truth: the driving chain's lowest resonance (free) and anti-resonance (motor
    # node held) from its own matrices; the two-mass model with J1, J2, K has both, and K = w_a^2 J2
    M, Kc, _ = travel.drivetrain.chain.condensed(p.q0, True)
    w_r = math.sqrt(np.sort(linalg.eigh(Kc, M, eigvals_only=True))[1])
    w_a = math.sqrt(np.sort(linalg.eigh(Kc[1:, 1:], M[1:, 1:], eigvals_only=True))[0])
    assert p.J1 + p.J2 == pytest.approx(np.trace(M), rel=1e-9)
    assert math.sqrt(p.K * (1 / p.J1 + 1 / p.J2)) == pytest.approx(w_r, rel=1e-6)
    assert math.sqrt(p.K / p.J2) == pytest.approx(w_a, rel=1e-6)


def test_a_chain_with_one_compliance_has_the_series_stiffness_as_its_k(travel):
    """With the gearhead made rigid the screw's spring is the chain's one compliance: the
    two-mass model's K is the series stiffness and the text says so."""
    import math
    from servo_toolkit.plant.linear import plant_parameters
    from servo_toolkit.report.sections_drivetrain import two_mass_stiffness
    data = tomllib.loads(TRAVEL_SCENE)
    del data["drivetrain"][0]["torsional_stiffness"]
    one = scene_from_dict(data)
    p = plant_parameters(one)
    series = float(one.drivetrain.stiffness([p.q0]).total[0])
    assert math.isfinite(series) and p.K == pytest.approx(series, rel=1e-6)
    rows, text = two_mass_stiffness(one, p, True)
    assert rows[0][1] == rows[1][1] and "within 1 %" in text


def test_ratio_of_an_angle_output_is_per_output_rad():
    from servo_toolkit.report.sections_drivetrain import ratio_row
    assert ratio_row(False) == ("ratio N (motor rad per output rad)", "")


def test_kv_table_without_a_rod_shows_a_dash(ctx):
    """A chain without a rod has no rod force: "-" as servo-toolkit kv prints it, never None."""
    section = _section(ctx, "kv")
    rows = _rows(section.html)
    body = [r for r in rows if r and r[0] == "1"]
    assert body and all(r[-2:] == ("-", "-") for r in body)
    assert "None" not in plain(section.html)


def test_a_resonance_near_the_plots_end_keeps_its_label_within_the_axes(ctx):
    """The carriage's drivetrain resonance (hundreds of Hz, near the Bode plot's 1 kHz end):
    its label goes left of its line instead of running past the axes."""
    section = _section(ctx, "plant")
    assert section.status == "info", section.reason
    assert section.layout == (), section.layout
