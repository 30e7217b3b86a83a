"""``servo-toolkit export``: files, JSON, exit codes, output-path checks."""

from __future__ import annotations

import json

import pytest

from servo_toolkit.cli import main

from .conftest import SCENES

EMA = SCENES / "ema_reference.toml"


def test_export_writes_the_folder_and_one_json_object(tmp_path, capsys):
    out = tmp_path / "drive" / "ctrl"
    assert main(["export", str(EMA), "-o", str(out), "--fixed-point", "q31", "--json"]) == 0
    cap = capsys.readouterr()
    data = json.loads(cap.out)  # exactly one object, nothing else
    assert data["passed"] and data["format"] == "q31" and data["directory"] == str(out)
    assert sorted(p.name for p in out.iterdir()) == ["controller.json", "servo_controller.c", "servo_controller.h"]
    written = json.loads((out / "controller.json").read_text())
    assert written["quantized"]["closed_loop_stable"] is True
    assert written["motion"] == data["motion"]
    # no temporary folder left beside it
    assert [p.name for p in out.parent.iterdir()] == ["ctrl"]
    # a second export replaces the files in place
    assert main(["export", str(EMA), "-o", str(out)]) == 0
    assert json.loads((out / "controller.json").read_text())["format"] == "float64"
    assert "Controller export of ema_reference" in capsys.readouterr().out


def test_output_that_is_a_file_is_refused(tmp_path, capsys):
    target = tmp_path / "file.txt"
    target.write_text("keep")
    assert main(["export", str(EMA), "-o", str(target)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("servo-toolkit: error: -o:")
    assert target.read_text() == "keep"


def test_never_overwrites_its_input(tmp_path, capsys):
    scene = tmp_path / "controller.json"
    scene.write_text(EMA.read_text())  # a scene that happens to bear an output's name
    before = scene.read_text()
    assert main(["export", str(scene), "-o", str(tmp_path)]) == 2
    assert "overwrite its input" in capsys.readouterr().err
    assert scene.read_text() == before


@pytest.mark.skipif(__import__("os").geteuid() == 0, reason="root writes into read-only folders")
def test_unwritable_folder_fails_before_work(tmp_path, capsys):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        assert main(["export", str(EMA), "-o", str(ro / "out")]) == 2
        assert "cannot write" in capsys.readouterr().err
    finally:
        ro.chmod(0o700)


def test_bad_options_name_the_option(tmp_path, capsys):
    assert main(["export", str(EMA), "-o", str(tmp_path / "o"), "--current-sample-time", "1 s"]) == 2
    assert capsys.readouterr().err.startswith("servo-toolkit: error: --current-sample-time:")
    assert not (tmp_path / "o").exists()
    with pytest.raises(SystemExit) as exc:
        main(["export", str(EMA), "-o", str(tmp_path / "o"), "--fixed-point", "q7"])
    assert exc.value.code == 2


def test_q15_holds_the_notch_near_z1_and_exits_0(tmp_path, capsys):
    """At 20 us the notch poles sit within 5e-3 of z = 1; stored about z = 1, Q15 holds them
    (a direct-form Q15 section turned the notch's zeros real and exited 1)."""
    scene = tmp_path / "fast.toml"
    text = EMA.read_text()
    assert 'sample_time = "0.1 ms"' in text
    scene.write_text(text.replace('sample_time = "0.1 ms"', 'sample_time = "20 us"'))
    assert main(["export", str(scene), "-o", str(tmp_path / "q15"), "--fixed-point", "q15", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["passed"] is True and not data["quantized"]["failures"]


def test_quantization_that_costs_a_requirement_exits_1(tmp_path, capsys, monkeypatch):
    """One-bit coefficients (a power of two each) cost the 66 deg of phase margin required."""
    import importlib
    qmod = importlib.import_module("servo_toolkit.export.quantize")
    monkeypatch.setitem(qmod.FORMATS, "q15", (1, 15, 16))
    args = ["export", str(EMA), "--require", "phase_margin=66", "--fixed-point", "q15"]
    assert main([*args, "-o", str(tmp_path / "q15"), "--json"]) == 1
    cap = capsys.readouterr()
    data = json.loads(cap.out)
    assert data["passed"] is False and data["quantized"]["failures"]
    assert "servo-toolkit: export: " in cap.err
    assert main(["export", str(EMA), "-o", str(tmp_path / "q31"), "--fixed-point", "q31"]) == 0


def test_output_below_a_file_is_refused(tmp_path, capsys):
    blocker = tmp_path / "plain"
    blocker.write_text("")
    assert main(["export", str(EMA), "-o", str(blocker / "sub" / "out")]) == 2
    assert "cannot write into" in capsys.readouterr().err


def test_a_failed_write_leaves_nothing_behind(tmp_path, monkeypatch):
    """Written in a temporary sibling and renamed: a failure half-way leaves no folder and no
    temporary files."""
    from servo_toolkit.core import files
    from servo_toolkit.errors import SceneError
    from servo_toolkit.export import writer

    calls = []

    def failing_fsync(fd):
        calls.append(fd)
        if len(calls) == 2:
            raise OSError("disk full")

    monkeypatch.setattr(files.os, "fsync", failing_fsync)
    with pytest.raises(SceneError, match="disk full"):
        writer.write_files(tmp_path / "out", {"a.txt": "1", "b.txt": "2"})
    assert list(tmp_path.iterdir()) == []
    # into an existing folder: the files already there stay as they were
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "a.txt").write_text("old")
    calls.clear()
    with pytest.raises(SceneError, match="disk full"):
        writer.write_files(tmp_path / "out", {"a.txt": "1", "b.txt": "2"})
    assert [p.name for p in tmp_path.iterdir()] == ["out"]
    assert (tmp_path / "out" / "a.txt").read_text() == "old"


def test_export_of_an_unstable_design_says_so_and_exits_1(tmp_path, capsys):
    """At Ts = 1 s the reference EMA's cascade cannot hold its drivetrain: its own closed
    loop has poles in the right half-plane (python-control's poles, independent of the
    export); the float export writes the files yet fails and says why."""
    import control as ct

    from servo_toolkit import design, load_scene
    from servo_toolkit.loop import linear_closed_loop
    out = tmp_path / "drive"
    assert main(["export", str(EMA), "-o", str(out), "--sample-time", "1 s", "--json"]) == 1
    cap = capsys.readouterr()
    data = json.loads(cap.out)
    assert data["passed"] is False and data["design"]["closed_loop_stable"] is False
    assert "unstable" in data["failures"][0]
    assert "designed closed loop (without quantization) is unstable" in cap.err
    written = json.loads((out / "controller.json").read_text())
    assert written["passed"] is False and written["design"]["closed_loop_stable"] is False
    from dataclasses import replace
    scene = load_scene(EMA)
    scene = replace(scene, sensors=replace(scene.sensors, sample_time=1.0))
    d = design(scene)
    poles = ct.poles(linear_closed_loop(scene, d.controller, d.q0)["theta", "theta_ref"])
    assert max(poles.real) > 0


def test_float_export_of_a_design_missing_a_requirement_exits_1(tmp_path, capsys):
    """A floating-point export judges the design's requirements as the fixed-point one does:
    the reference EMA's cascade against a 40 dB gain margin (its design reaches about 20 dB)
    writes the files, names every row ``design`` misses with the same requirement (the gain
    margin with the design's own figure) and exits 1."""
    out = tmp_path / "drive"
    assert main(["design", str(EMA), "--require", "gain_margin=40", "--json"]) == 1
    designed = json.loads(capsys.readouterr().out)
    gm = designed["gain_margin_db"]
    assert designed["requirements"]["gain_margin"]["passed"] is False and gm < 40
    assert main(["export", str(EMA), "--require", "gain_margin=40", "-o", str(out), "--json"]) == 1
    cap = capsys.readouterr()
    data = json.loads(cap.out)
    assert data["passed"] is False and data["design"]["closed_loop_stable"] is True
    assert data["design"]["gain_margin_db"] == pytest.approx(gm, rel=1e-9)
    missed = [k for k, c in designed["requirements"].items() if not c["passed"]]
    assert [r.split(":")[0] for r in data["failures"]] == missed  # every row design misses, no other
    row = f"gain_margin: the design misses it ({gm:.4g} dB, required >= 40 dB)"
    assert row in data["failures"] and f"servo-toolkit: export: {row}" in cap.err
    written = json.loads((out / "controller.json").read_text())
    assert written["passed"] is False and written["failures"] == data["failures"]
    assert (out / "servo_controller.c").is_file()
