"""Unit parsing at the scene boundary."""

import math

import pytest

from servo_toolkit import SceneError
from servo_toolkit.core.units import parse_quantity, parse_si


@pytest.mark.parametrize("text, unit, expected", [
    ("0.5 mH", "H", 5e-4),
    ("0.015 kgf*m/A", "N*m/A", 0.015 * 9.80665),
    ("1696.8 N*m/deg", "N*m/rad", 1696.8 * 180 / math.pi),
    ("6 dB", "dB", 6.0),
    ("2.0e-4 kg*m^2", "kg*m^2", 2e-4),
    ("12.25 kg*mm^2", "kg*m^2", 12.25e-6),
    ("0.146 V*s/rad", "V*s/rad", 0.146),
    ("10 um", "m", 1e-5),
    ("3 deg/s", "rad/s", math.radians(3)),
    ("8 Hz", "Hz", 8.0),
    (0.25, "m", 0.25),
])
def test_parse_quantity(text, unit, expected):
    assert parse_quantity(text, unit, "k") == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize("text, message", [
    ("5 kg", "dimension mismatch"),
    ("5 parsecs_per_foo", "unknown unit"),
    ("fast", "expected a number"),
])
def test_parse_errors_name_key(text, message):
    with pytest.raises(SceneError, match=message) as info:
        parse_quantity(text, "m", "drivetrain[1].lead")
    assert info.value.key == "drivetrain[1].lead"


@pytest.mark.parametrize("text, expected_hz", [
    ("100 rad/s", 100 / (2 * math.pi)),  # omega = 2 pi f
    ("60 rpm", 1.0),                      # one revolution per second
    ("360 deg/s", 1.0),
    ("1 kHz", 1000.0),
    ("10 1/s", 10.0),                     # cycles per second, as Hz
])
def test_an_angular_rate_given_for_a_frequency_is_divided_by_two_pi(text, expected_hz):
    assert parse_quantity(text, "Hz", "requirements.bandwidth") == pytest.approx(expected_hz, rel=1e-12)


def test_an_angular_rate_required_as_a_bandwidth_is_checked_in_hz():
    from servo_toolkit.loop.requirements import parse_override
    assert parse_override("bandwidth=100 rad/s") == ("bandwidth", pytest.approx(15.915494309189533))


@pytest.mark.parametrize("text", ["50 %", "0.5 percent", "3 ppm"])
def test_a_ratio_is_not_an_angle(text):
    with pytest.raises(SceneError, match="a ratio is not an angle") as info:
        parse_quantity(text, "deg", "requirements.min_phase_margin")
    assert info.value.key == "requirements.min_phase_margin"


def test_nan_rejected():
    with pytest.raises(SceneError, match="NaN"):
        parse_quantity(float("nan"), "m", "x")


def test_parse_si_keeps_words_and_recurses():
    out = parse_si({"f": {"start": "0.5 Hz"}, "t": "sine", "j": ["2 kg*m^2"]}, "s")
    assert out == {"f": {"start": 0.5}, "t": "sine", "j": [2.0]}


@pytest.mark.parametrize("text", ["nan ohm", "NaN ohm", "-nan ohm", "nan", " NAN  ohm"])
def test_nan_written_as_text_reports_the_nan_rule(text):
    with pytest.raises(SceneError, match="value is NaN") as info:
        parse_quantity(text, "ohm", "motor.resistance")
    assert info.value.key == "motor.resistance"
    with pytest.raises(SceneError, match="value is NaN"):
        parse_si({"f": text}, "studies.s")


def test_infinity_written_as_text_is_a_number():
    """"inf N*m/rad" is infinity (rigid); the component's rules decide whether it is allowed."""
    assert parse_quantity("inf N*m/rad", "N*m/rad", "k") == math.inf
    assert parse_quantity("-inf N", "N", "k") == -math.inf
    assert parse_si({"w": "information", "x": "infinite"}, "s") == {"w": "information", "x": "infinite"}


def test_infinite_resistance_breaks_the_finite_rule(ema_dict):
    from .conftest import build, variant
    with pytest.raises(SceneError, match="must be finite") as info:
        build(variant(ema_dict, motor__resistance="inf ohm"))
    assert info.value.key == "motor.resistance"


def test_a_scene_bandwidth_and_study_frequency_in_rad_per_s_are_read_in_hz(ema_dict):
    """[requirements] bandwidth and a study's frequency given as 2 pi * 8 rad/s are 8 Hz."""
    from servo_toolkit.scene.loader import scene_from_dict
    omega = f"{2 * math.pi * 8:.12g} rad/s"
    ema_dict["requirements"]["bandwidth"] = omega
    ema_dict["studies"]["kv_8hz"]["frequency"] = omega
    scene = scene_from_dict(ema_dict)
    assert scene.requirements.bandwidth == pytest.approx(8.0, rel=1e-10)
    assert scene.studies["kv_8hz"].params["frequency"] == pytest.approx(8.0, rel=1e-10)


@pytest.mark.parametrize("text, unit, expected", [
    ("5 mm/turn", "m/turn", 5e-3),           # a lead per turn is the lead
    ("5 mm/revolution", "m/turn", 5e-3),
    ("5 mm/cycle", "m/turn", 5e-3),
    ("5 mm", "m/turn", 5e-3),                 # written without the angle: per turn, the key's own
    ("5 mm/rad", "m/turn", 2 * math.pi * 5e-3),
    ("0.2 V/Hz", "V*s/rad", 0.2 / (2 * math.pi)),       # a hertz is a turn per second
    ("1e-4 N*m/Hz", "N*m*s/rad", 1e-4 / (2 * math.pi)),
    ("10 Hz", "rad/s", 20 * math.pi),
    ("0.02 V/krpm", "V*s/rad", 0.02 * 60 / (2 * math.pi * 1000)),
])
def test_per_turn_and_per_hertz_units_count_a_turn_as_two_pi(text, unit, expected):
    """pint's radian is dimensionless: left to pint, "5 mm/turn" is 0.796 mm and "0.2 V/Hz"
    0.2 V*s/rad."""
    assert parse_quantity(text, unit, "k") == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize("text, unit", [("5 mm/turn", "m"), ("0.2 V/Hz", "V*s"), ("2 N*m/rad", "N*m")])
def test_an_angle_the_key_has_no_place_for_is_refused(text, unit):
    with pytest.raises(SceneError, match="per angle") as info:
        parse_quantity(text, unit, "drivetrain[0].stroke")
    assert info.value.key == "drivetrain[0].stroke"


def test_a_lead_per_turn_gives_the_ratio_of_the_lead(ema_dict):
    from .conftest import build, variant
    plain = build(ema_dict).stages[1]
    for text in ("5 mm/turn", "5 mm/revolution", "0.005 m/cycle"):
        assert build(variant(ema_dict, drivetrain__1__lead=text)).stages[1].lead == pytest.approx(plain.lead)
    assert plain.lead == pytest.approx(5e-3)


def test_a_back_emf_constant_per_hertz_is_checked_against_kt(ema_dict):
    """0.2 V/Hz is 0.0318 V*s/rad: it does not equal Kt = 0.2 N*m/A."""
    from .conftest import build, variant
    with pytest.raises(SceneError, match="factor of 6.283") as info:
        build(variant(ema_dict, motor__back_emf_constant="0.2 V/Hz"))
    assert info.value.key == "motor.back_emf_constant"
    motor = build(variant(ema_dict, motor__back_emf_constant=f"{0.2 * 2 * math.pi} V/Hz",
                          motor__viscous_friction="1e-4 N*m/Hz")).motor
    assert motor.back_emf_constant == pytest.approx(0.2)
    assert motor.viscous_friction == pytest.approx(1e-4 / (2 * math.pi))
