"""A scene's derived quantities are computed once per scene object and reused: its reflected
drivetrain (and with it the lumped chain) and the linear plant's parameters at an operating
point. A changed scene is a new object with its own values; a pickled scene carries none."""

from __future__ import annotations

import copy
import functools
import inspect
import sys
import threading
from collections import Counter
from dataclasses import replace

import pytest

from servo_toolkit.cli import main
from servo_toolkit.drivetrain.chain import Chain
from servo_toolkit.drivetrain.reflected import Drivetrain
from servo_toolkit.errors import SceneError
from servo_toolkit.plant import linear
from servo_toolkit.plant.linear import plant_parameters
from servo_toolkit.scene.loader import load_scene, replace_params

SCENE = "servo_toolkit/data/ema_reference.toml"


@pytest.fixture
def builds(monkeypatch):
    """Every drivetrain built from a scene, every chain built from a drivetrain and every
    computation of the plant's parameters, with the scene (kept alive: no reused ids) and
    the arguments it was computed for."""
    seen = {"drivetrain": [], "chain": [], "parameters": []}
    asked = threading.local()

    def from_scene(cls, scene, _original=Drivetrain.from_scene.__func__):
        seen["drivetrain"].append(scene)
        return _original(cls, scene)

    def from_drivetrain(cls, drivetrain, _original=Chain.from_drivetrain.__func__):
        seen["chain"].append(drivetrain)
        return _original(cls, drivetrain)

    monkeypatch.setattr(Drivetrain, "from_scene", classmethod(from_scene))
    monkeypatch.setattr(Chain, "from_drivetrain", classmethod(from_drivetrain))

    original = linear.plant_parameters

    def asked_for(scene, q0=None, model="auto", structural_damping=linear.DEFAULT_STRUCTURAL_DAMPING):
        q = scene.drivetrain.mid_stroke if q0 is None else float(q0)
        outer = getattr(asked, "args", None)
        asked.args = (scene, (q, model, float(structural_damping)))
        try:
            return original(scene, q0, model, structural_damping)
        finally:
            asked.args = outer
    functools.update_wrapper(asked_for, original)
    for module in list(sys.modules.values()):  # names bound by `from ... import`, wrapped or not
        bound = getattr(module, "plant_parameters", None)
        if callable(bound) and inspect.unwrap(bound) is original and module.__name__.startswith("servo_toolkit"):
            monkeypatch.setattr(module, "plant_parameters", asked_for)

    lumped = linear.lumped_friction  # called once by each computation of the parameters

    def computing(scene, *args, **kwargs):
        args_now = getattr(asked, "args", None)
        if args_now is not None and args_now[0] is scene:
            seen["parameters"].append(args_now)
        return lumped(scene, *args, **kwargs)
    monkeypatch.setattr(linear, "lumped_friction", computing)
    return seen


def _repeats(items, key=id) -> dict:
    """The items computed more than once, with their counts."""
    counts = Counter(key(x) for x in items)
    return {k: n for k, n in counts.items() if n > 1}


@pytest.mark.parametrize("argv", [["simulate", SCENE, "--json"], ["check", SCENE, "--json"],
                                  ["design", SCENE, "--json"]], ids=["simulate", "check", "design"])
def test_a_command_computes_each_derived_quantity_once_per_scene(argv, builds, capsys):
    """One ``simulate``, ``check`` or ``design`` of the reference scene builds each scene's
    drivetrain once, each drivetrain's chain once, and the plant's parameters once per
    scene and argument set (before: 79 drivetrains and 33 parameter sets, 9 of them at
    the same q0, in one ``simulate``)."""
    assert main(argv) == 0
    capsys.readouterr()
    assert builds["drivetrain"] and builds["parameters"]
    assert not _repeats(builds["drivetrain"]), "a scene's drivetrain was built more than once"
    assert not _repeats(builds["chain"]), "a drivetrain's chain was built more than once"
    again = _repeats(builds["parameters"], key=lambda a: (id(a[0]), a[1]))
    assert not again, f"plant parameters computed again for the same scene and arguments: {again}"


def test_the_values_are_reused_and_equal_fresh_ones():
    """Asked again, a scene returns the very objects it computed; they equal those of a
    fresh copy of the scene, which computes its own."""
    scene = load_scene(SCENE)
    drive, p = scene.drivetrain, plant_parameters(scene)
    assert scene.drivetrain is drive and drive.chain is scene.drivetrain.chain
    assert plant_parameters(scene) is p
    assert plant_parameters(scene, p.q0) is p  # mid-stroke asked by its value
    assert plant_parameters(scene, model="rigid") is not p and plant_parameters(scene, model="rigid").rigid
    assert plant_parameters(scene, structural_damping=0.05).c > p.c
    fresh = replace(scene)
    assert fresh == scene and fresh.drivetrain is not drive and fresh.drivetrain == drive
    assert plant_parameters(fresh) is not p and plant_parameters(fresh) == p
    assert plant_parameters(scene, -0.0).q0 == 0.0 and str(plant_parameters(scene, -0.0).q0) == "-0.0"
    for model in ("bogus", ["auto"]):  # an unknown model is a SceneError, never kept
        with pytest.raises(SceneError, match="unknown plant model"):
            plant_parameters(scene, model=model)


def test_a_changed_scene_gets_its_own_values():
    """A scene with a stiffer housing (``replace_params``) has its own drivetrain and a
    higher series stiffness K; the original keeps its own."""
    scene = load_scene(SCENE)
    k_before = plant_parameters(scene).K
    stages = scene.stages
    i = next(i for i, s in enumerate(stages) if getattr(s, "name", None) == "housing")
    stiffer = replace(stages[i], stiffness=stages[i].stiffness * 10)
    changed = replace_params(scene, stages=stages[:i] + (stiffer,) + stages[i + 1:])
    assert changed.drivetrain is not scene.drivetrain and changed.drivetrain.stages[i] is stiffer
    assert plant_parameters(changed).K > 1.01 * k_before
    assert plant_parameters(scene).K == k_before


def test_equality_and_repr_ignore_the_derived_values():
    """Computing a scene's derived values changes neither its equality nor its repr."""
    scene, other = load_scene(SCENE), load_scene(SCENE)
    text = repr(scene)
    plant_parameters(scene)
    assert scene == other and repr(scene) == text == repr(other)


def test_a_copied_or_pickled_scene_carries_no_derived_values():
    """``copy.copy`` and dask's pickling (cloudpickle) give a scene equal to the original
    that computes its derived values again, to equal results."""
    cloudpickle = pytest.importorskip("cloudpickle")
    scene = load_scene(SCENE)
    p = plant_parameters(scene)
    assert set(scene.__getstate__()) == {f for f in scene.__dataclass_fields__}
    for twin in (copy.copy(scene), cloudpickle.loads(cloudpickle.dumps(scene))):
        assert twin == scene
        assert "drivetrain" not in vars(twin) and not vars(twin).get("_derived")
        assert plant_parameters(twin) == p and plant_parameters(twin) is not p
    assert len(cloudpickle.dumps(scene)) == len(cloudpickle.dumps(replace(scene)))


def test_threads_filling_the_cache_at_once_get_one_value():
    """Threads asking a fresh scene for its parameters at the same moment all get the same,
    whole object (a race computes twice at worst and keeps the value stored first)."""
    scene = replace(load_scene(SCENE))  # a scene object that has computed nothing yet
    assert not {"drivetrain", "_derived"} & set(vars(scene))
    expected = plant_parameters(replace(scene), 0.1)
    start, out = threading.Barrier(4), []

    def ask():
        start.wait()
        out.append((scene.drivetrain, plant_parameters(scene, 0.1)))
    threads = [threading.Thread(target=ask) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(out) == 4
    # the drivetrain: equal (a cached_property may build it in more than one thread); the
    # parameters: the one object stored first
    assert all(d == out[0][0] for d, _ in out) and all(p is out[0][1] for _, p in out)
    assert out[0][1] == expected


def test_derived_keys_and_values():
    """``Scene.derived``: one computation per key; an error is not kept."""
    scene = load_scene(SCENE)
    calls = []
    assert scene.derived("x", lambda: calls.append(1) or 7) == 7
    assert scene.derived("x", lambda: calls.append(1) or 8) == 7 and calls == [1]

    def fails():
        raise ValueError("no")
    with pytest.raises(ValueError):
        scene.derived("y", fails)
    assert scene.derived("y", lambda: 3) == 3

