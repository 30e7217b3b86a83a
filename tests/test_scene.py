"""Scene loading: the reference scenes load unchanged; every rule gives a SceneError."""

import math
import tomllib
from pathlib import Path

import pytest

from servo_toolkit import SceneError, load_scene
from servo_toolkit.components.platform.geometry import CrossedArchPlatform
from servo_toolkit.scene.loader import default_scene_path

from .conftest import SCENE_FILES, SCENES, build, variant

SHARED = Path(__file__).resolve().parents[2] / "shared" / "scenes"


@pytest.mark.parametrize("path", SCENE_FILES, ids=lambda p: p.stem)
def test_reference_scenes_load(path):
    scene = load_scene(path)
    assert scene.name == path.stem


@pytest.mark.skipif(not SHARED.is_dir(), reason="shared scenes not beside the checkout")
@pytest.mark.parametrize("path", [p for p in SCENE_FILES if (SHARED / p.name).exists()] or SCENE_FILES,
                         ids=lambda p: p.stem)
def test_scenes_are_unchanged_copies(path):  # the reference scenes; example scenes may be added
    assert path.read_bytes() == (SHARED / path.name).read_bytes()


def test_builtin_default_is_the_reference_ema():
    assert default_scene_path().read_bytes() == (SCENES / "ema_reference.toml").read_bytes()
    assert load_scene().name == "ema_reference"


def test_every_quantity_of_the_ema_in_si():
    s = load_scene(SCENES / "ema_reference.toml")
    m = s.motor
    assert (m.resistance, m.inductance, m.torque_constant) == (0.5, pytest.approx(5e-4), 0.2)
    assert m.voltage_limit == 270 and m.current_limit == 60
    gear, screw, link, housing = s.stages
    assert gear.ratio == pytest.approx(52 / 24)
    assert gear.backlash == pytest.approx(math.radians(0.1))
    assert screw.lead == pytest.approx(5e-3) and screw.backlash == pytest.approx(1e-5)
    assert link.arm_length == pytest.approx(0.051) and link.stroke == pytest.approx((-math.pi / 6, math.pi / 6))
    assert housing.stiffness == pytest.approx(1696.8 * 180 / math.pi)
    assert s.sensors.sample_time == pytest.approx(1e-4) and s.sensors.output_encoder_bits == 16
    r = s.requirements
    assert r.bandwidth == 8 and r.min_gain_margin == 6 and r.min_phase_margin == pytest.approx(math.pi / 4)
    assert s.study("kv_8hz").get("frequency") == 8.0
    assert s.study("kv_stroke").get("load_inertias") == [0, 1, 2, 4]


def test_cam_platform_roller_screw_quantities():
    cam = load_scene(SCENES / "cam_follower.toml")
    assert cam.motor.torque_constant == pytest.approx(0.1471, rel=1e-3)
    assert cam.stages[0].profile_constant == pytest.approx(0.035)
    plat = load_scene(SCENES / "deflection_platform.toml").mechanism
    assert isinstance(plat, CrossedArchPlatform)
    assert plat.platform_inertia[1, 1] == pytest.approx(12600.333e-6)
    rs = load_scene(SCENES / "roller_screw_two_stage.toml")
    assert rs.roller_screw[1].screw_spline_radius == pytest.approx(12.25e-3)
    assert rs.operating.nut_screw_friction == (0.005, 0.055, 0.105)


@pytest.mark.parametrize("edit, key, rule", [
    ({"drivetrain__2__rod_mass": "-0.15 kg"}, "drivetrain[2].rod_mass", "must not be negative"),
    ({"drivetrain__1__lead": "0 mm"}, "drivetrain[1].lead", "must be positive"),
    ({"drivetrain__2__rod_length": "5 mm"}, "drivetrain[2].rod_length", "rod too short"),
    ({"motor__resistance": float("nan")}, "motor.resistance", "NaN"),
    ({"motor__torque_constant": None}, "motor.torque_constant", "missing key"),
    ({"motor__inductance": "0.5 mFoo"}, "motor.inductance", "unknown unit"),
    ({"drivetrain__1__lead": "5 kg"}, "drivetrain[1].lead", "dimension mismatch"),
    ({"drivetrain__0__efficiency": 1.2}, "drivetrain[0].efficiency", r"\[0.01, 1\]"),
    ({"drivetrain__0__kind": "belt"}, "drivetrain[0].kind", "unknown stage kind"),
    ({"drivetrain__1__leed": "5 mm"}, "drivetrain[1].leed", "unknown key"),
    ({"load__inertia": "-1 kg*m^2"}, "load.inertia", "must not be negative"),
    ({"sensors__output_encoder_bits": -3}, "sensors.output_encoder_bits", "at least 0"),
    ({"studies__sweep__kind": "magic"}, "studies.sweep.kind", "must be one of"),
    ({"drivetrain__0__teeth": [24, 0, 52]}, "drivetrain[0].teeth[1]", "positive integer"),
    ({"drivetrain__0__inertia": ["1 kg*m^2"]}, "drivetrain[0].inertia", "one inertia per gear"),
])
def test_rules(ema_dict, edit, key, rule):
    with pytest.raises(SceneError, match=rule) as info:
        build(variant(ema_dict, **edit))
    assert info.value.key == key
    assert key in str(info.value)


def test_printed_platform_inertia_is_rejected():
    data = tomllib.loads((SCENES / "deflection_platform.toml").read_text())
    data["mechanism"]["platform_inertia"] = [["10688.89 kg*mm^2", "-46826.13 kg*mm^2"],
                                             ["-46826.13 kg*mm^2", "12600.333 kg*mm^2"]]
    with pytest.raises(SceneError, match="not positive definite") as info:
        build(data)
    assert info.value.key == "mechanism.platform_inertia"


def test_indefinite_drivetrain_inertia_is_rejected(ema_dict):
    # Components refuse negative inertias on their own, however they are made; the
    # drivetrain check is the last line of defence for a description whose field was set
    # behind the dataclass's back (here a negative load inertia).
    from dataclasses import replace

    scene = build(ema_dict)
    with pytest.raises(SceneError, match="load.inertia: must not be negative"):
        replace(scene.load, inertia=-100.0)
    load = replace(scene.load)
    object.__setattr__(load, "inertia", -100.0)
    bad = replace(scene, load=load)
    with pytest.raises(SceneError, match="indefinite"):
        bad.drivetrain.check()


def test_missing_file_and_bad_toml(tmp_path):
    with pytest.raises(SceneError, match="cannot read"):
        load_scene(tmp_path / "nope.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("name = \n")
    with pytest.raises(SceneError, match="not valid TOML"):
        load_scene(bad)


def test_scene_error_names_the_file(tmp_path):
    p = tmp_path / "s.toml"
    p.write_text((SCENES / "ema_reference.toml").read_text().replace('lead = "5 mm"', 'lead = "5 kg"'))
    with pytest.raises(SceneError) as info:
        load_scene(p)
    assert str(p) in str(info.value) and "drivetrain[1].lead" in str(info.value)


def test_speed_estimator_rules(ema_dict):
    """speed_estimator is one of the known names and needs motor counts and a sample time."""
    assert load_scene().sensors.speed_estimator == "ideal"
    with pytest.raises(SceneError, match=r"sensors\.speed_estimator"):
        build(variant(ema_dict, sensors__speed_estimator="magic"))
    with pytest.raises(SceneError, match=r"sensors\.speed_estimator.*sample_time"):
        build(variant(ema_dict, sensors__speed_estimator="kalman", sensors__sample_time=0))
    scene = build(variant(ema_dict, sensors__speed_estimator="kalman"))
    assert scene.sensors.speed_estimator == "kalman"
