"""The registry of study kinds: one descriptor per kind, found by scanning the studies'
packages; the scene reads each study table with its kind's schema and imports no study's
computation to do so."""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from pathlib import Path

import pytest

import servo_toolkit
from servo_toolkit.errors import SceneError
from servo_toolkit.scene import loader
from servo_toolkit.scene.study_kind import StudyKind, study_kinds

PACKAGE = Path(__file__).resolve().parents[1] / "servo_toolkit"
BUILTIN = ("kv", "frequency_sweep", "simulate", "inverse_dynamics", "mechanism_sweep")

#: modules where a built-in kind's name is another thing's name: the command of the same
#: name, the cascade controller's speed gain ``kv``, the time-simulation function
#: ``simulate``, the sizing's ``inverse_dynamics`` method and the function of that name
OTHER_MEANINGS = {
    "kv": {"cli", "cli.cmd_kv", "loop.nominal_search", "loop.design_file", "loop.structures", "loop.actuator_bounds",
           "loop.tuning", "loop.robust_design", "tuner.widget", "report.sections_loop"},
    "simulate": {"", "sim", "cli", "cli.cmd_simulate"},
    "inverse_dynamics": {"studies.sizing.run", "studies.mechanisms.inverse_dynamics"},
}


def _literal_modules(text: str) -> dict:
    """Module (relative to the package) -> count, of every string constant equal to ``text``."""
    found = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(PACKAGE).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        tree = ast.parse(path.read_text(encoding="utf-8"))
        n = sum(1 for node in ast.walk(tree) if isinstance(node, ast.Constant) and node.value == text)
        if n:
            found[name] = n
    return found


def test_the_builtin_kinds_are_registered_from_their_packages():
    kinds = study_kinds()
    assert set(BUILTIN) <= set(kinds)
    for name in BUILTIN:
        kind = kinds[name]
        assert isinstance(kind, StudyKind) and kind.name == name and kind.summary
        assert kind.origin.startswith("servo_toolkit.studies.") and kind.origin.endswith(".kind")
        assert callable(kind.resolve("run")) and isinstance(kind.resolve("result"), type)
        if kind.section is not None:
            assert callable(kind.resolve("section"))
    assert kinds["frequency_sweep"].command == "sweep" and kinds["kv"].command == "kv"
    with pytest.raises(TypeError):
        kinds["kv"] = kinds["simulate"]  # read-only


@pytest.mark.parametrize("name", BUILTIN)
def test_each_kind_name_is_written_once_in_the_package(name):
    """Everything else compares with the descriptor (``KV.name``) or asks it a flag."""
    found = _literal_modules(name)
    mine = [m for m in found if m not in OTHER_MEANINGS.get(name, set())]
    assert len(mine) == 1 and mine[0].endswith(".kind"), f"{name!r} written in {found}"


def _scene(studies: dict):
    import tomllib
    data = tomllib.loads((PACKAGE / "data" / "ema_reference.toml").read_text(encoding="utf-8"))
    return loader.scene_from_dict({**data, "studies": studies})


def test_an_unknown_kind_is_one_line_listing_the_registered_kinds():
    with pytest.raises(SceneError) as err:
        _scene({"spin": {"kind": "magic"}})
    message = str(err.value)
    assert "\n" not in message and message.startswith("studies.spin.kind")
    assert "magic" in message and all(k in message for k in BUILTIN)


def test_a_table_is_read_with_its_kinds_schema():
    with pytest.raises(SceneError, match=r"studies\.ramp\.amplitude\b"):  # a sine key is not a ramp's
        _scene({"ramp": {"kind": "inverse_dynamics", "amplitude": 1.0}})
    scene = _scene({"ramp": {"kind": "inverse_dynamics", "rate_alpha": "10 deg/s"}})
    assert scene.studies["ramp"].params["rate_alpha"] == pytest.approx(0.17453292519943295)


def test_loading_a_scene_imports_no_study_computation():
    code = ("import json, sys; import servo_toolkit as st; st.load_scene(sys.argv[1]); "
            "print(json.dumps(sorted(m for m in sys.modules if m.startswith('servo_toolkit.studies'))))")
    scene = PACKAGE / "data" / "ema_reference.toml"
    out = subprocess.run([sys.executable, "-c", code, str(scene)], capture_output=True, text=True, check=True)
    loaded = json.loads(out.stdout)
    assert "servo_toolkit.studies.kv.kind" in loaded  # the registry was read
    computation = [m for m in loaded if m != "servo_toolkit.studies" and not m.endswith(".kind")
                   and m + ".kind" not in loaded]  # a kind's package: its names load on first use
    assert not computation, f"loading a scene imported {computation}"


def test_the_study_command_runs_a_builtin_kind_and_guards_its_inputs(tmp_path, capsys):
    from servo_toolkit.cli import main

    from .conftest import SCENES
    scene = tmp_path / "platform.toml"
    scene.write_bytes((SCENES / "deflection_platform.toml").read_bytes())
    out = tmp_path / "ramp.json"
    assert main(["study", str(scene), "ramp", "--json", str(out)]) == 0
    printed = capsys.readouterr().out
    assert printed.startswith("Study ramp (inverse_dynamics) of deflection_platform\n") and "[N*m]" in printed
    data = json.loads(out.read_text(encoding="utf-8"))
    assert data["study"] == "ramp" and data["cases"]
    before = scene.read_bytes()
    assert main(["study", str(scene), "ramp", "--json", str(scene)]) == 2  # never over its own scene
    err = capsys.readouterr().err
    assert err.startswith("servo-toolkit: error: --json") and err.count("\n") == 1 and scene.read_bytes() == before


def test_a_study_run_by_another_kinds_command_names_the_commands_its_descriptor_gives(tmp_path):
    """The refusal reads the study's own command from its kind's descriptor."""
    from servo_toolkit.cli import main
    from servo_toolkit.studies.kv.kind import KV
    from servo_toolkit.studies.sweep.kind import SWEEP
    import contextlib
    import io
    scene = str(Path(servo_toolkit.__file__).parent / "data" / "ema_reference.toml")
    for command, study, kind in (("kv", "sweep", SWEEP), ("sweep", "kv_8hz", KV)):
        err = io.StringIO()
        with contextlib.redirect_stderr(err):
            assert main([command, scene, "--study", study]) == 2
        line = err.getvalue().strip()
        assert line.count("\n") == 0 and f"studies.{study}.kind" in line
        assert f"servo-toolkit {kind.command} or servo-toolkit study" in line, line


def test_the_study_command_without_a_name_lists_the_scenes_studies(capsys):
    """``servo-toolkit study SCENE`` prints each study of the scene with its kind, the kind's
    summary and the commands its descriptor names, then every registered kind; a roller-screw
    scene's built-in studies are listed too; ``--json`` asks for a study's result, so without
    a name it is one line and exit 2."""
    from servo_toolkit.cli import main
    from servo_toolkit.scene.study_kind import study_kinds

    from .conftest import SCENES
    scene = Path(servo_toolkit.__file__).parent / "data" / "ema_reference.toml"
    assert main(["study", str(scene)]) == 0
    out = capsys.readouterr().out
    assert out.startswith("Studies of ema_reference\nstudy ")
    loaded = servo_toolkit.load_scene(scene)
    assert loaded.studies
    for name, study in loaded.studies.items():
        kind = study_kinds()[study.kind]
        row = next(line for line in out.splitlines() if line.startswith(name + " "))
        assert kind.name in row and kind.summary in row and row.rstrip().endswith(kind.commands), row
    assert f"Registered kinds: {', '.join(sorted(study_kinds()))}." in out
    assert main(["study", str(SCENES / "roller_screw_two_stage.toml")]) == 0
    rows = capsys.readouterr().out.splitlines()
    assert any(r.startswith("efficiency ") and "built in" in r for r in rows)
    assert any(r.startswith("carrier_step ") and "built in" in r for r in rows)
    assert main(["study", str(scene), "--json", "out.json"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("servo-toolkit: error: --json") and err.count("\n") == 1
