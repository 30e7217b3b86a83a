"""Every seed-mechanism study runs by name through ``simulate``, ``kv`` and ``sweep``.

The three commands dispatch a study that :func:`servo_toolkit.studies.mechanisms.dispatch.handles` claims to
:func:`servo_toolkit.studies.mechanisms.dispatch.run_study`, before looking the name up in the scene file, so
the built-in roller-screw studies (not in the file) run too. Options that only mean something
for the sine-dwell sweep are refused with one line and exit 2.
"""

from __future__ import annotations

import json

import pytest

from servo_toolkit.cli import main
from servo_toolkit.studies.mechanisms.dispatch import ROLLER_SCREW_STUDIES
from servo_toolkit.scene.loader import load_scene

from .conftest import SCENES

#: scene file -> every study name the commands accept (the file's and the built-in ones)
MECHANISM_STUDIES = {
    "cam_follower.toml": ("constant_speed", "constant_voltage"),
    "deflection_platform.toml": ("ramp",),
    "roller_screw_two_stage.toml": ROLLER_SCREW_STUDIES,
}
CASES = [(command, scene, study) for command in ("simulate", "kv", "sweep")
         for scene, studies in MECHANISM_STUDIES.items() for study in studies]


def test_the_table_covers_every_study_of_the_scenes():
    """The parametrization lists every study of the three scene files (and the built-ins)."""
    for scene, studies in MECHANISM_STUDIES.items():
        in_file = set(load_scene(SCENES / scene).studies)
        assert in_file <= set(studies)


@pytest.mark.parametrize("command,scene,study", CASES)
def test_every_command_runs_every_mechanism_study(command, scene, study, capsys):
    """Exit 0 and one JSON object on stdout, naming the study's result."""
    argv = [command, str(SCENES / scene), "--study", study, "--json"]
    if command == "simulate" and study == "constant_voltage":
        argv += ["--dt", "2e-3"]  # light: the study's step is 1 ms
    code = main(argv)
    captured = capsys.readouterr()
    assert code == 0, captured.err
    out = json.loads(captured.out)
    assert isinstance(out, dict) and out
    if command == "kv":
        assert out["scene"] == load_scene(SCENES / scene).name and len(out["studies"]) == 1
        out = out["studies"][0]
    # the same mechanism result whichever command ran it (simulate runs first)
    _KEYS.setdefault((scene, study), set(out))
    assert set(out) == _KEYS[(scene, study)]
    assert "points" not in out or command != "sweep" or "gain_db" not in out["points"][0]


_KEYS: dict = {}


@pytest.mark.parametrize("command", ["simulate", "kv", "sweep"])
def test_unknown_study_lists_the_built_in_studies(command, capsys):
    """A name that is neither in the file nor built in: exit 2, one line naming the key and
    listing the built-in studies."""
    code = main([command, str(SCENES / "roller_screw_two_stage.toml"), "--study", "nope", "--json"])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and "studies.nope" in err
    assert all(name in err for name in ROLLER_SCREW_STUDIES)


@pytest.mark.parametrize("option", [["--frequency", "3"], ["--amplitude", "2"], ["--full"]])
def test_sweep_options_do_not_apply_to_mechanism_studies(option, capsys):
    """The sine-dwell options mean nothing for a mechanism study: exit 2, one line."""
    code = main(["sweep", str(SCENES / "cam_follower.toml"), "--study", "constant_speed", *option])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and "studies.constant_speed" in err and option[0] in err
