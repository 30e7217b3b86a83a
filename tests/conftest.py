"""Shared fixtures: the reference scenes and small scene builders."""

from __future__ import annotations

import copy
import tomllib
from pathlib import Path

import pytest

from servo_toolkit.scene.loader import scene_from_dict

ROOT = Path(__file__).resolve().parents[1]
SCENES = ROOT / "scenes"
SCENE_FILES = sorted(SCENES.glob("*.toml"))


@pytest.fixture
def scenes_dir() -> Path:
    """Folder of the reference scenes shipped with the repository."""
    return SCENES


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
