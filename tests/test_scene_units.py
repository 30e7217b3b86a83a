"""Every quantity string of the reference scenes, converted independently with pint, equals
the value the loaded components hold (read back through their attributes)."""

import re
import tomllib

import numpy as np
import pint
import pytest

from servo_toolkit import load_scene

from .conftest import SCENES

#: the four scenes built from the seed papers (also in the shared scenes folder)
SEED_SCENES = ("cam_follower", "deflection_platform", "ema_reference", "roller_screw_two_stage")
ALL_SCENES = tuple(sorted(p.stem for p in SCENES.glob("*.toml")))
UREG = pint.UnitRegistry()  # a registry of the test's own, not the toolkit's
_STARTS_WITH_NUMBER = re.compile(r"^\s*[-+]?(\d|\.\d)")
#: scene key -> attribute name where they differ
_ALIAS = {"inertia": "inertias", "stroke": "stroke_range"}


def quantity_strings(data, path=()):
    """(key path, text) of every string that starts with a number."""
    if isinstance(data, dict):
        for k, v in data.items():
            if path or k not in ("name", "description"):  # free text, never parsed
                yield from quantity_strings(v, path + (k,))
    elif isinstance(data, list):
        for i, v in enumerate(data):
            yield from quantity_strings(v, path + (i,))
    elif isinstance(data, str) and _STARTS_WITH_NUMBER.match(data):
        yield path, data


def expected_si(text: str) -> float:
    """pint's own parse of the whole string, in SI base units (dB levels stay numbers)."""
    number, _, unit = text.strip().partition(" ")
    if unit.strip() == "dB":
        assert UREG.Unit("dB") == UREG.decibel
        return float(number)
    if UREG.Unit(unit.strip()).is_compatible_with("K") and unit.strip() not in ("K", "kelvin"):
        return float(UREG.Quantity(float(number), unit.strip()).to_base_units().magnitude)  # degC: an offset unit
    return float(UREG.Quantity(text).to_base_units().magnitude)


def _index(value, rest):
    for r in rest:
        value = value[r]
    return value


def loaded_value(scene, path):
    """The loaded value at a scene key path, through the component attributes."""
    head, *rest = path
    if head == "motor":
        return _index(getattr(scene.motor, rest[0]), rest[1:])
    if head == "drivetrain":
        stage = scene.stages[rest[0]]
        if rest[1] == "stages":  # [[drivetrain.stages]] of a roller screw
            return _index(getattr(stage.stages[rest[2]], rest[3]), rest[4:])
        return _index(getattr(stage, _ALIAS.get(rest[1], rest[1])), rest[2:])
    if head == "stages":
        return _index(getattr(scene.roller_screw[rest[0]], rest[1]), rest[2:])
    if head == "mechanism":
        mech = scene.mechanism
        if rest[0] == "platform_inertia":
            return mech.platform_inertia[rest[1], rest[2]]
        return mech.inertias[rest[0]] if rest[0] in mech.inertias else getattr(mech, rest[0])
    if head == "studies":
        return _index(scene.studies[rest[0]].params[rest[1]], rest[2:])
    if head == "duty_cycle" and rest[0] in ("segments", "motors"):
        item = getattr(scene.duty_cycle, rest[0])[rest[1]]
        return _index(getattr(item if rest[0] == "segments" else item[1], rest[2]), rest[3:])
    return _index(getattr(getattr(scene, head), rest[0]), rest[1:])


def cases(names):
    out = []
    for name in names:
        data = tomllib.loads((SCENES / f"{name}.toml").read_text())
        out += [(name, path, text) for path, text in quantity_strings(data)]
    return out


SEED_CASES = cases(SEED_SCENES)


def test_every_seed_scene_quantity_is_checked():
    # 19 + 24 + 54 + 27 quantity strings in the four seed scenes (the platform's
    # description, "2-DOF ...", starts with a digit but is free text)
    assert len(SEED_CASES) == 124
    assert {name for name, _, _ in SEED_CASES} == set(SEED_SCENES)


@pytest.fixture(scope="module")
def scenes():
    return {name: load_scene(SCENES / f"{name}.toml") for name in ALL_SCENES}


@pytest.mark.parametrize("name, path, text", cases(ALL_SCENES),
                         ids=lambda v: ".".join(map(str, v)) if isinstance(v, tuple) else str(v))
def test_quantity_matches_pint(scenes, name, path, text):
    got = loaded_value(scenes[name], path)
    assert float(got) == pytest.approx(expected_si(text), rel=1e-12, abs=1e-300), (name, path, text)


def test_representative_values_in_si(scenes):
    """A few by hand, so that a shared mistake of pint and the walk would show."""
    ema, cam, plat = scenes["ema_reference"], scenes["cam_follower"], scenes["deflection_platform"]
    assert ema.motor.inductance == pytest.approx(0.5e-3)
    assert ema.stages[0].backlash == pytest.approx(0.10 * np.pi / 180)
    assert ema.stages[1].backlash == pytest.approx(10e-6)
    assert ema.stages[3].stiffness == pytest.approx(1696.8 * 180 / np.pi)
    assert ema.requirements.min_gain_margin == 6.0
    assert ema.requirements.bandwidth == 8.0
    assert cam.motor.torque_constant == pytest.approx(0.015 * 9.80665)
    assert plat.mechanism.platform_inertia[1, 1] == pytest.approx(12600.333e-6)
    assert scenes["roller_screw_two_stage"].roller_screw[1].screw_spline_radius == pytest.approx(12.25e-3)


# -- unit slips: an angle where a number is expected, Kt and Ke in disagreement --------------

def _edited(**edits):
    from .conftest import build, variant
    data = tomllib.loads((SCENES / "ema_reference.toml").read_text())
    return build(variant(data, **edits))


@pytest.mark.parametrize("edits, key", [
    ({"drivetrain__0__teeth": None, "drivetrain__0__inertia": "1e-5 kg*m^2", "drivetrain__0__ratio": "3 deg"},
     "drivetrain[0].ratio"),
    ({"drivetrain__0__teeth": None, "drivetrain__0__inertia": "1e-5 kg*m^2", "drivetrain__0__ratio": "1 rad"},
     "drivetrain[0].ratio"),
    ({"drivetrain__0__efficiency": "1 rad"}, "drivetrain[0].efficiency"),
    ({"drivetrain__1__efficiency": "0.9 turn"}, "drivetrain[1].efficiency"),
])
def test_an_angle_is_no_dimensionless_number(edits, key):
    from servo_toolkit.errors import SceneError
    with pytest.raises(SceneError, match="expected a dimensionless number, got an angle") as info:
        _edited(**edits)
    assert info.value.key == key


def test_a_percentage_is_still_a_number():
    assert _edited(drivetrain__0__efficiency="97 %").stages[0].efficiency == pytest.approx(0.97)


@pytest.mark.parametrize("kt, ke, slip", [
    ("2 N*m/A", "0.002 V*s/rad", "milli prefix"),
    ("0.2 N*m/A", "20.94 V*s/rad", "V/krpm"),
    ("0.2 N*m/A", "0.02094 V*s/rad", "V/rpm"),
    ("0.2 N*m/A", "0.3 V*s/rad", ""),
])
def test_kt_and_ke_of_a_dc_motor_must_agree(kt, ke, slip):
    from servo_toolkit.errors import SceneError
    with pytest.raises(SceneError, match="must equal torque_constant within 10%") as info:
        _edited(motor__torque_constant=kt, motor__back_emf_constant=ke)
    assert info.value.key == "motor.back_emf_constant" and slip in info.value.rule


def test_shipped_motors_keep_loading_with_their_datasheet_kt_and_ke():
    cam = load_scene(SCENES / "cam_follower.toml")  # 0.1471 N*m/A against 0.146 V*s/rad
    assert cam.motor.back_emf_constant == pytest.approx(0.146)
    assert _edited(motor__back_emf_constant="0.19 V*s/rad").motor.back_emf_constant == pytest.approx(0.19)
