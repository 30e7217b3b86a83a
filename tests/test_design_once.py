"""A command designs the loop once and hands the controller down: the studies it runs take
that controller, and the run's setup (run spec, method, reduction) is resolved once."""

from __future__ import annotations

import functools
import importlib
import json

import pytest

from servo_toolkit.cli import main

SCENE = "servo_toolkit/data/ema_reference.toml"


@pytest.fixture
def counts(monkeypatch):
    """Calls of the loop design, the run spec, the method's resolution and the reduction's
    plan, counted wherever they are called from."""
    seen = {}
    for module_name, name in (("servo_toolkit.loop.design", "design"),
                              ("servo_toolkit.studies.time.reference", "run_spec"),
                              ("servo_toolkit.studies.time.run", "resolve_method"),
                              ("servo_toolkit.studies.reduce.estimates", "plan_reduction")):
        module = importlib.import_module(module_name)
        original = getattr(module, name)

        def counted(*args, _original=original, _name=name, **kwargs):
            seen[_name] = seen.get(_name, 0) + 1
            return _original(*args, **kwargs)
        functools.update_wrapper(counted, original)
        for other in list(importlib.sys.modules.values()):  # names bound by `from ... import`
            if getattr(other, name, None) is original and getattr(other, "__name__", "").startswith("servo_toolkit"):
                monkeypatch.setattr(other, name, counted)
    return seen


def _run(argv, capsys):
    code = main(argv)
    out = capsys.readouterr().out
    return code, out


def test_simulate_designs_once_and_resolves_its_run_once(counts, capsys):
    """``simulate``: one design, one run spec, one method resolution, one reduction plan."""
    code, out = _run(["simulate", SCENE, "--json"], capsys)
    assert code == 0
    assert counts == {"design": 1, "run_spec": 1, "resolve_method": 1, "plan_reduction": 1}
    notes = json.loads(out)["notes"]
    assert notes[0] == "controller from loop.design"


def test_sweep_designs_once(counts, capsys):
    """``sweep``: one design, one reduction plan for the sweep's points."""
    code, out = _run(["sweep", SCENE, "--frequency", "8", "--json"], capsys)
    assert code == 0
    assert counts.get("design") == 1 and counts.get("plan_reduction") == 1
    assert "controller from loop.design" in json.loads(out)["notes"]


def test_sweep_multisine_designs_once_and_hands_the_controller_down(counts, capsys, monkeypatch):
    """``sweep --method multisine``: one design, in the command, handed to the multisine (which
    then designs nothing)."""
    import servo_toolkit.studies.multisine as package
    real, given = package.multisine_sweep, []

    def recorded(*args, **kwargs):
        given.append((kwargs.get("controller"), kwargs.get("controller_source")))
        return real(*args, **kwargs)
    monkeypatch.setattr(package, "multisine_sweep", recorded)
    code, out = _run(["sweep", SCENE, "--method", "multisine", "--band", "2:16", "--lines", "4", "--json"], capsys)
    assert code == 0
    assert counts.get("design") == 1 and counts.get("plan_reduction") == 1
    assert len(given) == 1 and given[0][0] is not None and given[0][1] == "loop.design"
    assert "controller from loop.design" in json.loads(out)["notes"]


def test_multisine_given_a_controller_does_not_design(counts, ema):
    """A multisine sweep given a controller never designs; its note names the given source."""
    from servo_toolkit.studies.multisine import multisine_sweep
    scene, controller = ema
    counts.clear()
    res = multisine_sweep(scene, band=(2.0, 16.0), lines=4, amplitudes=[0.01], periods=1, settle=1,
                          controller=controller, controller_source="my tuning", progress=False)
    assert counts.get("design", 0) == 0
    assert res.notes[0] == "controller from my tuning"


def test_reduce_designs_once(counts, capsys):
    """``reduce``: one design and one reduction plan for the estimates and the measured runs."""
    code, out = _run(["reduce", SCENE, "--frequency", "8", "--json"], capsys)
    assert code == 0
    assert counts.get("design") == 1 and counts.get("plan_reduction") == 1
    assert "controller from loop.design" in json.loads(out)["notes"]


def test_reduce_of_a_time_study_plans_once(counts, capsys):
    """``reduce`` of a kv study: one plan, whose choice runs on the time runs' full model (the
    stroke end's stop kept on the reduced model too)."""
    code, out = _run(["reduce", SCENE, "--study", "kv_8hz", "--amplitude", "2 deg", "--json"], capsys)
    assert code == 0
    assert counts.get("design") == 1 and counts.get("plan_reduction") == 1
    res = json.loads(out)
    assert res["full_options"]["stroke_end"] == res["reduced_options"]["stroke_end"] == "stop"


def test_check_designs_once(counts, capsys):
    """``check``: one design for the linear rows and the nonlinear ones."""
    code, _ = _run(["check", SCENE, "--json"], capsys)
    assert code in (0, 1)
    assert counts.get("design") == 1


def test_check_with_design_file_designs_nothing(counts, capsys, tmp_path):
    """``check --design FILE``: the file's controller, no design."""
    from servo_toolkit import load_scene
    from servo_toolkit.loop.tuning import save_design
    design = importlib.import_module("servo_toolkit.loop.design").design
    path = save_design(design(load_scene(SCENE), progress=False), tmp_path / "d.json")
    counts.clear()
    code, _ = _run(["check", SCENE, "--design", str(path), "--json"], capsys)
    assert code in (0, 1)
    assert counts.get("design", 0) == 0


def test_study_given_a_controller_does_not_design(counts, ema):
    """A study function given a controller never designs; its note names the given source."""
    from servo_toolkit.studies.time.run import simulate_study
    scene, controller = ema
    counts.clear()
    res = simulate_study(scene, None, controller=controller, controller_source="my tuning")
    assert counts.get("design", 0) == 0
    assert res.notes[0] == "controller from my tuning"
