"""``servo-toolkit new``: a commented scene to start from, which loads and passes ``check``
as written, never over an existing file."""

import re

import pytest

from servo_toolkit.cli import main
from servo_toolkit.scene.loader import load_scene
from servo_toolkit.scene.template import OUTPUTS, scene_template


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """output -> the scene file ``new`` writes for it."""
    folder = tmp_path_factory.mktemp("new")
    paths = {}
    for output in OUTPUTS:
        paths[output] = folder / f"my_{output}.toml"
        assert main(["new", str(paths[output]), "--output", output]) == 0
    return paths


@pytest.mark.parametrize("output, unit", [("angle", "rad"), ("travel", "m")])
def test_the_scene_loads_as_written(written, output, unit):
    scene = load_scene(written[output])
    assert scene.name == f"my_{output}"
    assert scene.drivetrain.output_unit == unit
    assert scene.drivetrain.stroke_note is None  # its stroke is the scene's own
    assert scene.notes == ()
    text = written[output].read_text()
    for section in ("[motor]", "[[drivetrain]]", "[load]", "[sensors]", "[requirements]", "[studies."):
        assert section in text


@pytest.mark.parametrize("output", OUTPUTS)
def test_each_study_is_named_for_what_it_runs(written, output):
    """The simulate study runs a sine command: it is named ``sine``, not ``step``, and the
    commands in the comment name the studies the file has."""
    scene = load_scene(written[output])
    assert set(scene.studies) == {"sine", "kv"}
    assert scene.studies["sine"].kind == "simulate" and "amplitude" in scene.studies["sine"].params
    text = written[output].read_text()
    for name in re.findall(r"--study ([a-z_]+)", text):
        assert name in scene.studies
    assert "[studies.step]" not in text


@pytest.mark.parametrize("output", OUTPUTS)
def test_the_scene_passes_check_as_written(written, output, capsys):
    assert main(["check", str(written[output])]) == 0, capsys.readouterr().out


@pytest.mark.parametrize("output", OUTPUTS)
def test_every_optional_key_shown_loads_when_uncommented(tmp_path, output):
    text = scene_template(output, "opened")
    opened = re.sub(r"^# ([a-z_]+ = )", r"\1", text, flags=re.MULTILINE)
    assert opened != text
    path = tmp_path / "opened.toml"
    path.write_text(opened)
    load_scene(path)


@pytest.mark.parametrize("output", OUTPUTS)
def test_every_quantity_is_written_with_its_unit(output):
    bare = re.findall(r"^([a-z_]+) = (-?[0-9.e+-]+)\b", scene_template(output), flags=re.MULTILINE)
    assert {k for k, _ in bare} <= {"ratio", "efficiency", "output_encoder_bits", "motor_encoder_counts"}


def test_an_existing_file_is_never_overwritten(tmp_path, capsys):
    path = tmp_path / "mine.toml"
    path.write_text("name = 'mine'\n")
    assert main(["new", str(path), "--output", "travel"]) == 2
    assert "exists" in capsys.readouterr().err
    assert path.read_text() == "name = 'mine'\n"
    assert main(["new", str(tmp_path / "mine.txt")]) == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine.toml"]  # no temporary left behind
