"""A sine that leaves the stroke is refused where it is given: a study's amplitude when the
scene loads (naming ``studies.NAME.amplitude``), a command's ``--amplitude`` before any run."""

import pytest

from servo_toolkit.cli import main
from servo_toolkit.errors import SceneError

from .conftest import SCENES, build, variant

EMA = str(SCENES / "ema_reference.toml")
LINEAR = str(SCENES / "linear_roller_screw_actuator.toml")


@pytest.mark.parametrize("edit, key", [
    (dict(studies__sweep__amplitude="40 deg"), "studies.sweep.amplitude"),
    (dict(studies__kv_8hz__amplitudes=["2 deg", "31 deg"]), "studies.kv_8hz.amplitudes"),
    (dict(studies__kv_stroke__amplitude="20 deg", studies__kv_stroke__offset="15 deg"), "studies.kv_stroke.amplitude"),
])
def test_a_study_sine_beyond_the_stroke_is_refused_at_load_time(ema_dict, edit, key):
    with pytest.raises(SceneError) as err:
        build(variant(ema_dict, **edit))
    assert err.value.key == key and "leaves the stroke -30 deg..30 deg" in err.value.rule


def test_a_sine_to_the_stroke_end_still_loads(ema_dict):
    scene = build(variant(ema_dict, studies__sweep__amplitude="30 deg"))
    assert scene.studies["sweep"].get("amplitude") == pytest.approx(0.5235987755982988)


@pytest.mark.parametrize("command", ["stiffness", "check", "simulate"])
def test_every_command_names_the_study_amplitude(tmp_path, command, capsys):
    text = open(EMA).read().replace('amplitude = "2 deg"\nfrequencies', 'amplitude = "170 deg"\nfrequencies')
    path = tmp_path / "wide.toml"
    path.write_text(text)
    assert main([command, str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "studies.sweep.amplitude" in err[0] and "leaves the stroke" in err[0]


@pytest.mark.parametrize("scene, amplitude, limit", [(EMA, "100 deg", "at most 30 deg"), (EMA, "179", "at most 30 deg"),
                                                     (LINEAR, "1 m", "at most 60 mm")])
@pytest.mark.parametrize("command", ["sweep", "simulate"])
def test_an_absurd_command_amplitude_is_refused_before_any_run(command, scene, amplitude, limit, capsys):
    assert main([command, scene, "--amplitude", amplitude, "--frequency", "8"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--amplitude" in err[0] and limit in err[0]

