"""The Python API's arguments: a pint Quantity is converted, a bare number is in the documented
unit, and a misuse is one SceneError naming the argument and the rule, raised before any work."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pint
import pytest

import servo_toolkit as st
from servo_toolkit.errors import SceneError
from servo_toolkit.sim import Reference, simulate
from servo_toolkit.studies.stiffness import stiffness_study

#: a registry of the user's own, not the toolkit's
UREG = pint.UnitRegistry()


def _refused(key, call):
    with pytest.raises(SceneError) as info:
        call()
    assert info.value.key == key
    return info.value.rule


# -- simulate: the sine a run resolves (the command line's rule) --

@pytest.mark.parametrize("frequency", [5000.0, 4000.0])
def test_simulate_refuses_a_sine_above_a_quarter_of_the_sample_rate(ema, frequency):
    scene, controller = ema  # 0.1 ms controller: 10 kHz sample rate, at most 2.5 kHz
    rule = _refused("reference", lambda: simulate(scene, controller, duration=0.05,
                                                  reference=Reference.sine(math.radians(0.1), frequency)))
    assert "at most 2500 Hz" in rule and "quarter" in rule


def test_simulate_refuses_a_run_shorter_than_the_sine_s_period(ema):
    scene, controller = ema
    rule = _refused("duration", lambda: simulate(scene, controller, duration=0.5,
                                                 reference=Reference.sine(math.radians(1.0), 1.0)))
    assert "at least 1 s" in rule and "whole period" in rule


def test_the_frequency_rule_is_checked_before_the_loop_is_designed(monkeypatch, ema):
    import importlib
    module = importlib.import_module("servo_toolkit.sim.simulate")
    monkeypatch.setattr(module, "controller_for", lambda scene: pytest.fail("designed before the check"))
    _refused("reference", lambda: simulate(ema[0], reference=Reference.sine(0.001, 5000.0), duration=0.05))


def test_simulate_and_the_command_line_share_one_frequency_check():
    from servo_toolkit.sim import reference_checks
    from servo_toolkit.studies.time import reference as study_reference
    assert study_reference.check_sine_frequency is reference_checks.check_sine_frequency


def test_a_sine_at_a_quarter_of_the_sample_rate_over_one_period_passes():
    from servo_toolkit.sim.reference_checks import check_sine_frequency
    check_sine_frequency(2500.0, 1e-4, 1 / 2500.0, "reference", duration_key="duration")


# -- simulate's other arguments --

@pytest.mark.parametrize("kwargs, key", [(dict(dt=0.0), "dt"), (dict(dt=-1e-5), "dt"), (dict(duration="0.5 s"), "duration"),
                                         (dict(duration=0.5 * UREG.V), "duration"), (dict(duration=math.nan), "duration"),
                                         (dict(reference=0.1), "reference"), (dict(method="euler"), "method")])
def test_simulate_names_a_bad_argument(ema, kwargs, key):
    scene, controller = ema
    _refused(key, lambda: simulate(scene, controller, **{"duration": 0.01, **kwargs}))


def test_simulate_takes_a_quantity_of_time_and_a_design_result(ema):
    scene, controller = ema
    step = Reference.step(math.radians(0.1))
    plain = simulate(scene, controller, reference=step, duration=0.01, dt=1e-4)
    design = dataclasses.replace(st.design(scene, progress=False), controller=controller)
    given = simulate(scene, design, reference=step, duration=10 * UREG.ms, dt=100 * UREG.us)
    assert given.times[-1] == pytest.approx(0.01)
    np.testing.assert_array_equal(given.output_angle, plain.output_angle)


def test_a_controller_of_another_type_is_named(ema):
    rule = _refused("controller", lambda: simulate(ema[0], "cascade", duration=0.01))
    assert "got str" in rule


def test_a_design_of_another_scene_is_named(ema, scenes_dir):
    """Another actuator's design run on this one would mix two controllers' worth of physics."""
    other = st.load_scene(scenes_dir / "linear_roller_screw_actuator.toml")
    design = dataclasses.replace(st.design(ema[0], progress=False), controller=ema[1])
    rule = _refused("controller", lambda: simulate(other, design, duration=0.01))
    assert "designed for the scene 'ema_reference'" in rule


def test_design_reads_a_scene_path_and_names_another_type(scenes_dir):
    path = scenes_dir / "ema_reference.toml"
    assert st.design(str(path), progress=False).scene_name == "ema_reference"
    assert "got dict" in _refused("scene", lambda: st.design({"motor": {}}, progress=False))


def test_design_names_q0_given_as_text(ema):
    rule = _refused("q0", lambda: st.design(ema[0], q0="10 deg", progress=False))
    assert "pint" in rule


# -- Reference: checked when it is made --

@pytest.mark.parametrize("call, key", [(lambda: Reference.sine(math.nan, 8.0), "amplitude"),
                                       (lambda: Reference.sine("2 deg", 8.0), "amplitude"),
                                       (lambda: Reference.sine(0.01, 0.0), "frequency"),
                                       (lambda: Reference.sine(0.01, math.inf), "frequency"),
                                       (lambda: Reference.sine(0.01, 8.0, offset=math.nan), "offset"),
                                       (lambda: Reference.step(1 * UREG.s), "size"),
                                       (lambda: Reference.ramp(0.1, at=math.nan), "at"),
                                       (lambda: Reference("sine", 0.01, -8.0), "frequency")])
def test_reference_names_a_bad_argument(call, key):
    _refused(key, call)


def test_reference_converts_quantities_to_si():
    sine = Reference.sine(2 * UREG.deg, 0.5 * UREG.kHz, offset=1 * UREG.deg)
    assert (sine.amplitude, sine.frequency, sine.offset) == pytest.approx((math.radians(2.0), 500.0, math.radians(1)))
    travel = Reference.sine(2 * UREG.mm, 0.5 * UREG.kHz, offset=1 * UREG.mm)
    assert (travel.amplitude, travel.offset) == pytest.approx((2e-3, 1e-3))
    assert Reference.ramp(90 * UREG.deg / UREG.s).amplitude == pytest.approx(math.pi / 2)
    assert Reference.move(10 * UREG.deg, 1.0, 10.0, 100.0).profile.distance == pytest.approx(math.radians(10.0))


# -- angles: a Quantity converted to the argument's unit --

def test_stiffness_study_converts_a_quantity_to_its_degrees(ema):
    scene = ema[0]
    given = stiffness_study(scene, [10 * UREG.deg, 0.1 * UREG.rad])
    np.testing.assert_allclose(given.angles_deg, [10.0, math.degrees(0.1)])
    np.testing.assert_allclose(given.total, stiffness_study(scene, [10.0, math.degrees(0.1)]).total)


def test_the_operating_point_converts_a_quantity_to_rad(ema):
    from servo_toolkit.drivetrain.operating_point import operating_point
    assert operating_point(ema[0], 10 * UREG.deg)[0] == pytest.approx(math.radians(10.0))
    assert operating_point(ema[0], np.array(0.1))[0] == operating_point(ema[0], np.float64(0.1))[0] == 0.1
    _refused("q0", lambda: operating_point(ema[0], 10 * UREG.mm))


# -- components set from Python meet the scene file's rules --

@pytest.mark.parametrize("field, value", [("resistance", "1 ohm"), ("resistance", -1.0), ("inductance", math.nan),
                                          ("current_limit", 0.0), ("torque_constant", 1 * UREG.H),
                                          ("static_friction", -0.1)])
def test_replacing_a_motor_field_meets_the_scene_file_s_rule(ema, field, value):
    _refused(f"motor.{field}", lambda: dataclasses.replace(ema[0].motor, **{field: value}))


def test_a_motor_field_takes_a_quantity(ema):
    motor = dataclasses.replace(ema[0].motor, resistance=2 * UREG.kohm, rotor_inertia=2 * UREG.g * UREG.cm ** 2)
    assert (motor.resistance, motor.rotor_inertia) == pytest.approx((2000.0, 2e-7))
    assert dataclasses.replace(ema[0].motor, voltage_limit=math.inf).voltage_limit == math.inf


#: (stage index in the reference EMA, its class's name, field, bad value)
STAGE_MISUSES = [(0, "GearTrain", "efficiency", 1.5), (0, "GearTrain", "ratio", 0.0),
                 (0, "GearTrain", "backlash", -1e-3), (0, "GearTrain", "torsional_stiffness", -5.0),
                 (1, "BallScrew", "lead", "5 mm"), (1, "BallScrew", "nut_mass", math.nan),
                 (1, "BallScrew", "axial_stiffness", 1 * UREG.N),
                 (2, "RockerLinkage", "arm_length", -0.1), (2, "RockerLinkage", "efficiency", 0.0),
                 (3, "Compliance", "stiffness", math.inf), (3, "Compliance", "damping_ratio", -0.1)]


@pytest.mark.parametrize("index, name, field, value", STAGE_MISUSES)
def test_replacing_a_stage_field_meets_the_scene_file_s_rule(ema, index, name, field, value):
    stage = ema[0].stages[index]
    assert type(stage).__name__ == name
    _refused(f"{name}.{field}", lambda: dataclasses.replace(stage, **{field: value}))


def test_a_stage_field_takes_a_quantity_and_a_gear_s_inertias_each_meet_the_rule(ema):
    gear, screw = ema[0].stages[:2]
    assert dataclasses.replace(screw, lead=4 * UREG.mm).lead == pytest.approx(4e-3)
    assert dataclasses.replace(gear, backlash=0.2 * UREG.deg).backlash == pytest.approx(math.radians(0.2))
    assert dataclasses.replace(gear, inertias=[1e-5, 2e-5]).inertias == (1e-5, 2e-5)
    _refused("GearTrain.inertias[1]", lambda: dataclasses.replace(gear, inertias=(1e-5, -2e-5)))
    _refused("BallScrew.stroke_range", lambda: dataclasses.replace(screw, stroke_range=(0.1, 0.0)))


@pytest.mark.parametrize("field, value", [("inertia", -1.0), ("inertia", "2 kg*m^2"), ("damping", math.inf),
                                          ("coulomb_friction", -0.5), ("static_friction", 0.0)])
def test_replacing_a_load_field_meets_the_scene_file_s_rule(ema, field, value):
    load = dataclasses.replace(ema[0].load, coulomb_friction=1.0)
    _refused(f"load.{field}", lambda: dataclasses.replace(load, **{field: value}))


def test_a_load_field_takes_a_quantity_of_a_shaft_or_a_travel(ema):
    load = ema[0].load
    assert dataclasses.replace(load, inertia=3 * UREG.kg * UREG.m ** 2).inertia == pytest.approx(3.0)
    assert dataclasses.replace(load, inertia=3 * UREG.g).inertia == pytest.approx(3e-3)  # a carriage's mass
    _refused("load.inertia", lambda: dataclasses.replace(load, inertia=3 * UREG.N))


@pytest.mark.parametrize("field, value, words", [("rod_length", 1e-3, "rod too short"),
                                                 ("stroke_range", (-3.3, 0.0), "(-180, 180) deg"),
                                                 ("stroke_range", (-1.4, 1.4), "dead point")])
def test_replacing_a_linkage_field_meets_its_geometry_s_rule(ema, field, value, words):
    assert words in _refused(f"RockerLinkage.{field}", lambda: dataclasses.replace(ema[0].stages[2], **{field: value}))


@pytest.mark.parametrize("path", [123, b"name = 'x'", ["ema.toml"]])
def test_load_scene_names_a_path_of_another_type(path):
    assert "expected a file path" in _refused("path", lambda: st.load_scene(path))


def test_a_reference_in_the_other_output_s_unit_is_named_before_the_run(ema, scenes_dir):
    """1 mm read as 0.001 rad of a shaft angle is no command the user meant: a sine of a
    length for the reference EMA's output angle, or of an angle for the EMPS cart's travel,
    is refused naming ``reference``; a bare number (SI of the output) and the output's own
    unit run."""
    length, angle = Reference.sine(1 * UREG.mm, 8.0), Reference.sine(2 * UREG.deg, 8.0)
    assert (length.position_unit, angle.position_unit, Reference.sine(0.03, 8.0).position_unit) == ("m", "rad", None)
    assert "a travel (m)" in _refused("reference", lambda: simulate(ema[0], reference=length, duration=0.2))
    emps = st.load_scene(scenes_dir / "emps.toml")
    assert "an angle (rad)" in _refused("reference", lambda: simulate(emps, reference=angle, duration=0.2))
    assert simulate(ema[0], reference=angle, duration=0.2).output_angle.size > 0
    assert "where amplitude is a travel" in _refused("offset", lambda: Reference.sine(1 * UREG.mm, 8.0, 2 * UREG.deg))
    assert "where distance is an angle" in _refused(
        "v_max", lambda: Reference.move(1 * UREG.deg, 1 * UREG.mm / UREG.s, 1.0, 1.0))
