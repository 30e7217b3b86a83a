"""The output's sensor is of the output's dimension: an encoder's 2**bits counts per revolution
of an output angle, a linear scale's length per count along an output travel; the other one
is refused naming its key (never 2 pi / 2**bits read as metres)."""

from __future__ import annotations

import json
import math
import tomllib

import numpy as np
import pytest

from servo_toolkit import SceneError
from servo_toolkit.cli import main
from servo_toolkit.scene.template import scene_template
from servo_toolkit.sim import ModelOptions, Reference, build_model, default_controller
from servo_toolkit.sim import layout as lo
from servo_toolkit.sim.kernel import controller_sample
from servo_toolkit.sim.reference import fill, initial_state

from .conftest import build, variant

TRAVEL = tomllib.loads(scene_template("travel", "carriage"))
ANGLE = tomllib.loads(scene_template("angle", "shaft"))


def test_the_travel_scene_new_writes_reads_the_carriage_with_a_linear_scale():
    scene = build(TRAVEL)
    assert scene.drivetrain.output_unit == "m"
    assert scene.sensors.output_scale_resolution == pytest.approx(1e-6)
    assert scene.sensors.output_count(linear=True) == pytest.approx(1e-6)
    model = build_model(scene, default_controller(scene))
    assert model.parameters()[lo.LSB] == pytest.approx(1e-6)
    assert any("counts of 0.001 mm" in n and "linear scale" in n for n in model.notes), model.notes


def test_an_output_angle_keeps_its_encoder_counts_per_revolution():
    scene = build(ANGLE)
    model = build_model(scene, default_controller(scene))
    assert model.parameters()[lo.LSB] == pytest.approx(2 * math.pi / 2**16)
    assert any("16 bits per revolution" in n for n in model.notes), model.notes
    unquantized = build_model(scene, default_controller(scene), ModelOptions(quantization=False))
    assert unquantized.parameters()[lo.LSB] == 0.0
    assert not any("counts of" in n for n in unquantized.notes)


@pytest.mark.parametrize("data, edits, key, hint", [
    (TRAVEL, {"sensors__output_scale_resolution": None, "sensors__output_encoder_bits": 16},
     "sensors.output_encoder_bits", "output_scale_resolution"),
    (TRAVEL, {"sensors__output_encoder_bits": 16}, "sensors.output_encoder_bits", "output_scale_resolution"),
    (ANGLE, {"sensors__output_scale_resolution": "1 um"}, "sensors.output_scale_resolution",
     "output_encoder_bits"),
])
def test_a_sensor_of_the_other_dimension_is_refused_naming_its_key(data, edits, key, hint):
    with pytest.raises(SceneError) as info:
        build(variant(data, **edits))
    assert info.value.key == key
    assert hint in str(info.value) and "\n" not in str(info.value)


def test_zero_reads_the_output_ideally_in_either_dimension():
    travel = build(variant(TRAVEL, sensors__output_scale_resolution=None, sensors__output_encoder_bits=0))
    assert travel.sensors.output_count(linear=True) == 0.0
    assert build_model(travel, default_controller(travel)).parameters()[lo.LSB] == 0.0
    angle = build(variant(ANGLE, sensors__output_scale_resolution="0 m"))
    assert angle.sensors.output_count(linear=False) == pytest.approx(2 * math.pi / 2**16)


def test_the_sampled_controller_sees_the_travel_on_the_scale_grid():
    """1 um scale: every travel within half a count of a grid point gives the same controller
    update, the next count another one (an encoder's 2 pi / 2**16 = 96 um read as metres
    would give one update over all of them)."""
    scene = build(TRAVEL)
    lsb = 1e-6
    model = build_model(scene, default_controller(scene))
    P = fill(model, Reference(offset=0.0))
    x0 = initial_state(model, P)
    k = 20
    irefs = []
    for frac in (-0.49, 0.0, 0.49, 1.0, 2.0, 5.0):
        x = x0.copy()
        x[2] = (k + frac) * lsb
        irefs.append(controller_sample(0.0, x, P, model.T, np.empty(model.nx)))
    assert irefs[0] == irefs[1] == irefs[2]
    assert len(set(irefs[2:])) == 4


def test_check_refuses_an_encoder_on_a_travel_with_one_line(tmp_path, capsys):
    text = scene_template("travel", "carriage").replace(
        'output_scale_resolution = "1 um"', "output_encoder_bits = 16")
    path = tmp_path / "carriage.toml"
    path.write_text(text)
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "sensors.output_encoder_bits" in err[0] and "output_scale_resolution" in err[0]


def test_reduce_counts_the_lost_motion_in_the_scale_s_counts(tmp_path, capsys):
    """The ball screw's 10 um lash (10.7 um at the output with the gear's) is 10.7 counts of
    the 1 um scale."""
    path = tmp_path / "carriage.toml"
    path.write_text(scene_template("travel", "carriage"))
    assert main(["reduce", str(path), "--study", "sine", "--estimate-only", "--json"]) == 0
    effect = next(e for e in json.loads(capsys.readouterr().out)["effects"] if e["effect"] == "backlash")
    play = build(TRAVEL).drivetrain.backlash([0.0])[0]
    assert f"{play / 1e-6:.3g} scale counts" in effect["quantity"]
