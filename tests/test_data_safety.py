"""Nothing a user has is lost: every output path is checked before work and written
atomically, every input is a bounded read of a regular file (servo_toolkit.core.files)."""

from __future__ import annotations

import errno
import os
import signal
import stat
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest

from servo_toolkit.core import files, folders, inputs
from servo_toolkit.cli import main
from servo_toolkit.errors import SceneError

from .conftest import SCENES

EMA = SCENES / "ema_reference.toml"
ROOT = Path(__file__).resolve().parents[1]


def _one_line(capsys, key=None):
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("servo-toolkit: error: "), err
    if key is not None:
        assert f" {key}: " in err[0], err
    assert "Traceback" not in err[0]
    return err[0]


def _fake_result():
    from servo_toolkit.sim.result import SimulationResult
    t = np.linspace(0.0, 0.01, 5)
    z = np.zeros_like(t)
    return SimulationResult(t, np.zeros((5, 1)), ("output_angle_rad",), z, z, z, z, z, z, 0.0, 0.0, "rk4", 1e-4)


@pytest.fixture
def no_run(monkeypatch):
    """The simulation must not start: a refused output is refused before any work."""
    import servo_toolkit.studies.time.run as time_run

    def forbidden(*args, **kwargs):
        raise AssertionError("the run started before the output path was refused")
    monkeypatch.setattr(time_run, "simulate_study", forbidden)


@pytest.fixture
def fake_run(monkeypatch):
    """A simulation that returns at once (the output handling is what is tested)."""
    import servo_toolkit.studies.time.run as time_run
    monkeypatch.setattr(time_run, "simulate_study", lambda *a, **k: _fake_result())


def _scene_copy(tmp_path, name="ema.toml") -> Path:
    scene = tmp_path / name
    scene.write_text(EMA.read_text())
    return scene


# --- simulate -o ------------------------------------------------------------------------------

def test_simulate_refuses_a_symlink_to_its_scene(tmp_path, capsys, no_run):
    scene = _scene_copy(tmp_path)
    before = scene.read_text()
    link = tmp_path / "link.csv"
    link.symlink_to(scene.name)
    assert main(["simulate", str(scene), "-o", str(link)]) == 2
    assert "input" in _one_line(capsys, "--output")
    assert scene.read_text() == before and link.is_symlink()


def test_simulate_refuses_its_own_scene_and_a_hard_link_to_it(tmp_path, capsys, no_run):
    scene = _scene_copy(tmp_path, "scene.csv")
    before = scene.read_text()
    assert main(["simulate", str(scene), "-o", str(scene)]) == 2
    assert "input" in _one_line(capsys, "--output")
    hard = tmp_path / "hard.csv"
    os.link(scene, hard)
    assert main(["simulate", str(scene), "-o", str(hard)]) == 2
    assert "input" in _one_line(capsys, "--output")
    assert scene.read_text() == before


def test_simulate_never_writes_through_a_symlink(tmp_path, capsys, no_run):
    notes = tmp_path / "notes.txt"
    notes.write_text("mine\n")
    link = tmp_path / "traces.csv"
    link.symlink_to(notes)
    assert main(["simulate", str(EMA), "-o", str(link)]) == 2
    assert "symbolic link" in _one_line(capsys, "--output")
    assert notes.read_text() == "mine\n" and link.is_symlink()


def test_simulate_on_a_full_disk_keeps_the_old_traces(tmp_path, capsys, fake_run, monkeypatch):
    traces = tmp_path / "traces.csv"
    traces.write_text("old traces\n")

    def full(fd):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    monkeypatch.setattr(files.os, "fsync", full)
    assert main(["simulate", str(EMA), "-o", str(traces)]) == 2
    assert os.strerror(errno.ENOSPC) in _one_line(capsys, "--output")
    assert traces.read_text() == "old traces\n"
    assert os.listdir(tmp_path) == ["traces.csv"]  # no temporary left


def test_simulate_writes_csv_and_npz(tmp_path, capsys, fake_run):
    for name in ("traces.csv", "traces.npz"):
        assert main(["simulate", str(EMA), "-o", str(tmp_path / name)]) == 0
    assert (tmp_path / "traces.csv").read_text().startswith("t_s,output_angle_rad")
    assert set(np.load(tmp_path / "traces.npz").files) >= {"t_s", "output_angle_rad"}
    assert sorted(os.listdir(tmp_path)) == ["traces.csv", "traces.npz"]
    capsys.readouterr()


def test_a_read_only_target_is_refused_before_the_run(tmp_path, capsys, no_run):
    traces = tmp_path / "traces.csv"
    traces.write_text("keep\n")
    traces.chmod(0o444)
    assert main(["simulate", str(EMA), "-o", str(traces)]) == 2  # even as root
    assert "read-only" in _one_line(capsys, "--output")
    assert traces.read_text() == "keep\n"


def test_simulate_refuses_a_fifo(tmp_path, capsys, no_run):
    fifo = tmp_path / "traces.csv"
    os.mkfifo(fifo)
    assert main(["simulate", str(EMA), "-o", str(fifo)]) == 2
    assert "regular file" in _one_line(capsys, "--output")
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)


# --- special files as outputs -----------------------------------------------------------------

def test_junit_onto_a_special_file_is_refused_and_left_as_it_is(tmp_path, capsys, monkeypatch):
    import servo_toolkit.cli.cmd_check as cmd_check

    def no_design(*args, **kwargs):
        raise AssertionError("designed before checking the --junit path")
    monkeypatch.setattr(cmd_check, "design_from_args", no_design)
    fifo = tmp_path / "loop.xml"
    os.mkfifo(fifo)
    assert main(["check", str(EMA), "--junit", str(fifo)]) == 2
    assert "regular file" in _one_line(capsys, "--junit")
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)


def test_a_character_device_is_refused_by_the_check_alone():
    """The check reads only the path's status: nothing is written to the device."""
    with pytest.raises(SceneError, match="regular file"):
        files.check_output_file("/dev/null", "junit")
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode)


def test_sweep_plot_onto_a_fifo_is_refused_before_the_sweep(tmp_path, capsys, monkeypatch):
    import servo_toolkit.studies.sweep.compute as sweep_mod

    def forbidden(*args, **kwargs):
        raise AssertionError("swept before checking --plot")
    monkeypatch.setattr(sweep_mod, "sweep", forbidden)
    fifo = tmp_path / "sweep.png"
    os.mkfifo(fifo)
    assert main(["sweep", str(EMA), "--plot", str(fifo)]) == 2
    assert "regular file" in _one_line(capsys, "--plot")
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)


def test_symlinked_output_folders_are_refused(tmp_path):
    real = tmp_path / "real"
    real.mkdir()
    (tmp_path / "out").symlink_to(real)
    with pytest.raises(SceneError, match="symbolic link"):
        files.check_output_folder(tmp_path / "out", "-o")


# --- bounded reads of inputs ------------------------------------------------------------------

@pytest.mark.parametrize("command", [["fit", str(EMA), "{}", "--param", "load.inertia"],
                                     ["design", str(EMA), "--design", "{}"],
                                     ["check", str(EMA), "--design", "{}"],
                                     ["tolerances", str(SCENES / "examples" / "ema_tolerances.toml"), "--design", "{}"]],
                         ids=["fit", "design", "check", "tolerances"])
def test_a_fifo_input_does_not_block(command, tmp_path):
    """Refused in one line before any work, so the command ends in seconds."""
    fifo = tmp_path / "input.csv"
    os.mkfifo(fifo)
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    argv = [a.format(fifo) for a in command]
    proc = subprocess.run([sys.executable, "-m", "servo_toolkit", *argv], cwd=ROOT, env=env, capture_output=True,
                          text=True, timeout=60)
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2 and len(lines) == 1, proc.stderr
    assert str(fifo) in lines[0] and "regular file" in lines[0]


def test_fit_on_dev_zero_is_one_line(capsys):
    assert main(["fit", str(EMA), "/dev/zero", "--param", "load.inertia"]) == 2
    line = _one_line(capsys)
    assert "/dev/zero" in line and "regular file" in line


def test_fit_with_a_huge_csv_field_is_one_line(tmp_path, capsys):
    data = tmp_path / "huge.csv"
    data.write_text("frequency_hz,gain_db,phase_deg\n\"" + "1" * 300_000 + "\",0,0\n")
    assert main(["fit", str(EMA), str(data), "--param", "load.inertia"]) == 2
    line = _one_line(capsys)
    assert str(data) in line and "CSV" in line


def test_a_data_file_beyond_the_limit_is_refused(tmp_path):
    big = tmp_path / "big.csv"
    big.write_bytes(b"x" * 2000)
    with pytest.raises(SceneError, match="more than"):
        inputs.read_input_bytes(big, "(file)", 1000)
    assert inputs.read_input_bytes(big, "(file)", 2000) == b"x" * 2000


@pytest.mark.parametrize("make", ["zero", "folder", "nested", "binary"])
def test_design_file_reads_are_one_line(make, tmp_path, capsys):
    path = {"zero": Path("/dev/zero"), "folder": tmp_path, "nested": tmp_path / "n.json",
            "binary": tmp_path / "b.json"}[make]
    if make == "nested":
        path.write_text("[" * 100_000 + "]" * 100_000)
    elif make == "binary":
        path.write_bytes(b"{\xff\xfe}")
    assert main(["design", str(EMA), "--design", str(path)]) == 2
    line = _one_line(capsys, "--design")
    rule = {"zero": "regular file", "folder": "directory", "nested": "nested too deeply", "binary": "UTF-8"}[make]
    assert rule in line


# --- report and export folders ----------------------------------------------------------------

def _tiny_report():
    from servo_toolkit.report.builder import Report
    return Report("tiny", "a tiny report", (), ())


def _earlier_report(folder: Path) -> dict:
    """A folder as an earlier report leaves it (the marks it is told by, dummy content)."""
    folder.mkdir()
    (folder / "index.html").write_text('<meta name="generator" content="servo_toolkit 0">old html')
    (folder / "report.pdf").write_text("%PDF- old pdf")
    return {p.name: p.read_text() for p in folder.iterdir()}


@pytest.fixture
def quick_report(monkeypatch):
    """``report`` with the tiny report instead of building the scene's sections."""
    import servo_toolkit.report as report_pkg
    monkeypatch.setattr(report_pkg, "build_report", lambda *a, **k: _tiny_report())


def test_interrupted_report_keeps_the_old_one(tmp_path, capsys, monkeypatch, quick_report):
    import servo_toolkit.report.pdf_writer as pdf_writer
    out = tmp_path / "rep"
    old = _earlier_report(out)

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt
    monkeypatch.setattr(pdf_writer, "write_pdf", interrupted)
    assert main(["report", str(EMA), "-o", str(out)]) == 130
    assert {p.name: p.read_text() for p in out.iterdir()} == old
    assert os.listdir(tmp_path) == ["rep"]  # no .rep.* temporary left
    capsys.readouterr()


def test_report_never_swaps_away_its_input(tmp_path, capsys, quick_report):
    out = tmp_path / "rep"
    out.mkdir()
    scene = out / "index.html"  # a scene that bears a report file's name, inside the folder
    scene.write_text(EMA.read_text())
    assert main(["report", str(scene), "-o", str(out)]) == 2
    assert "input" in _one_line(capsys, "--output")
    assert scene.read_text() == EMA.read_text()


def test_ctrl_c_while_publishing_is_delivered_after_the_swap(tmp_path, monkeypatch):
    """Without renameat2 the swap takes two renames; Ctrl-C between them waits for both."""
    monkeypatch.setattr(folders, "_exchange", lambda a, b: "unsupported")
    real_rename = os.rename
    sent = []

    def rename(a, b):
        real_rename(a, b)
        if ".old." in str(b) and not sent:  # the old output just moved aside
            sent.append(b)
            signal.raise_signal(signal.SIGINT)
    monkeypatch.setattr(files.os, "rename", rename)
    out = tmp_path / "rep"
    _earlier_report(out)
    with pytest.raises(KeyboardInterrupt):
        with folders.atomic_folder(out) as tmp:
            (tmp / "index.html").write_text("new html")
            (tmp / "report.pdf").write_text("new pdf")
    assert sent and (out / "index.html").read_text() == "new html"
    assert os.listdir(tmp_path) == ["rep"]


def test_a_failed_output_leaves_no_folder_it_made_above_it(tmp_path):
    """An output into missing folders (``export -o a/b/c``) makes them; when it fails they go
    again, those another writer has put something in stay."""
    with pytest.raises(RuntimeError):
        with folders.atomic_folder(tmp_path / "a" / "b" / "c", parents=True) as tmp:
            (tmp / "controller.json").write_text("{}")
            raise RuntimeError("the export failed")
    assert os.listdir(tmp_path) == []
    with pytest.raises(RuntimeError):
        with folders.atomic_folder(tmp_path / "a" / "b" / "c", parents=True) as tmp:
            (tmp_path / "a" / "theirs.txt").write_text("kept")
            raise RuntimeError("the export failed")
    assert sorted(os.listdir(tmp_path / "a")) == ["theirs.txt"]
    with folders.atomic_folder(tmp_path / "x" / "y", parents=True) as tmp:
        (tmp / "controller.json").write_text("{}")
    assert (tmp_path / "x" / "y" / "controller.json").read_text() == "{}"


def _export_set(text) -> dict:
    """An export's files as an earlier export leaves them (its marks), each ending in ``text``."""
    from servo_toolkit.export.writer import FILES, MARKS
    return {name: f"{MARKS[name].decode()} {text}" for name in FILES}


@pytest.mark.parametrize("exchange", [True, False], ids=["renameat2", "two-renames"])
def test_two_writers_leave_one_complete_set(tmp_path, monkeypatch, exchange):
    from servo_toolkit.export.writer import FILES, write_files
    if not exchange:
        monkeypatch.setattr(folders, "_exchange", lambda a, b: "unsupported")
    out = tmp_path / "ctrl"
    start = threading.Barrier(6)
    errors = []

    def writer(n):
        try:
            start.wait()
            for _ in range(5):
                write_files(out, _export_set(n))
        except BaseException as exc:  # noqa: BLE001 - the test reports it
            errors.append(exc)
    threads = [threading.Thread(target=writer, args=(n,)) for n in range(6)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert errors == []
    contents = {p.name: p.read_text() for p in out.iterdir()}
    assert sorted(contents) == sorted(FILES) and len({c.split()[-1] for c in contents.values()}) == 1
    assert os.listdir(tmp_path) == ["ctrl"]


def test_a_failed_export_into_an_existing_folder_keeps_the_old_set(tmp_path):
    from servo_toolkit.export.writer import FILES, write_files
    out = tmp_path / "ctrl"
    write_files(out, _export_set("old"))
    bad = {**_export_set("new"), FILES[1]: None}  # the second file cannot be written
    with pytest.raises(TypeError):
        write_files(out, bad)
    assert {p.name: p.read_text() for p in out.iterdir()} == _export_set("old")
    assert os.listdir(tmp_path) == ["ctrl"]
    write_files(out, _export_set("new"))  # a complete new set, no mix
    assert {p.name: p.read_text() for p in out.iterdir()} == _export_set("new")


def test_a_failure_while_publishing_an_export_keeps_the_old_set(tmp_path, monkeypatch):
    """The second rename (or replace) of the publication fails: the old set stays whole."""
    from servo_toolkit.export.writer import write_files
    out = tmp_path / "ctrl"
    write_files(out, _export_set("old"))
    monkeypatch.setattr(folders, "_exchange", lambda a, b: "unsupported")
    calls = []

    def failing(real):
        def move(a, b):
            calls.append((a, b))
            if len(calls) == 2:
                raise OSError(errno.EIO, os.strerror(errno.EIO))
            return real(a, b)
        return move
    monkeypatch.setattr(os, "rename", failing(os.rename))
    monkeypatch.setattr(os, "replace", failing(os.replace))
    with pytest.raises((SceneError, OSError)):
        write_files(out, _export_set("new"))
    monkeypatch.undo()
    assert len(calls) == 2  # the publication ran and failed at its second rename
    assert {p.name: p.read_text() for p in out.iterdir()} == _export_set("old")
    assert os.listdir(tmp_path) == ["ctrl"]


def test_export_never_swaps_away_a_folder_with_other_files(tmp_path, capsys):
    out = tmp_path / "project"
    out.mkdir()
    (out / "main.c").write_text("int main(void) { return 0; }\n")
    assert main(["export", str(EMA), "-o", str(out)]) == 2
    assert "other files" in _one_line(capsys, "-o")
    assert [p.name for p in out.iterdir()] == ["main.c"]


def test_write_report_from_python_checks_and_swaps(tmp_path):
    from servo_toolkit.report import write_report
    keep = tmp_path / "notes"
    keep.mkdir()
    (keep / "mine.txt").write_text("mine")
    with pytest.raises(SceneError, match="other files"):
        write_report(_tiny_report(), keep)
    assert [p.name for p in keep.iterdir()] == ["mine.txt"]
    paths = write_report(_tiny_report(), tmp_path / "a" / "b")
    assert paths["html"].is_file() and paths["pdf"].is_file()


# --- modes follow the umask -------------------------------------------------------------------

@pytest.fixture
def umask_022():
    old = os.umask(0o022)
    yield
    os.umask(old)


def test_new_files_and_folders_follow_the_umask(tmp_path, umask_022):
    from servo_toolkit.report import write_report
    from servo_toolkit.export.writer import FILES, write_files
    files.write_text(tmp_path / "a.txt", "a")
    assert stat.S_IMODE(os.stat(tmp_path / "a.txt").st_mode) == 0o644
    write_report(_tiny_report(), tmp_path / "rep")
    assert stat.S_IMODE(os.stat(tmp_path / "rep").st_mode) == 0o755
    assert stat.S_IMODE(os.stat(tmp_path / "rep" / "index.html").st_mode) == 0o644
    write_files(tmp_path / "ctrl", {name: "x" for name in FILES})
    assert stat.S_IMODE(os.stat(tmp_path / "ctrl").st_mode) == 0o755
    # a replaced file keeps its own mode
    (tmp_path / "a.txt").chmod(0o600)
    files.write_text(tmp_path / "a.txt", "b")
    assert stat.S_IMODE(os.stat(tmp_path / "a.txt").st_mode) == 0o600
    assert (tmp_path / "a.txt").read_text() == "b"
