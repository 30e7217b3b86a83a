"""Every output takes its stroke from the scene: a ``stroke`` on the stage that drives the
output (a ball screw's nut travel, a gear's output angle, as on a linkage or a roller screw);
without one, the design's notes say the stroke is a default and which key sets it."""

import math

import pytest

from servo_toolkit import SceneError
from servo_toolkit.loop.design import design

from .conftest import build, variant


@pytest.fixture
def carriage(ema_dict):
    """The reference EMA's gear and ball screw driving a 20 kg carriage (an output travel)."""
    data = variant(ema_dict)
    data["drivetrain"] = data["drivetrain"][:2]
    data["load"] = {"inertia": "20 kg"}
    data["sensors"] = {**data["sensors"], "output_encoder_bits": 0, "output_scale_resolution": "1 um"}
    for key in ("studies", "robustness"):
        data.pop(key, None)
    return data


def test_a_ball_screw_takes_the_stroke_of_its_nut(carriage):
    carriage["drivetrain"][1]["stroke"] = ["-20 mm", "30 mm"]
    dt = build(carriage).drivetrain
    assert dt.stroke == pytest.approx((-0.02, 0.03))
    assert dt.mid_stroke == pytest.approx(0.005)
    assert dt.stroke_note is None


def test_a_gear_driving_the_output_takes_the_stroke_of_its_shaft(ema_dict):
    data = variant(ema_dict)
    data["drivetrain"] = data["drivetrain"][:1]
    data["drivetrain"][0]["stroke"] = ["-90 deg", "90 deg"]
    for key in ("studies", "robustness"):
        data.pop(key, None)
    assert build(data).drivetrain.stroke == pytest.approx((-math.pi / 2, math.pi / 2))


@pytest.mark.parametrize("stroke, rule", [(["30 mm", "-20 mm"], "lowest < highest"),
                                          (["-20 mm"], "lowest < highest"),
                                          (["-20 deg", "20 deg"], "an angle where"), (["1 kg", "2 kg"], "dimension mismatch")])
def test_a_bad_stroke_is_refused_naming_the_key(carriage, stroke, rule):
    carriage["drivetrain"][1]["stroke"] = stroke
    with pytest.raises(SceneError, match=rule) as info:
        build(carriage)
    assert info.value.key.startswith("drivetrain[1].stroke")


def test_a_stroke_on_a_stage_that_does_not_drive_the_output_is_refused(carriage):
    carriage["drivetrain"][0]["stroke"] = ["-20 deg", "20 deg"]
    with pytest.raises(SceneError, match=r"give it on the stage that drives the output, drivetrain\[1\]") as info:
        build(carriage)
    assert info.value.key == "drivetrain[0].stroke"


def test_the_design_says_where_a_default_stroke_came_from(carriage):
    notes = design(build(carriage)).notes
    assert ("stroke -50 mm .. 50 mm: the default for an output travel (the scene gives none; set it with "
            "stroke = [lowest, highest] on drivetrain[1])") in notes
    carriage["drivetrain"][1]["stroke"] = ["-20 mm", "30 mm"]
    given = design(build(carriage))
    assert not any(n.startswith("stroke ") for n in given.notes)
    assert given.stroke.q.min() == pytest.approx(-0.02) and given.stroke.q.max() == pytest.approx(0.03)
