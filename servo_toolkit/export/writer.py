"""Output folder of an export: checked before work, written atomically."""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

from ..errors import SceneError

#: the files an export writes into its folder
FILES = ("controller.json", "servo_controller.h", "servo_controller.c")


def check_directory(directory, inputs=(), key: str = "-o") -> Path:
    """The output folder, after checking that it can be written and that no output file is
    one of ``inputs``; nothing is created yet."""
    path = Path(directory)
    if path.exists() and not path.is_dir():
        raise SceneError(key, f"{path} exists and is not a folder")
    parent = path if path.exists() else path.parent
    probe = parent
    while not probe.exists():  # missing parents are created on writing
        probe = probe.parent
    if not probe.is_dir() or not os.access(probe, os.W_OK | os.X_OK):
        raise SceneError(key, f"cannot write into {probe}")
    targets = {(path / name).resolve() for name in FILES}
    for item in inputs:
        if item is not None and Path(item).resolve() in targets:
            raise SceneError(key, f"the export would overwrite its input {item}")
    return path


def write_files(directory, contents: dict) -> Path:
    """Write ``{file name: text}`` into ``directory``: a new folder appears complete
    (written in a temporary sibling, then renamed); in an existing folder each file is
    replaced atomically."""
    path = Path(directory)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{path.name}.", dir=path.parent))
    try:
        for name, text in contents.items():
            with open(tmp / name, "w", encoding="utf-8", newline="\n") as fh:
                fh.write(text)
                fh.flush()
                os.fsync(fh.fileno())
        if not path.exists():
            try:
                os.rename(tmp, path)
                return path
            except OSError:  # created meanwhile: fall back to per-file replacement
                pass
        for name in contents:
            os.replace(tmp / name, path / name)
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
    return path
