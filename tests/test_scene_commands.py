"""Every shipped scene runs every command with its defaults, or says in one line what to run;
amplitudes and results carry the output's unit (deg for an angle, mm for a travel)."""

from __future__ import annotations

import json
import math

import pytest

from servo_toolkit import load_scene
from servo_toolkit.cli import main
from servo_toolkit.core.output_units import OutputUnit, output_unit
from servo_toolkit.errors import SceneError

from .conftest import SCENE_FILES, SCENES

#: every command that takes a scene, with the arguments it needs beyond it (the report has
#: its own tests on every scene: test_report_scenes.py); ``reduce`` measures each effect at
#: 8 Hz (its whole sweep costs ~35 s of CPU a scene), except on the reference scene
COMMANDS = {"stiffness": [], "kv": [], "design": [], "check": [], "simulate": [], "accuracy": [],
            "sweep": [], "reduce": ["--frequency", "8"], "export": ["-o", "{tmp}/export"],
            "montecarlo": ["--samples", "8"]}
#: (scene, command) run with the command's defaults only: the README's scene measures the
#: reduction over its whole sweep
DEFAULTS = {("ema_reference", "reduce")}


@pytest.mark.parametrize("command", sorted(COMMANDS))
@pytest.mark.parametrize("path", SCENE_FILES, ids=lambda p: p.stem)
def test_every_command_on_every_scene_succeeds_or_hints(path, command, tmp_path, capsys):
    extra = [] if (path.stem, command) in DEFAULTS else [a.format(tmp=tmp_path) for a in COMMANDS[command]]
    code = main([command, str(path), *extra, "--json"])
    out, err = capsys.readouterr()
    messages = [line for line in err.splitlines() if line.startswith("servo-toolkit: error")]
    if code in (0, 1):  # done (1: a requirement of the scene is not met, a verdict)
        json.loads(out)
        assert not messages, err
    else:  # does not apply: one line that says what to run instead
        assert code == 2, err
        assert len(messages) == 1 and len(err.strip().splitlines()) == 1, err
        assert "`servo-toolkit" in messages[0] or "`export --sample-time" in messages[0], messages[0]
        hinted = messages[0].split("`")[1]
        if hinted.startswith("servo-toolkit simulate"):  # the hint itself runs
            argv = hinted.split()[1:]
            assert main(argv) == 0
            capsys.readouterr()


def test_default_amplitude_follows_the_output_unit(capsys):
    linear = SCENES / "linear_roller_screw_actuator.toml"
    assert main(["sweep", str(linear), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["amplitudes_mm"] == [1.0] and "amplitudes_deg" not in d
    assert not any(p["failed"] for p in d["points"])
    assert main(["simulate", str(linear), "--json"]) == 0
    sim = json.loads(capsys.readouterr().out)
    assert "max_abs_tracking_error_deg" not in sim
    err_mm = sim["max_abs_tracking_error_mm"]
    # the same run asked with units gives the same figure; a half amplitude halves it
    # (the reduced model is linear in the command below the limits)
    assert main(["simulate", str(linear), "--amplitude", "1 mm", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["max_abs_tracking_error_mm"] == pytest.approx(err_mm, rel=1e-12)
    assert main(["simulate", str(linear), "--amplitude", "0.5 mm", "--json"]) == 0
    half = json.loads(capsys.readouterr().out)["max_abs_tracking_error_mm"]
    assert half == pytest.approx(err_mm / 2, rel=1e-3)
    # the tracking error of a 1 mm sine at 8 Hz is a fraction of a millimetre: not 0.03 of anything
    assert 0.05 < err_mm < 1.0


def test_units_on_an_angle_output(capsys):
    ema = SCENES / "ema_reference.toml"
    assert main(["simulate", str(ema), "--amplitude", "2 deg", "--json"]) == 0
    a = json.loads(capsys.readouterr().out)["max_abs_tracking_error_deg"]
    assert main(["simulate", str(ema), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["max_abs_tracking_error_deg"] == pytest.approx(a, rel=1e-12)
    assert main(["simulate", str(ema), "--amplitude", f"{math.radians(2.0)} rad", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["max_abs_tracking_error_deg"] == pytest.approx(a, rel=1e-9)


@pytest.mark.parametrize("command", ["simulate", "sweep", "montecarlo", "reduce", "kv", "accuracy"])
@pytest.mark.parametrize("scene, amplitude, words", [
    ("linear_roller_screw_actuator", "2 deg", "the output is a travel: give the amplitude in mm"),
    ("ema_reference", "1 mm", "the output is an angle: give the amplitude in deg"),
    ("ema_reference", "-2 deg", "must be positive"),
    ("ema_reference", "2 blorps", "unknown unit"),
])
def test_amplitude_of_the_wrong_kind_is_one_line(command, scene, amplitude, words, capsys):
    code = main([command, str(SCENES / f"{scene}.toml"), "--amplitude", amplitude])
    err = capsys.readouterr().err
    assert code == 2 and words in err and "--amplitude" in err
    assert len(err.strip().splitlines()) == 1


def test_output_unit_parse_round_trip():
    for unit in (OutputUnit("rad"), OutputUnit("m")):
        for shown in (0.5, 1.0, 2.0, 37.0):
            si = unit.parse(f"{shown} {unit.shown}", "x")
            assert unit.show(si) == pytest.approx(shown, rel=1e-12)
            assert unit.parse(shown, "x") == pytest.approx(si, rel=1e-12)  # a bare number: the shown unit
    assert OutputUnit("m").parse("0.1 in", "x") == pytest.approx(2.54e-3)
    with pytest.raises(SceneError, match="at most 180 deg"):
        OutputUnit("rad").parse("181 deg", "x")
    assert output_unit(load_scene(SCENES / "deflection_platform.toml")).si == "rad"


def test_mechanism_scene_runs_its_study_by_default(capsys):
    assert main(["simulate", str(SCENES / "deflection_platform.toml")]) == 0
    captured = capsys.readouterr()
    assert "running its study 'ramp'" in captured.err and "ramp" in captured.out


def test_cam_simulation_starts_where_the_loop_was_designed(capsys):
    from servo_toolkit.loop import design
    from servo_toolkit.sim import build_model, controller_for
    scene = load_scene(SCENES / "cam_follower.toml")
    q0 = design(scene).q0
    model = build_model(scene, controller_for(scene)[0])
    assert model.q0 == pytest.approx(q0, abs=1e-12)
    # the designed point is not the dwell: the reflected inertia there is the largest
    j = scene.drivetrain.motor_inertia([model.q0, scene.drivetrain.mid_stroke])
    assert j[0] > 10 * j[1]


def test_kv_without_a_kv_study_runs_the_default_sine(capsys):
    assert main(["kv", str(SCENES / "linear_roller_screw_actuator.toml"), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    case = d["cases"][0]
    assert case["amplitude_mm"] == pytest.approx(1.0) and case["frequency_hz"] == 8.0
    assert "load_mass_kg" in case


def test_rigid_chain_stiffness_says_it_is_rigid(capsys):
    assert main(["stiffness", str(SCENES / "cam_follower.toml")]) == 0
    assert "no compliant stage: the chain is rigid" in capsys.readouterr().out
