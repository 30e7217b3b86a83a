"""Output paths checked before any work, and files and folders written atomically: nothing a
user has is overwritten by something else or left half-written (a failure, Ctrl-C or two
concurrent runs leave either the old output or the new one)."""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from pathlib import Path

from ..errors import SceneError

#: figure formats matplotlib writes without extra packages
FIGURE_SUFFIXES = (".png", ".svg", ".pdf", ".eps", ".ps", ".jpg", ".jpeg", ".tif", ".tiff", ".webp")
#: a folder holding these (and nothing else) is an earlier report
REPORT_FILES = {"index.html", "report.pdf"}


def _probe(folder: Path, key: str, path) -> None:
    """Create and remove a temporary folder in ``folder``: the only sure test that the output
    can be written there (permissions, a read-only or pseudo file system, a full disk)."""
    try:
        os.rmdir(tempfile.mkdtemp(prefix=".servo-toolkit-probe.", dir=folder))
    except OSError as exc:
        raise SceneError(key, f"cannot write {str(path)!r}: {exc.strerror or exc}") from None


def check_file(path, key: str, suffixes=None, inputs=()) -> Path:
    """A file that may be written at ``path``: its folder exists and is writable, it is not a
    folder, not one of ``inputs``, and ends in one of ``suffixes`` (when given).

    Raises
    ------
    SceneError
        Naming ``key`` (the option) and the rule.
    """
    p = Path(path)
    if suffixes and p.suffix.lower() not in suffixes:
        raise SceneError(key, f"{p.name!r} must end in one of {', '.join(suffixes)}")
    if p.is_dir():
        raise SceneError(key, f"cannot write {str(path)!r}: it is a folder")
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.is_dir():
        raise SceneError(key, f"cannot write {str(path)!r}: folder {str(parent)!r} does not exist")
    if p.exists() and not os.access(p, os.W_OK):
        raise SceneError(key, f"cannot write {str(path)!r}: permission denied")
    _probe(parent, key, path)
    for name in inputs:
        with contextlib.suppress(OSError):
            if p.exists() and Path(name).exists() and p.resolve() == Path(name).resolve():
                raise SceneError(key, f"refusing to overwrite the input {str(path)!r}")
    return p


def check_report_folder(path, key: str = "--output") -> Path:
    """A report folder that may be (re)written: absent, empty, or an earlier report
    (``index.html``, ``report.pdf``), in a writable folder."""
    p = Path(path)
    if p.exists() and not p.is_dir():
        raise SceneError(key, f"{str(path)!r} is a file, not a report folder")
    parent = p.resolve().parent
    if not parent.is_dir():
        raise SceneError(key, f"cannot write {str(path)!r}: folder {str(parent)!r} does not exist")
    _probe(parent, key, path)
    if p.is_dir():
        others = sorted(x.name for x in p.iterdir() if x.name not in REPORT_FILES)
        if others:
            raise SceneError(key, f"{str(path)!r} holds other files ({', '.join(others[:3])}"
                             f"{', ...' if len(others) > 3 else ''}); give an empty or new folder, or an earlier report")
    return p


@contextlib.contextmanager
def atomic_folder(path):
    """Yield a temporary folder beside ``path``; on success it replaces ``path`` (an earlier
    report is swapped out and removed), on failure it is removed and ``path`` is untouched."""
    target = Path(path).resolve()
    tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}.", dir=target.parent))
    try:
        yield tmp
        old = None
        if target.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{target.name}.old.", dir=target.parent))
            os.rename(target, old / "report")
        os.rename(tmp, target)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


@contextlib.contextmanager
def atomic_file(path):
    """Yield a temporary name beside ``path``; on success it is renamed over ``path``, on any
    failure (Ctrl-C included) removed: ``path`` holds the old content or the new, never half."""
    target = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.stem}.", suffix=target.suffix, dir=target.parent or ".")
    os.close(fd)
    try:
        yield tmp
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def save_figure(fig, path) -> Path:
    """``fig.savefig`` to a temporary name beside ``path``, then renamed over it."""
    with atomic_file(path) as tmp:
        fig.savefig(tmp, bbox_inches="tight")
    return Path(path)


def write_text(path, text: str, check=None) -> Path:
    """Write ``text`` to a temporary file beside ``path``, call ``check(tmp_path)`` on it when
    given (it raises to refuse the file), then rename it over ``path``."""
    with atomic_file(path) as tmp:
        Path(tmp).write_text(text, encoding="utf-8")
        if check is not None:
            check(tmp)
    return Path(path)
