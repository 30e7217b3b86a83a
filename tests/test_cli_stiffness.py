"""The stiffness command and the CLI error contract."""

import json
import subprocess
import sys

import pytest

from servo_toolkit.cli import main

from .conftest import SCENES

EMA = str(SCENES / "ema_reference.toml")


def test_stiffness_json(capsys):
    assert main(["stiffness", EMA, "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["angles_deg"] == [-30, 0, 10, 30]
    assert {"angles_deg", "stages", "total_Nm_per_rad", "total_Nm_per_deg", "ratio",
            "reflected_inertia_kg_m2"} <= set(data)
    names = [s["name"] for s in data["stages"]]
    assert names == ["spur gear train", "ball screw", "link rod and rocker arm", "housing"]
    for i in range(4):
        assert sum(s["share"][i] for s in data["stages"]) == pytest.approx(1)
        assert data["total_Nm_per_deg"][i] == pytest.approx(data["total_Nm_per_rad"][i] * 3.141592653589793 / 180)


def test_stiffness_table_with_angles(capsys):
    assert main(["stiffness", EMA, "--angle", "5", "--angle", "-5"]) == 0
    out = capsys.readouterr().out
    assert "+5.0 deg" in out and "-5.0 deg" in out and "series total" in out


def test_bad_scene_exits_2_with_one_line(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text((SCENES / "ema_reference.toml").read_text().replace('lead = "5 mm"', 'lead = "0 mm"'))
    proc = subprocess.run([sys.executable, "-m", "servo_toolkit", "stiffness", str(bad)],
                          capture_output=True, text=True)
    assert proc.returncode == 2
    assert proc.stdout == ""
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "drivetrain[1].lead" in lines[0] and "must be positive" in lines[0]
