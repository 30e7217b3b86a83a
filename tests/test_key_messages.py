"""What a scene author meets after a slip: a misspelt key named with the key it misspells
(before the key it hides is reported missing), a refused value with an example in the key's
own unit, and a bare number far from its key's typical values noted with the unit it was
read in."""

import warnings

import pytest

from servo_toolkit import SceneError
from servo_toolkit.cli import main
from servo_toolkit.errors import SceneWarning
from servo_toolkit.scene.loader import load_scene

from .conftest import SCENE_FILES, SCENES, build, variant


def _with_stage(ema_dict, i, table):
    data = variant(ema_dict)
    data["drivetrain"][i] = table
    return data


def test_a_misspelt_required_key_is_named_with_the_key_it_misspells(ema_dict):
    with pytest.raises(SceneError) as info:
        build(_with_stage(ema_dict, 0, {"kind": "gear", "ratio_": 50}))
    assert info.value.key == "drivetrain[0].ratio_"
    assert "unknown key; did you mean ratio?" in info.value.rule


def test_a_key_holding_a_missing_ones_name_is_named_without_calling_it_unknown(ema_dict):
    """``gear_ratio`` beside a missing ``ratio`` may be meant for it; ``thermal_resistance_winding``
    beside a missing ``resistance`` is a key of its own: the missing key is the fact, the
    holder a suggestion."""
    with pytest.raises(SceneError) as info:
        build(_with_stage(ema_dict, 0, {"kind": "gear", "gear_ratio": 50}))
    assert info.value.key == "drivetrain[0].ratio"
    assert info.value.rule.startswith("missing key (required)") and "gear_ratio" in info.value.rule
    data = variant(ema_dict, motor__thermal_resistance_winding="0.3 K/W")
    del data["motor"]["resistance"]
    with pytest.raises(SceneError) as info:
        build(data)
    assert info.value.key == "motor.resistance" and "unknown" not in info.value.rule


@pytest.mark.parametrize("edit, key, near", [
    ({"drivetrain__1__leed": "5 mm"}, "drivetrain[1].leed", "lead"),
    ({"motor__resistanse": "1 ohm"}, "motor.resistanse", "resistance"),
    ({"sensors__sampletime": "0.1 ms"}, "sensors.sampletime", "sample_time"),
])
def test_an_unknown_key_names_the_nearest_known_key(ema_dict, edit, key, near):
    with pytest.raises(SceneError) as info:
        build(variant(ema_dict, **edit))
    assert info.value.key == key
    assert f"did you mean {near}?" in info.value.rule


def test_an_unknown_key_far_from_every_known_key_only_lists_them(ema_dict):
    with pytest.raises(SceneError) as info:
        build(variant(ema_dict, motor__colour="red"))
    assert "did you mean" not in info.value.rule and "known keys are" in info.value.rule


def test_a_ratio_written_n_to_1_is_refused_with_the_keys_own_example(ema_dict):
    with pytest.raises(SceneError) as info:
        build(_with_stage(ema_dict, 0, {"kind": "gear", "ratio": "50:1"}))
    assert info.value.key == "drivetrain[0].ratio"
    assert "ms" not in info.value.rule and "e.g. 50" in info.value.rule


def test_an_expression_is_refused_with_an_example_in_the_keys_unit(ema_dict):
    with pytest.raises(SceneError, match=r"e\.g\. '5 m/turn'"):
        build(variant(ema_dict, drivetrain__1__lead="5 mm / 2"))


@pytest.mark.parametrize("edit, key, unit", [
    ({"sensors__sample_time": 0.2}, "sensors.sample_time", "s"),
    ({"drivetrain__1__lead": 5}, "drivetrain[1].lead", "m/turn"),
    ({"motor__inductance": 5}, "motor.inductance", "H"),
    ({"motor__rotor_inertia": 536}, "motor.rotor_inertia", "kg*m^2"),  # a catalogue's 536 g*cm^2
    ({"motor__resistance": 500}, "motor.resistance", "ohm"),
    ({"load__inertia": 2e5}, "load.inertia", "kg*m^2"),
])
def test_a_bare_number_far_from_its_keys_typical_values_is_noted(ema_dict, edit, key, unit):
    scene = build(variant(ema_dict, **edit))
    assert len(scene.notes) == 1
    assert scene.notes[0].startswith(f"{key} = ") and f"read in {unit} (SI)" in scene.notes[0]
    if key == "motor.rotor_inertia":
        assert 'e.g. "536 g*cm^2"' in scene.notes[0]


def test_a_typical_bare_number_or_a_written_unit_is_not_noted(ema_dict):
    assert build(variant(ema_dict, sensors__sample_time=1e-4)).notes == ()
    assert build(variant(ema_dict, sensors__sample_time="0.2 s")).notes == ()


@pytest.mark.parametrize("path", SCENE_FILES, ids=lambda p: p.stem)
def test_the_shipped_scenes_have_no_notes(path):
    with warnings.catch_warnings():
        warnings.simplefilter("error", SceneWarning)
        assert load_scene(path).notes == ()


def test_the_command_line_prints_a_note_on_stderr(tmp_path, capsys):
    text = (SCENES / "ema_reference.toml").read_text().replace('sample_time = "0.1 ms"', "sample_time = 0.2")
    scene = tmp_path / "slow.toml"
    scene.write_text(text)
    assert main(["stiffness", str(scene), "--json"]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"servo-toolkit: note: {scene}: sensors.sample_time = 0.2 has no unit and is read in s (SI): "
                   "0.2 s is outside the typical 1e-06..0.02 s; write the unit if another was meant (e.g. \"0.2 ms\")"]


def _emps_dict():
    import tomllib
    return tomllib.loads((SCENES / "emps.toml").read_text())


def test_a_load_given_as_a_mass_without_a_drivetrain_names_the_rule():
    data = variant(_emps_dict(), drivetrain=None)
    with pytest.raises(SceneError) as info:
        build(data)
    assert info.value.key == "load.inertia"
    assert "dimension mismatch" not in info.value.rule
    assert "needs a drivetrain ending in a travel output" in info.value.rule
    assert "[[drivetrain]] is missing" in info.value.rule


def test_a_load_given_as_a_mass_on_a_rotary_output_names_the_last_stage():
    data = variant(_emps_dict(), drivetrain=[{"kind": "gear", "ratio": 5}])
    with pytest.raises(SceneError) as info:
        build(data)
    assert info.value.key == "load.inertia"
    assert "output is an angle (drivetrain[0] is a gear)" in info.value.rule
    assert "kg*m^2" in info.value.rule


@pytest.mark.parametrize("table", ["requirements", "robustness"])
@pytest.mark.parametrize("written", [45, "45"])
def test_a_bare_phase_margin_is_refused_saying_it_was_read_in_rad(written, table):
    import tomllib
    data = tomllib.loads((SCENES / "ema_robust.toml").read_text())
    data[table]["min_phase_margin"] = written
    with pytest.raises(SceneError) as info:
        build(data)
    assert info.value.key == f"{table}.min_phase_margin"
    assert "(got 45, read as 45 rad = 2578 deg: a bare number is in rad; write '45 deg')" in info.value.rule


def test_a_phase_margin_with_its_unit_is_refused_in_deg(ema_dict):
    with pytest.raises(SceneError, match=r"must be below 180 deg.*\(got 190 deg\)"):
        build(variant(ema_dict, requirements__min_phase_margin="190 deg"))


@pytest.mark.parametrize("written", [90, "90"])
def test_a_bare_phase_lag_far_beyond_a_turn_is_noted_in_rad(ema_dict, written):
    scene = build(variant(ema_dict, requirements__max_phase_lag_at_bandwidth=written))
    assert scene.requirements.max_phase_lag_at_bandwidth == 90.0  # read in rad, as documented
    assert len(scene.notes) == 1
    assert "max_phase_lag_at_bandwidth = 90 has no unit and is read in rad (SI)" in scene.notes[0]
    assert 'e.g. "90 deg"' in scene.notes[0]
    assert build(variant(ema_dict, requirements__max_phase_lag_at_bandwidth=1.2)).notes == ()
