"""Shared fixtures: the reference scenes and small scene builders; with several test
processes (pytest-xdist), one compilation of the simulation kernels for all of them."""

from __future__ import annotations

import copy
import io
import os
import tomllib
from contextlib import contextmanager, redirect_stderr, redirect_stdout
from dataclasses import dataclass
from pathlib import Path

import pytest

from servo_toolkit.scene.loader import scene_from_dict

ROOT = Path(__file__).resolve().parents[1]
SCENES = ROOT / "scenes"
SCENE_FILES = sorted(SCENES.glob("*.toml"))


@contextmanager
def _file_lock(path: Path):
    """Hold an exclusive lock on ``path`` (shared by the pytest-xdist workers) for the block."""
    import fcntl
    with open(path, "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)


@pytest.fixture
def scenes_dir() -> Path:
    """Folder of the reference scenes shipped with the repository."""
    return SCENES


@dataclass(frozen=True)
class ReportRun:
    """One ``servo-toolkit report SCENE -o FOLDER --strict`` run: its folder, exit code and output."""

    folder: Path
    code: int
    out: str
    err: str


@pytest.fixture(scope="session")
def ema():
    """``(scene, controller)``: the reference EMA and its designed controller (a test module
    that needs another ``ema`` defines its own, which takes precedence)."""
    from servo_toolkit.scene.loader import load_scene
    from servo_toolkit.sim import controller_for
    scene = load_scene(SCENES / "ema_reference.toml")
    controller, _ = controller_for(scene)
    return scene, controller


@pytest.fixture(scope="session")
def scene_report(tmp_path_factory):
    """``scene_report(name)``: the report of ``scenes/NAME.toml`` written by the command line
    (light settings, ``--strict``), once per scene for the whole session; a
    :class:`ReportRun`. The report tests share these runs, so each scene's report is built
    once however many tests read it; under pytest-xdist the workers share them too (the
    first to ask writes it under a lock, the others read what it wrote)."""
    import json

    from servo_toolkit.cli import main
    base = tmp_path_factory.getbasetemp()
    shared = (base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base) / "scene-reports"
    shared.mkdir(exist_ok=True)
    made = {}

    def report(name: str) -> ReportRun:
        if name not in made:
            folder, record = shared / name, shared / f"{name}.json"
            with _file_lock(shared / f"{name}.lock"):
                if not record.exists():
                    out, err = io.StringIO(), io.StringIO()
                    with redirect_stdout(out), redirect_stderr(err):
                        code = main(["report", str(SCENES / f"{name}.toml"), "-o", str(folder), "--strict"])
                    record.write_text(json.dumps({"code": code, "out": out.getvalue(), "err": err.getvalue()}))
            run = json.loads(record.read_text())
            made[name] = ReportRun(folder, run["code"], run["out"], run["err"])
        return made[name]
    return report


@pytest.fixture
def ema_dict() -> dict:
    """The reference EMA as a plain dict, for building variants."""
    return tomllib.loads((SCENES / "ema_reference.toml").read_text())


def variant(data: dict, **edits):
    """Deep-copied scene dict with ``path=value`` edits (``drivetrain__2__rod_length``)."""
    data = copy.deepcopy(data)
    for key, value in edits.items():
        parts = [int(p) if p.isdigit() else p for p in key.split("__")]
        target = data
        for p in parts[:-1]:
            target = target[p]
        if value is None:
            del target[parts[-1]]
        else:
            target[parts[-1]] = value
    return data


def build(data: dict):
    """Scene from a dict."""
    return scene_from_dict(data, "test.toml")


def closed_tags(html: str) -> bool:
    """Every div, table and svg an HTML card opens is closed."""
    from html.parser import HTMLParser
    depth = {"div": 0, "table": 0, "svg": 0}

    class Tags(HTMLParser):
        def handle_starttag(self, tag, attrs):
            depth[tag] = depth.get(tag, 0) + 1

        def handle_endtag(self, tag):
            depth[tag] = depth.get(tag, 0) - 1
    Tags().feed(html)
    return all(depth[t] == 0 for t in ("div", "table", "svg"))


def open_circuit_run(model, P, x0, dt: float, n_steps: int, every: int = 1):
    """Fixed-step RK4 from ``x0`` with the armature open (its resistance set to 1e12 ohm in the
    parameter block; a scene refuses such a resistance). Returns the recorded states."""
    import numpy as np

    from servo_toolkit.sim import layout as lo
    from servo_toolkit.sim.integrators import integrate
    P = P.copy()
    P[lo.R] = 1e12
    x = np.array(x0, dtype=float)
    n_rec = n_steps // every + 1
    out_t, out_x, aux = np.zeros(n_rec), np.zeros((n_rec, model.nx)), np.zeros((n_rec, lo.NAUX))
    status, _, got, _, _ = integrate(x, P, model.T, 0.0, dt, n_steps, 0, 0.0, False, every, out_t, out_x, aux)
    assert status == 0, status
    return out_x[:got]


def _scene_content(scene) -> str:
    """The scene file's bytes (the design's input; a scene's repr is only a summary)."""
    import hashlib
    return hashlib.sha256(Path(scene.source).read_bytes()).hexdigest() if scene.source else str(id(scene))


@contextmanager
def memoized_designs():
    """Within the block, the loop design runs once per set of inputs (it is deterministic):
    ``servo_toolkit.loop.design.design`` and the ``design`` command's reference to it answer
    from a cache keyed on the scene, its file's bytes and the arguments."""
    import functools
    import importlib
    module = importlib.import_module("servo_toolkit.loop.design")
    cmd = importlib.import_module("servo_toolkit.cli.cmd_design")
    original, saved = module.design, cmd.design
    cache = {}

    @functools.wraps(original)
    def design(scene, *args, **kwargs):
        key = repr((scene, _scene_content(scene), args, sorted(kwargs.items())))
        if key not in cache:
            cache[key] = original(scene, *args, **kwargs)
        return cache[key]
    module.design = cmd.design = design
    try:
        yield
    finally:
        module.design, cmd.design = original, saved



@pytest.fixture(scope="module")
def memo():
    """Within a test module, the loop design runs once per set of inputs
    (:func:`memoized_designs`)."""
    with memoized_designs():
        yield