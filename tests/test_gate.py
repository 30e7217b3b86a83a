"""The margin gate: an open-loop-unstable loop fails on its w = 0 gain margin, design exits 1
like check when a requirement fails, no state of stdout changes the verdict, and --junit
never overwrites what a user has."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from servo_toolkit.cli import main

from .conftest import ROOT, SCENES

HINGE_ARGS = ["--structure", "lead_lag", "--require", "bandwidth=2Hz", "--require", "phase_lag=100deg",
              "--require", "pm=30deg", "--require", "ms=8dB"]


@pytest.fixture(scope="module")
def hinge_scene(tmp_path_factory) -> Path:
    """The reference EMA on a load with a negative hinge stiffness: an open-loop pole at
    about +19 rad/s, so lowering the loop gain destabilizes it (L(0) < 0)."""
    text = (SCENES / "ema_reference.toml").read_text()
    lines = [('hinge_stiffness = "-2000 N*m/rad"' if ln.startswith("hinge_stiffness") else ln)
             for ln in text.splitlines()]
    path = tmp_path_factory.mktemp("hinge") / "hinge.toml"
    path.write_text("\n".join(lines) + "\n")
    return path


def test_open_loop_unstable_design_fails_on_its_low_frequency_gain_margin(hinge_scene, capsys):
    assert main(["check", str(hinge_scene), *HINGE_ARGS, "--json"]) == 1
    import json
    out = json.loads(capsys.readouterr().out)
    scene = out["scenes"][0]
    margins = scene["margins"]
    assert margins["open_loop_rhp_poles"] >= 1
    assert 0.0 in margins["phase_crossover_hz"]  # the crossing at w = 0 is a margin
    assert not scene["requirements"]["gain_margin"]["passed"]
    assert scene["requirements"]["gain_margin"]["achieved"] < 6.0


def test_design_exits_1_when_a_requirement_fails(hinge_scene, capsys):
    assert main(["design", str(hinge_scene), *HINGE_ARGS]) == 1
    assert main(["design", str(SCENES / "ema_reference.toml")]) == 0
    capsys.readouterr()


def _cli(args, **kw):
    return subprocess.Popen([sys.executable, "-m", "servo_toolkit", *args], cwd=ROOT, stderr=subprocess.PIPE,
                            env={**os.environ, "MPLBACKEND": "Agg"}, **kw)


def test_a_closed_pipe_never_changes_the_verdict(hinge_scene):
    proc = _cli(["check", str(hinge_scene), *HINGE_ARGS, "--json"], stdout=subprocess.PIPE)
    proc.stdout.close()  # the reader goes away at once (`| true`)
    _, err = proc.communicate(timeout=300)
    assert proc.returncode == 1
    assert b"Traceback" not in err


def test_a_full_disk_on_stdout_is_one_line_and_exit_2():
    if not os.path.exists("/dev/full"):
        pytest.skip("no /dev/full on this system")
    with open("/dev/full", "w") as full:
        proc = _cli(["stiffness", str(SCENES / "ema_reference.toml"), "--json"], stdout=full)
        _, err = proc.communicate(timeout=120)
    assert proc.returncode == 2
    lines = err.decode().strip().splitlines()
    assert len(lines) == 1 and "stdout" in lines[0] and "Traceback" not in lines[0]


def test_junit_refuses_an_input_scene(tmp_path, capsys):
    scene = tmp_path / "cam.toml"
    original = (SCENES / "cam_follower.toml").read_text()
    scene.write_text(original)
    assert main(["check", str(scene), str(SCENES / "ema_reference.toml"), "--junit", str(scene)]) == 2
    assert scene.read_text() == original
    assert "junit" in capsys.readouterr().err


def test_junit_refuses_an_existing_file_that_is_not_junit_and_replaces_an_earlier_report(tmp_path, capsys):
    notes = tmp_path / "notes.txt"
    notes.write_text("my notes\n")
    ema = str(SCENES / "ema_reference.toml")
    assert main(["check", ema, "--junit", str(notes)]) == 2
    assert notes.read_text() == "my notes\n"
    report = tmp_path / "margins.xml"
    assert main(["check", ema, "--junit", str(report)]) == 0
    first = report.read_text()
    assert "<testsuites" in first
    assert main(["check", ema, "--junit", str(report)]) == 0  # an earlier report is replaced
    assert sorted(p.name for p in tmp_path.iterdir()) == ["margins.xml", "notes.txt"]  # no temporary left
    capsys.readouterr()
