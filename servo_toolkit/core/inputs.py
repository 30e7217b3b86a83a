"""User files read safely: regular files only (a FIFO, a device or a folder is refused without
blocking), at most a stated number of bytes, UTF-8 errors in one line."""

from __future__ import annotations

import os
import stat

from ..errors import SceneError
from .files import _q


def _mib(n: int) -> str:
    return f"{n / 2**20:g} MiB" if n >= 2**20 else f"{n / 2**10:g} KiB"


def read_input_bytes(path, key: str, limit: int, source: str | None = None, what: str | None = None) -> bytes:
    """The bytes of the input file ``path``: a regular file of at most ``limit`` bytes (a
    FIFO, device or folder is refused without blocking: opened non-blocking, fstat checked).

    Parameters
    ----------
    path : str or path-like
    key : str
        The option (or scene key) named in the error.
    limit : int
        Largest size read (bytes).
    source, what : str, optional
        The file the :class:`SceneError` names, and what the file is (default: its path).

    Raises
    ------
    SceneError
    """
    what = what or _q(path)

    def refuse(rule):
        return SceneError(key, f"cannot read {what}: {rule}", source)

    def kind(mode):
        if stat.S_ISDIR(mode):
            raise refuse("it is a directory")
        if not stat.S_ISREG(mode):
            raise refuse("not a regular file (a device, FIFO or socket)")
    try:
        kind(os.stat(path).st_mode)
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_NOCTTY | os.O_CLOEXEC)
    except OSError as exc:
        raise refuse(exc.strerror or str(exc)) from None
    try:
        st = os.fstat(fd)
        kind(st.st_mode)
        if st.st_size > limit:
            raise refuse(f"{st.st_size} bytes, more than the {_mib(limit)} read at most")
        chunks, size = [], 0
        while size <= limit:
            chunk = os.read(fd, min(1 << 20, limit + 1 - size))
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
        if size > limit:
            raise refuse(f"more than the {_mib(limit)} read at most")
        return b"".join(chunks)
    except OSError as exc:
        raise refuse(exc.strerror or str(exc)) from None
    finally:
        os.close(fd)


def read_input_text(path, key: str, limit: int, source: str | None = None, what: str | None = None) -> str:
    """:func:`read_input_bytes` decoded as UTF-8 (bad bytes: one SceneError naming the offset).
    A leading byte-order mark (as spreadsheet programs and some editors write UTF-8) is dropped."""
    raw = read_input_bytes(path, key, limit, source, what)
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise SceneError(key, f"cannot read {what or _q(path)}: the bytes at offset {exc.start} are not UTF-8 "
                         "text (save the file as UTF-8)", source) from None


__all__ = ["read_input_bytes", "read_input_text"]
