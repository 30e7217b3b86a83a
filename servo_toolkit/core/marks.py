"""How an output file tells that the toolkit wrote it, so that an existing file is replaced only
when it is an earlier output of the same command (:func:`.files.check_output_file`).

- A text output that takes ``#`` comments (``excite -o``, ``frf -o``, ``sweep -o``/``--log``,
  ``fit -o``) starts with a line naming the command and the SHA-256 of the lines below it:
  a file the user changed since (a rig's measurements written into an excitation file, an
  edited calibrated scene) no longer matches and is never overwritten.
- A figure (``--plot``) carries the toolkit's name in its metadata (PNG, SVG, PDF, PS, EPS);
  JPEG, TIFF and WebP take no metadata, so an existing one is never replaced.
"""

from __future__ import annotations

import hashlib
import re

#: the name a figure's metadata carries
GENERATOR = "servo_toolkit"

#: the metadata key of each figure format that takes one
FIGURE_METADATA = {".png": "Software", ".svg": "Creator", ".pdf": "Creator", ".ps": "Creator", ".eps": "Creator"}

#: how far from either end of a figure its mark is looked for
_FIGURE_BYTES = 64 * 1024

_STAMP = re.compile(r"# written by servo-toolkit (\S+); sha256 of the lines below: ([0-9a-f]{64})\n")


def stamp(text: str, command: str) -> str:
    """``text`` with a first line naming ``command`` and the SHA-256 of ``text``."""
    digest = hashlib.sha256(text.encode("utf-8")).hexdigest()
    return f"# written by servo-toolkit {command}; sha256 of the lines below: {digest}\n{text}"


def stamped_by(path, command: str) -> bool:
    """True when the file at ``path`` is an unchanged output of ``command`` (its first line's
    digest matches the rest)."""
    try:
        with open(path, "rb") as fh:
            first = fh.readline(200).decode("utf-8", "replace")
            m = _STAMP.fullmatch(first)
            if m is None or m.group(1) != command:
                return False
            h = hashlib.sha256()
            for block in iter(lambda: fh.read(1 << 20), b""):
                h.update(block)
    except OSError:
        return False
    return h.hexdigest() == m.group(2)


def figure_metadata(suffix: str) -> dict | None:
    """The metadata marking a figure of format ``suffix`` (None: the format takes none)."""
    key = FIGURE_METADATA.get(suffix.lower())
    return None if key is None else {key: GENERATOR}


def figure_marked(path) -> bool:
    """True when the figure at ``path`` carries the toolkit's mark (near its start or end,
    where each format keeps its metadata)."""
    if path.suffix.lower() not in FIGURE_METADATA:
        return False
    try:
        with open(path, "rb") as fh:
            head = fh.read(_FIGURE_BYTES)
            fh.seek(0, 2)
            size = fh.tell()
            fh.seek(max(0, size - _FIGURE_BYTES))
            tail = fh.read()
    except OSError:
        return False
    return GENERATOR.encode() in head or GENERATOR.encode() in tail


__all__ = ["FIGURE_METADATA", "GENERATOR", "figure_marked", "figure_metadata", "stamp", "stamped_by"]
