"""What the command line reads and writes: every file a scene is read from is an input of
the command (the points file of a ``[duty_cycle]`` is never replaced by an output, and a
calibrated scene written elsewhere never loses it); two figures of one run never share a
file; an option's error names the option as typed (``--samples``, not the scene's
``robustness.samples``); inputs saved as UTF-8 with a byte-order mark read as UTF-8; a
misspelt key's error lists the key it meant; a folder holding the user's own file of an
output's name (index.html, controller.json) is not taken for an earlier output."""

from __future__ import annotations

import pytest

from servo_toolkit.cli import main
from servo_toolkit.scene import load_scene

from .conftest import SCENES

EMA = SCENES / "ema_reference.toml"
POINTS = "t [s], position [deg]\n0, 0\n0.5, 5\n1.0, 0\n"
FRF = "frequency_hz,gain_db,phase_deg\n1,40,-90\n2,34,-91\n4,28,-92\n8,22,-95\n16,16,-100\n"


def _one_line(capsys, key):
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"servo-toolkit: error: {key}: "), err
    return err[0]


@pytest.fixture
def points_scene(tmp_path):
    """The reference EMA with a duty cycle whose one segment is the points file pts.csv."""
    (tmp_path / "pts.csv").write_text(POINTS)
    scene = tmp_path / "ema.toml"
    scene.write_text(EMA.read_text() + '\n[duty_cycle]\n[[duty_cycle.segments]]\nkind = "points"\nfile = "pts.csv"\n')
    return scene


def _forbid(monkeypatch, module, name):
    def forbidden(*args, **kwargs):
        raise AssertionError("the work started before the output was refused")
    monkeypatch.setattr(module, name, forbidden)


def test_the_scene_lists_its_points_file_among_its_inputs(points_scene):
    scene = load_scene(points_scene)
    assert scene.input_files == (str(points_scene), str(points_scene.parent / "pts.csv"))
    assert scene.duty_cycle.segments[0].file == "pts.csv"
    assert load_scene(EMA).input_files == (str(EMA),)


def test_simulate_never_overwrites_the_scene_s_points_file(points_scene, capsys, monkeypatch):
    import servo_toolkit.studies.time.run as time_run
    _forbid(monkeypatch, time_run, "simulate_study")
    pts = points_scene.parent / "pts.csv"
    assert main(["simulate", str(points_scene), "-o", str(pts)]) == 2
    assert "refusing to overwrite the input" in _one_line(capsys, "--output")
    assert pts.read_text() == POINTS


def test_fit_refuses_a_calibrated_scene_that_would_not_find_its_points_file(points_scene, capsys, monkeypatch):
    import servo_toolkit.identify as identify
    _forbid(monkeypatch, identify, "fit")
    data = points_scene.parent / "frf.csv"
    data.write_text(FRF)
    (points_scene.parent / "other").mkdir()
    out = points_scene.parent / "other" / "cal.toml"
    assert main(["fit", str(points_scene), str(data), "--param", "load.inertia", "-o", str(out)]) == 2
    assert "duty_cycle.segments[0].file 'pts.csv'" in _one_line(capsys, "-o")
    assert not out.exists() and list((points_scene.parent / "other").iterdir()) == []


def test_size_refuses_one_file_for_both_figures(tmp_path, capsys, monkeypatch):
    import servo_toolkit.studies.sizing as sizing
    _forbid(monkeypatch, sizing, "size")
    fig = tmp_path / "fig.png"
    assert main(["size", str(SCENES / "ema_sizing.toml"), "--plot", str(fig), "--sweep-plot", str(fig)]) == 2
    assert "another file than --plot" in _one_line(capsys, "--sweep-plot")
    assert not fig.exists()


@pytest.mark.parametrize("argv, key", [
    (["montecarlo", str(EMA), "--samples", "99999999"], "--samples"),
    (["montecarlo", str(EMA), "--seed", "-1"], "--seed"),
    (["check", str(EMA), "--linear-only", "--junit", str(SCENES)], "--junit"),
])
def test_an_option_s_error_names_the_option(argv, key, capsys):
    assert main(argv) == 2
    _one_line(capsys, key)


def test_a_utf8_byte_order_mark_is_read_as_utf8(tmp_path, capsys):
    """Spreadsheet programs and some editors start UTF-8 files with a byte-order mark."""
    scene = tmp_path / "ema.toml"
    scene.write_bytes(b"\xef\xbb\xbf" + EMA.read_bytes())
    assert load_scene(scene).name == load_scene(EMA).name
    from servo_toolkit.identify import read_data
    data = tmp_path / "frf.csv"
    data.write_bytes(b"\xef\xbb\xbf" + FRF.encode())
    assert list(read_data(data).frequency_hz) == [1, 2, 4, 8, 16]


def test_a_misspelt_optional_key_is_told_the_key_it_meant(tmp_path, capsys):
    """An optional key the scene leaves out (read only when present) is among the known keys
    the error lists, so the typo's correction is in the message."""
    scene = tmp_path / "typo.toml"
    scene.write_text(EMA.read_text().replace('bandwidth = "8 Hz"', 'bandwdth = "8 Hz"', 1))
    assert main(["stiffness", str(scene)]) == 2
    line = _one_line(capsys, f"{scene}: requirements.bandwdth")
    assert "unknown key" in line and "'bandwidth'" in line


def test_report_never_replaces_a_folder_holding_the_user_s_own_index_html(tmp_path, capsys, monkeypatch):
    import servo_toolkit.report as report
    _forbid(monkeypatch, report, "build_report")
    site = tmp_path / "site"
    site.mkdir()
    (site / "index.html").write_text("<html>my own page</html>\n")
    assert main(["report", str(EMA), "-o", str(site)]) == 2
    assert "index.html not written by this command" in _one_line(capsys, "--output")
    assert [p.name for p in site.iterdir()] == ["index.html"]
    assert (site / "index.html").read_text() == "<html>my own page</html>\n"


def test_report_never_replaces_a_folder_holding_only_the_user_s_own_report_pdf(tmp_path, capsys, monkeypatch):
    import servo_toolkit.report as report
    _forbid(monkeypatch, report, "build_report")
    docs = tmp_path / "docs"
    docs.mkdir()
    mine = b"%PDF-1.7\n%my own paper\n"
    (docs / "report.pdf").write_bytes(mine)
    assert main(["report", str(EMA), "-o", str(docs)]) == 2
    assert "without the index.html" in _one_line(capsys, "--output")
    assert [p.name for p in docs.iterdir()] == ["report.pdf"]
    assert (docs / "report.pdf").read_bytes() == mine


def test_export_never_replaces_a_folder_holding_the_user_s_own_controller_json(tmp_path, capsys):
    out = tmp_path / "ctl"
    out.mkdir()
    (out / "controller.json").write_text('{"mine": 1}\n')
    assert main(["export", str(EMA), "-o", str(out)]) == 2
    assert "controller.json not written by this command" in _one_line(capsys, "-o")
    assert [p.name for p in out.iterdir()] == ["controller.json"]
    assert (out / "controller.json").read_text() == '{"mine": 1}\n'
    again = tmp_path / "again"  # an earlier export carries its marks: it is replaced
    assert main(["export", str(EMA), "-o", str(again)]) == 0
    assert main(["export", str(EMA), "-o", str(again)]) == 0


@pytest.mark.parametrize("args, key", [(["report", "-o", ""], "--output"), (["simulate", "-o", ""], "--output"),
                                       (["export", "-o", ""], "-o"), (["sweep", "--plot", " "], "--plot")])
def test_an_empty_output_path_is_one_line_not_the_current_folder(args, key, capsys):
    """``-o "$OUT"`` with OUT unset names no output: refused before any work, never read as
    the current folder."""
    from servo_toolkit.cli import main
    assert main([args[0], str(SCENES / "ema_reference.toml"), *args[1:]]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{key}: is empty: give the" in err[0], err
