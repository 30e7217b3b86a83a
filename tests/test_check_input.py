"""Bad input to ``check`` and ``design``: one line naming the key (or file), exit 2."""

import json
import xml.etree.ElementTree as ET

import pytest

from servo_toolkit.cli import main
from servo_toolkit.errors import SceneError
from servo_toolkit.loop.requirements import parse_override, requirements_of
from servo_toolkit.scene.loader import load_scene, scene_from_dict

from .conftest import SCENES

EMA = str(SCENES / "ema_reference.toml")
PLATFORM = str(SCENES / "deflection_platform.toml")
CAM = str(SCENES / "cam_follower.toml")

BAD = [("bandwidth=-5Hz", "bandwidth", "must be positive"),
       ("bandwidth=0", "bandwidth", "must be positive"),
       ("bandwidth=nan", "bandwidth", "NaN"),
       ("bandwidth=1e400", "bandwidth", "finite"),
       ("bandwidth=5 m", "bandwidth", "dimension mismatch"),
       ("bandwidth=", "bandwidth", "missing value"),
       ("phase_lag_at_bandwidth=-1deg", "phase_lag_at_bandwidth", "must be positive"),
       ("phase_margin=400deg", "phase_margin", "below 180 deg"),
       ("phase_margin=180deg", "phase_margin", "below 180 deg"),
       ("pm=3.2rad", "phase_margin", "below 180 deg"),
       ("phase_margin=0deg", "phase_margin", "must be positive"),
       ("sensitivity_peak=0dB", "sensitivity_peak", "must be positive"),
       ("sensitivity_peak=-2dB", "sensitivity_peak", "must be positive"),
       ("gain_margin=-3dB", "gain_margin", "must not be negative"),
       ("gain_margin=6 Hz", "gain_margin", "dB")]


@pytest.mark.parametrize("text, name, rule", BAD)
def test_parse_override_applies_the_scene_rules(text, name, rule):
    with pytest.raises(SceneError) as err:
        parse_override(text)
    assert err.value.key == f"--require {text}" and rule in err.value.rule


@pytest.mark.parametrize("text, expected", [("bandwidth=200Hz", ("bandwidth", 200.0)),
                                            ("gain_margin=0dB", ("gain_margin", 0.0)),
                                            ("phase_margin=179.9", ("phase_margin", 179.9)),
                                            ("pm=0.5rad", ("phase_margin", 28.64788975654116)),
                                            ("phase_lag=1.5 rad", ("phase_lag_at_bandwidth", 85.94366926962348)),
                                            ("bandwidth=0.3 kHz", ("bandwidth", 300.0))])
def test_parse_override_accepts_valid_values(text, expected):
    name, value = parse_override(text)
    assert name == expected[0] and value == pytest.approx(expected[1], rel=1e-12)


def test_python_overrides_follow_the_same_rules():
    scene = load_scene()
    with pytest.raises(SceneError, match=r"require\.bandwidth: must be positive"):
        requirements_of(scene, {"bandwidth": -5})
    reqs = {r.name: r for r in requirements_of(scene, {"bandwidth": "0.2 kHz", "pm": 50})}
    assert reqs["bandwidth"].value == pytest.approx(200.0) and reqs["bandwidth"].source == "override"
    assert reqs["phase_margin"].value == 50.0


def test_scene_phase_margin_of_180_deg_or_more_is_rejected(ema_dict):
    ema_dict["requirements"]["min_phase_margin"] = "400 deg"
    with pytest.raises(SceneError, match=r"requirements\.min_phase_margin: must be below 180 deg"):
        scene_from_dict(ema_dict)


@pytest.mark.parametrize("command", ["check", "design"])
@pytest.mark.parametrize("text, name", [("bandwidth=-5Hz", "bandwidth"), ("bandwidth=0", "bandwidth"),
                                        ("phase_margin=400deg", "phase_margin"),
                                        ("sensitivity_peak=0dB", "sensitivity_peak"),
                                        ("gain_margin=-3dB", "gain_margin")])
def test_cli_bad_require_exits_2_with_one_line(command, text, name, capsys):
    assert main([command, EMA, "--require", text]) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"servo-toolkit: error: --require {text}: ")
    assert captured.out == ""


@pytest.mark.parametrize("command", ["check", "design", "tolerances", "export"])
def test_a_requirement_given_twice_exits_2_naming_both(command, tmp_path, capsys):
    """The same requirement under two names (pm is phase_margin) is refused, not the last kept."""
    out = ["-o", str(tmp_path / "out")] if command == "export" else []
    assert main([command, EMA, *out, "--require", "phase_margin=45deg", "--require", "pm=60deg"]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("servo-toolkit: error: --require pm=60deg: ")
    assert "phase_margin is already required by --require phase_margin=45deg" in lines[0]


def test_junit_in_a_missing_directory_exits_2_before_any_design(tmp_path, capsys, monkeypatch):
    import servo_toolkit.cli.cmd_check as cmd_check

    def no_design(*args, **kwargs):
        raise AssertionError("designed before checking the --junit path")
    monkeypatch.setattr(cmd_check, "design_from_args", no_design)
    path = tmp_path / "missing" / "x.xml"
    assert main(["check", EMA, "--junit", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "junit" in err[0] and str(path) in err[0] and "does not exist" in err[0]
    assert main(["check", EMA, "--junit", str(tmp_path)]) == 2
    assert "is a directory" in capsys.readouterr().err


@pytest.mark.parametrize("empty", ["", "  "])
def test_an_empty_junit_path_exits_2_instead_of_writing_no_report(empty, capsys, monkeypatch):
    import servo_toolkit.cli.cmd_check as cmd_check

    def no_design(*args, **kwargs):
        raise AssertionError("designed before checking the --junit path")
    monkeypatch.setattr(cmd_check, "design_from_args", no_design)
    assert main(["check", EMA, "--linear-only", "--junit", empty]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--junit" in err[0] and "is empty" in err[0]


def test_design_names_the_scene_without_a_drivetrain(capsys):
    assert main(["design", PLATFORM]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and PLATFORM in err[0] and "no motor-driven drivetrain" in err[0]


def test_a_scene_without_a_loop_is_skipped_and_the_exit_code_is_the_others(tmp_path, capsys):
    junit = tmp_path / "loop.xml"
    assert main(["check", CAM, PLATFORM, "--junit", str(junit)]) == 0
    captured = capsys.readouterr()
    assert captured.err == ""
    line = next(l for l in captured.out.splitlines() if PLATFORM in l)
    assert "SKIPPED" in line and "no motor-driven drivetrain" in line and "--study" in line
    assert "all requirements met" in captured.out and "1 of 2 scene(s) skipped" in captured.out
    suites = ET.parse(junit).getroot().findall("testsuite")
    assert [s.get("name") for s in suites] == ["cam_follower", load_scene(PLATFORM).name]
    assert not suites[0].findall(".//failure") and not suites[0].findall(".//error")
    assert {c.get("name") for c in suites[0].findall("testcase")} >= {"bandwidth", "closed_loop_stable"}
    skipped = suites[1].find("testcase/skipped")
    assert suites[1].get("skipped") == "1" and suites[1].get("errors") == "0" and suites[1].get("failures") == "0"
    assert "no motor-driven drivetrain" in skipped.get("message")


def test_only_scenes_without_a_loop_exit_0_skipped(tmp_path, capsys):
    two_stage = str(SCENES / "roller_screw_two_stage.toml")
    assert main(["check", PLATFORM, two_stage, "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["passed"] is True and data["errors"] == 0 and data["skipped"] == 2
    assert [d["skipped"] for d in data["scenes"]] == [True, True]
    assert all("no motor-driven drivetrain" in d["reason"] for d in data["scenes"])
    assert main(["check", PLATFORM, "--require", "bandwith=8Hz"]) == 2  # the options are still checked


def test_a_failing_scene_beside_a_skipped_one_still_exits_1(capsys):
    assert main(["check", PLATFORM, EMA, "--require", "bandwidth=200Hz"]) == 1
    out = capsys.readouterr().out
    assert "SKIPPED" in out and "some requirements NOT met" in out


def test_multi_scene_check_json_marks_the_scene_in_error(tmp_path, capsys):
    missing = str(tmp_path / "missing.toml")
    junit = tmp_path / "loop.xml"
    assert main(["check", missing, CAM, "--json", "--junit", str(junit)]) == 2
    captured = capsys.readouterr()
    data = json.loads(captured.out)
    assert data["passed"] is False and data["errors"] == 1
    bad, good = data["scenes"]
    assert good["passed"] is True and good["closed_loop_stable"] is True
    assert bad["source"] == missing and bad["passed"] is False and missing in bad["error"]
    assert missing in captured.err and len(captured.err.strip().splitlines()) == 1
    suites = ET.parse(junit).getroot().findall("testsuite")
    assert [s.get("name") for s in suites] == [missing, "cam_follower"]
    assert missing in suites[0].find("testcase/error").get("message")
