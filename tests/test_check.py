"""``servo-toolkit design`` and ``check``: exit codes, table, JSON, JUnit."""

import json
import xml.etree.ElementTree as ET

from servo_toolkit.cli import main

from .conftest import SCENES

EMA = str(SCENES / "ema_reference.toml")
CAM = str(SCENES / "cam_follower.toml")


def test_check_passes_and_writes_junit(tmp_path, capsys):
    junit = tmp_path / "loop.xml"
    assert main(["check", EMA, CAM, "--junit", str(junit)]) == 0
    out = capsys.readouterr().out
    assert "all requirements met" in out
    root = ET.parse(junit).getroot()
    suites = root.findall("testsuite")
    assert [s.get("name") for s in suites] == ["ema_reference", "cam_follower"]
    names = [c.get("name") for c in suites[0].findall("testcase")]
    assert {"bandwidth", "gain_margin", "phase_margin", "sensitivity_peak", "closed_loop_stable"} <= set(names)
    assert not root.findall(".//failure")


def test_impossible_bandwidth_exits_1_with_a_table(tmp_path, capsys):
    junit = tmp_path / "loop.xml"
    assert main(["check", EMA, "--require", "bandwidth=200Hz", "--junit", str(junit)]) == 1
    out = capsys.readouterr().out
    line = next(l for l in out.splitlines() if l.strip().startswith("bandwidth"))
    assert ">= 200 Hz" in line and "FAIL" in line and "(override)" in line
    assert "some requirements NOT met" in out
    failures = ET.parse(junit).getroot().findall(".//testcase[failure]")
    assert "bandwidth" in [f.get("name") for f in failures]


def test_check_json(capsys):
    assert main(["check", EMA, "--json", "--require", "bandwidth=200Hz"]) == 1
    data = json.loads(capsys.readouterr().out)
    scene = data["scenes"][0]
    assert data["passed"] is False and scene["passed"] is False
    req = scene["requirements"]["bandwidth"]
    assert req["required"] == 200 and req["passed"] is False and req["achieved"] < 200
    for key in ("gain_margin_db", "phase_margin_deg", "delay_margin_s", "disk_margin", "sensitivity_peak_db",
                "bandwidth_hz", "phase_at_8hz_deg", "closed_loop_stable"):
        assert key in scene


def test_bad_input_exits_2(tmp_path, capsys):
    assert main(["check", str(tmp_path / "missing.toml")]) == 2
    assert main(["check", EMA, "--require", "bandwith=8Hz"]) == 2
    assert main(["check", str(SCENES / "deflection_platform.toml")]) == 2
    err = capsys.readouterr().err
    assert "require.bandwith" in err


def test_design_json(capsys):
    assert main(["design", CAM, "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["closed_loop_stable"] is True and data["plant"]["model"] == "rigid"
