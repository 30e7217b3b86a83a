"""Output folder of an export: checked before work, written as a whole (see
:mod:`servo_toolkit.core.files`)."""

from __future__ import annotations

from pathlib import Path

from ..core.files import check_output_folder
from ..core.folders import atomic_folder

#: the files an export writes into its folder
FILES = ("controller.json", "servo_controller.h", "servo_controller.c")


def check_directory(directory, inputs=(), key: str = "-o") -> Path:
    """The output folder, after checking that it can be written: absent (missing parents
    are created), empty, or an earlier export (only :data:`FILES`), and holding none of
    ``inputs``; nothing is created yet."""
    return check_output_folder(directory, key, allowed=FILES, inputs=inputs, parents=True)


def write_files(directory, contents: dict, key: str = "-o") -> Path:
    """Write ``{file name: text}`` as the folder ``directory``: the whole set is written in
    a temporary sibling and swapped in at once, so the folder holds the earlier set or the
    new one, never a mix."""
    path = check_output_folder(directory, key, allowed=set(FILES) | set(contents), parents=True)
    with atomic_folder(path, key, parents=True) as tmp:
        for name, text in contents.items():
            with open(tmp / name, "w", encoding="utf-8", newline="\n") as fh:
                fh.write(text)
    return path
