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
    # the stability row is a row of the table: its verdict in the column of the others'
    rows = out.split("requirement", 1)[1].splitlines()[1:]
    rows = rows[:next(k for k, r in enumerate(rows) if r.strip().startswith("closed_loop_stable")) + 1]
    assert len({r.index(" ok") if " ok" in r else r.index(" FAIL") for r in rows}) == 1, rows
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
    err = capsys.readouterr().err
    assert "servo-toolkit: error: --require bandwith=8Hz: unknown requirement" in err


def test_design_json(capsys):
    assert main(["design", CAM, "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["closed_loop_stable"] is True and data["plant"]["model"] == "rigid"


ROBUST = str(SCENES / "ema_robust.toml")


def test_robustness_requirement_exit_1_and_junit(tmp_path, capsys):
    # the nominal design over the scene's [robustness]: most variants unstable -> exit 1
    junit = tmp_path / "robust.xml"
    assert main(["check", ROBUST, "--nominal", "--junit", str(junit)]) == 1
    out = capsys.readouterr().out
    line = next(l for l in out.splitlines() if "worst stable_fraction" in l)
    assert "FAIL" in line and "at load_inertia = " in line and " kg*m^2, stiffness = " in line and "x nominal" in line
    suite = ET.parse(junit).getroot().find("testsuite")
    cases = {c.get("name"): c for c in suite.findall("testcase")}
    robust = {"robust_stable_fraction", "robust_gain_margin", "robust_phase_margin", "robust_sensitivity_peak"}
    assert robust <= set(cases)
    assert cases["robust_stable_fraction"].find("failure") is not None
    assert "worst case over 1000 variants" in cases["robust_stable_fraction"].find("failure").get("message")


def test_robust_design_passes_check_with_exit_0(tmp_path, capsys):
    # robust design (the scene has [robustness]) with a bandwidth its variants allow; the
    # linear rows only: the robust rows are what this test is about (the large-signal rows run
    # the lossy chain's nonlinear loop, see test_gate.py)
    junit = tmp_path / "robust.xml"
    assert main(["check", ROBUST, "--require", "bandwidth=7Hz", "--linear-only", "--json", "--junit",
                 str(junit)]) == 0
    data = json.loads(capsys.readouterr().out)
    rb = data["scenes"][0]["robustness"]
    assert data["passed"] is True and rb["passed"] is True and rb["unstable_variants"] == 0
    for name in ("stable_fraction", "gain_margin", "phase_margin", "sensitivity_peak"):
        worst = rb["worst"][name]
        assert worst["passed"] is True and set(worst["at"]) == {"load_inertia", "stiffness"}
    assert rb["worst"]["gain_margin"]["achieved"] >= 6.0
    root = ET.parse(junit).getroot()
    names = [c.get("name") for c in root.iter("testcase")]
    assert "robust_phase_margin" in names and not root.findall(".//failure")


def test_vary_and_samples_override(capsys):
    assert main(["check", EMA, "--vary", "stiffness=0.95:1.05", "--samples", "40", "--json"]) in (0, 1)
    rb = json.loads(capsys.readouterr().out)["scenes"][0]["robustness"]
    assert rb["variants"] == 40 and list(rb["ranges"]) == ["stiffness"]
    assert 0.95 <= rb["ranges"]["stiffness"][0] <= rb["ranges"]["stiffness"][1] <= 1.05
    assert main(["check", EMA, "--vary", "stiffness=0:1"]) == 2
    assert main(["check", EMA, "--vary", "mass=0:1"]) == 2
