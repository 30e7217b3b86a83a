"""Nothing a user has is overwritten: an output file replaces an existing one only when that
is an earlier output of the same command, told by its content (a text output's stamped
digest, a figure's metadata); anything else is one line naming the option, exit 2, before
any work, and the file keeps its content."""

from __future__ import annotations

import matplotlib
import pytest

from servo_toolkit.cli import main
from servo_toolkit.core import marks
from servo_toolkit.core.files import save_figure

from .conftest import SCENES

matplotlib.use("Agg")

EMA = str(SCENES / "ema_reference.toml")


def _refused(argv, path, option, capsys):
    before = path.read_bytes()
    assert main([str(a) for a in argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{option}: refusing to overwrite" in err[0] and "give a new file name" in err[0], err
    assert path.read_bytes() == before


def test_a_stamp_tells_an_unchanged_output_of_its_command(tmp_path):
    path = tmp_path / "out.csv"
    text = "# period_samples: 4\ntime_s,current_A,motor_angle_rad\n0,1,2\n"
    path.write_text(marks.stamp(text, "excite"))
    assert marks.stamped_by(path, "excite") and not marks.stamped_by(path, "frf")
    path.write_text(marks.stamp(text, "excite").replace("0,1,2", "0,1,2.001"))  # a rig's measurement
    assert not marks.stamped_by(path, "excite")
    path.write_text(text)
    assert not marks.stamped_by(path, "excite")


@pytest.mark.parametrize("suffix, marked", [(".png", True), (".svg", True), (".pdf", True), (".eps", True),
                                            (".jpg", False)])
def test_a_figure_the_toolkit_saves_carries_its_mark(suffix, marked, tmp_path):
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots()
    ax.plot([0, 1], [0, 1])
    path = save_figure(fig, tmp_path / f"f{suffix}")
    plt.close(fig)
    assert marks.figure_marked(path) is marked
    other = tmp_path / f"g{suffix}"
    fig, ax = plt.subplots()
    fig.savefig(other)  # matplotlib's own, not the toolkit's
    plt.close(fig)
    assert not marks.figure_marked(other)


@pytest.mark.parametrize("argv, option", [
    (["excite", EMA, "-o", "{f}.csv"], "-o"),
    (["excite", EMA, "--plot", "{f}.png"], "--plot"),
    (["size", EMA, "--plot", "{f}.png"], "--plot"),
    (["size", EMA, "--sweep-plot", "{f}.png"], "--sweep-plot"),
    (["reduce", EMA, "--plot", "{f}.png"], "--plot"),
    (["sweep", EMA, "--plot", "{f}.png"], "--plot"),
    (["sweep", EMA, "--method", "multisine", "--band", "2:50", "-o", "{f}.csv"], "-o"),
    (["sweep", EMA, "--method", "multisine", "--band", "2:50", "--log", "{f}.csv"], "--log"),
    (["fit", EMA, "{data}", "--param", "load.inertia", "-o", "{f}.toml"], "-o"),
    (["frf", "{data}", "-o", "{f}.csv"], "-o"),
])
def test_a_users_file_is_refused_before_any_work(argv, option, tmp_path, capsys):
    """A file of the user's at the output path (here one holding ``keep``) stays as it is."""
    data = tmp_path / "data.csv"
    data.write_text("frequency_hz,gain_db,phase_deg\n1,0,0\n2,0,0\n")
    argv = [a.replace("{f}", str(tmp_path / "mine")).replace("{data}", str(data)) for a in argv]
    target = next(tmp_path / a.rsplit("/", 1)[1] for a in argv if "mine" in a)
    target.write_text("keep\n")
    _refused(argv, target, option, capsys)


def test_excite_replaces_its_own_output_and_never_a_log_made_from_it(tmp_path, capsys):
    """A second run replaces the first's file; once a rig's log is written into it (its lines
    kept, a measured column changed), excite refuses it, and frf likewise keeps a measured
    response with the very header frf writes, while replacing its own earlier output."""
    stimulus, figure = tmp_path / "stimulus.csv", tmp_path / "stimulus.png"
    argv = ["excite", EMA, "-o", stimulus, "--plot", figure, "--resolution", "2", "--periods", "2"]
    for _ in range(2):
        assert main([str(a) for a in argv]) == 0, capsys.readouterr().err
    capsys.readouterr()
    lines = stimulus.read_text().splitlines()
    assert lines[0].startswith("# written by servo-toolkit excite; sha256") and lines[1].startswith(
        "# servo-toolkit excite:")
    frf = tmp_path / "frf.csv"
    for _ in range(2):
        assert main(["frf", str(stimulus), "--derivative", "-o", str(frf)]) == 0
    capsys.readouterr()
    measured = tmp_path / "measured.csv"
    measured.write_text("".join(ln + "\n" for ln in frf.read_text().splitlines()[1:]))  # same header, no stamp
    _refused(["frf", stimulus, "--derivative", "-o", measured], measured, "-o", capsys)
    row = lines[-1].split(",")
    row[2] = repr(float(row[2]) + 0.05)  # the rig's measured current
    stimulus.write_text("\n".join(lines[:-1] + [",".join(row)]) + "\n")
    _refused(argv, stimulus, "-o", capsys)
