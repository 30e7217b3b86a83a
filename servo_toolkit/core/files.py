"""Every file the toolkit reads from or writes for a user goes through here.

Outputs are checked before any work and written atomically: a temporary file (or folder)
beside the target, flushed to disk, then renamed into place, so a failure, a full disk,
Ctrl-C or two concurrent runs leave the old output or the new one, never half of one, and no
temporary behind. The rules of an output path:

- it is absent or a regular file (a folder output: absent, empty, or an earlier output of the
  same command); a device, FIFO, socket or folder is refused;
- an output path that is a symbolic link is refused, whatever it points to: the toolkit never
  writes through a link, nor replaces one;
- it is never one of the command's inputs (compared after resolving links, and by device
  and inode, so hard links count);
- a read-only file is refused, and its folder must exist and take a new file (probed);
- with ``earlier``, an existing file is replaced only when it is an earlier output of the
  command, told by its content (:mod:`.marks`: a stamped text unchanged, a marked figure);
- a new file's or folder's mode follows the umask (a replaced file keeps its mode).

Folders are published by :mod:`.folders`; inputs are read by :mod:`.inputs`.
"""

from __future__ import annotations

import contextlib
import os
import secrets
import stat
from pathlib import Path

from ..errors import SceneError

#: figure formats matplotlib writes without extra packages
FIGURE_SUFFIXES = (".png", ".svg", ".pdf", ".eps", ".ps", ".jpg", ".jpeg", ".tif", ".tiff", ".webp")


def _q(path) -> str:
    return repr(str(path))


def same_file(a, b) -> bool:
    """True when ``a`` and ``b`` name one file (after links; same device and inode)."""
    with contextlib.suppress(OSError, ValueError):
        if Path(a).resolve() == Path(b).resolve():
            return True
        sa, sb = os.stat(a), os.stat(b)
        return (sa.st_dev, sa.st_ino) == (sb.st_dev, sb.st_ino)
    return False


def _lstat(path):
    try:
        return os.lstat(path)
    except (FileNotFoundError, NotADirectoryError):
        return None
    except OSError as exc:
        return exc


def _probe(folder, key: str, path) -> None:
    """Create and remove a file in ``folder``: the only sure test that an output can be
    written there (permissions, a read-only file system)."""
    try:
        name = os.path.join(folder, f".servo-toolkit-probe.{secrets.token_hex(6)}")
        os.close(os.open(name, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600))
        os.unlink(name)
    except OSError as exc:
        raise SceneError(key, f"cannot write {_q(path)}: {exc.strerror or exc}") from None


def check_named(path, key: str, what: str) -> None:
    """An empty path (an unset variable in a script: ``-o "$OUT"``) names no output: refused
    rather than read as the current folder."""
    if not str(os.fspath(path)).strip():
        raise SceneError(key, f"is empty: give the {what} to write")


def check_output_file(path, key: str, suffixes=None, inputs=(), earlier=None) -> Path:
    """Check, before any work, that a file may be written at ``path``.

    Parameters
    ----------
    path : str or path-like
    key : str
        The option (or argument) named in the error.
    suffixes : sequence of str, optional
        The file name must end in one of these (lower case, with the dot).
    inputs : sequence of path
        Files the command reads: the output is never one of them.
    earlier : tuple (callable, str), optional
        ``(test, what)``: an existing file is replaced only when ``test(path)`` tells it is an
        earlier output of the command (:mod:`.marks`), ``what`` naming that output; else it
        is refused (nothing a user has is overwritten). None: any regular file is replaced.

    Returns
    -------
    pathlib.Path

    Raises
    ------
    SceneError
        Naming ``key`` and the rule: a wrong suffix, one of the inputs, a symbolic link, a
        folder, a device, FIFO or socket, a read-only file, an existing file that is not an
        earlier output (with ``earlier``), a folder that does not exist or does not take a
        new file, an empty path.
    """
    check_named(path, key, "file")
    p = Path(path)
    if suffixes and p.suffix.lower() not in suffixes:
        raise SceneError(key, f"{p.name!r} must end in one of {', '.join(suffixes)}")
    for name in inputs:
        if name is not None and same_file(p, name):
            raise SceneError(key, f"refusing to overwrite the input {_q(name)} with {_q(path)}")
    st = _lstat(p)
    if isinstance(st, OSError):
        raise SceneError(key, f"cannot write {_q(path)}: {st.strerror or st}")
    if st is not None:
        if stat.S_ISLNK(st.st_mode):
            raise SceneError(key, f"refusing to write {_q(path)}: it is a symbolic link (to "
                             f"{os.readlink(p)!r}); give the file itself or remove the link")
        if stat.S_ISDIR(st.st_mode):
            raise SceneError(key, f"cannot write {_q(path)}: it is a directory")
        if not stat.S_ISREG(st.st_mode):
            raise SceneError(key, f"refusing to write {_q(path)}: it is a device, FIFO or socket, not a regular file")
        if not st.st_mode & 0o222 or not os.access(p, os.W_OK):
            raise SceneError(key, f"refusing to overwrite {_q(path)}: it is read-only")
        if earlier is not None and not earlier[0](p):
            raise SceneError(key, f"refusing to overwrite {_q(path)}: it exists and is not {earlier[1]}; give a "
                                  f"new file name, or remove the file first")
    parent = p.parent
    if not parent.is_dir():
        raise SceneError(key, f"cannot write {_q(path)}: folder {_q(parent)} does not exist")
    _probe(parent, key, path)
    return p


def _regular_or_gone(path: Path) -> bool:
    """True for a regular file, or an entry another writer's swap removed since the listing."""
    try:
        return stat.S_ISREG(os.lstat(path).st_mode)
    except FileNotFoundError:
        return True


def _lacks_mark(path: Path, mark: bytes) -> bool:
    """True for a file whose first :data:`MARK_BYTES` do not hold ``mark`` (not one the
    command wrote); an entry another writer's swap removed since the listing is not judged."""
    try:
        with open(path, "rb") as fh:
            return mark not in fh.read(MARK_BYTES)
    except FileNotFoundError:
        return False
    except OSError:
        return True


#: how far into a file of an earlier output its mark is looked for
MARK_BYTES = 64 * 1024


def check_output_folder(path, key: str, allowed=(), inputs=(), parents: bool = False, marks=None,
                        anchors=()) -> Path:
    """Check, before any work, that a folder output may be (re)written at ``path``.

    Parameters
    ----------
    path : str or path-like
    key : str
        The option (or argument) named in the error.
    allowed : collection of str
        The files of an earlier output of the command: a folder holding only these (regular
        files) is replaced whole; any other content is refused.
    inputs : sequence of path
        Files the command reads: none may lie in the folder.
    parents : bool
        Missing parent folders will be created (else the parent must exist).
    marks : mapping of str to bytes, optional
        Bytes each of these files of an earlier output holds near its start (e.g. the
        generator's name): a file of that name without them is the user's, and the folder
        is refused.
    anchors : collection of str
        Files of which an earlier output holds at least one (each with its mark): a
        non-empty folder holding none of them is not an earlier output and is refused (a
        user's own ``report.pdf`` carries no mark of the command; the report's
        ``index.html`` beside it does).

    Returns
    -------
    pathlib.Path

    Raises
    ------
    SceneError
        Naming ``key`` and the rule (an empty path too).
    """
    check_named(path, key, "folder")
    p = Path(path)
    st = _lstat(p)
    if isinstance(st, OSError):
        raise SceneError(key, f"cannot write {_q(path)}: {st.strerror or st}")
    if st is not None:
        if stat.S_ISLNK(st.st_mode):
            raise SceneError(key, f"refusing to write {_q(path)}: it is a symbolic link (to "
                             f"{os.readlink(p)!r}); give the folder itself or remove the link")
        if not stat.S_ISDIR(st.st_mode):
            raise SceneError(key, f"{_q(path)} exists and is not a folder")
    for name in inputs:
        if name is None:
            continue
        inside = False
        with contextlib.suppress(OSError, ValueError):
            inside = p.resolve() in Path(name).resolve().parents
        if inside or any(same_file(p / entry, name) for entry in allowed):
            raise SceneError(key, f"the output would overwrite its input {_q(name)}")
    if st is not None:
        try:
            entries = os.listdir(p)
        except FileNotFoundError:  # another writer is swapping its set in (two renames)
            entries = []
        others = sorted(e for e in entries if e not in allowed or not _regular_or_gone(p / e))
        if others:
            raise SceneError(key, f"{_q(path)} holds other files ({', '.join(others[:3])}"
                             f"{', ...' if len(others) > 3 else ''}); give an empty or new folder, or an "
                             f"earlier output of this command")
        foreign = sorted(e for e in entries if e in (marks or {}) and _lacks_mark(p / e, marks[e]))
        if foreign:
            raise SceneError(key, f"{_q(path)} holds {', '.join(foreign)} not written by this command; give an "
                             f"empty or new folder, or an earlier output of this command")
        if anchors and entries and not any(e in entries for e in anchors):
            raise SceneError(key, f"{_q(path)} holds {', '.join(sorted(entries))} without the "
                             f"{' or '.join(sorted(anchors))} an earlier output of this command has beside it; "
                             f"give an empty or new folder, or an earlier output of this command")
    parent = p.absolute().parent
    if parents:
        while not parent.exists() and parent != parent.parent:
            parent = parent.parent
        if not parent.is_dir():
            raise SceneError(key, f"cannot write into {_q(parent)}: it is not a folder")
    elif not parent.is_dir():
        raise SceneError(key, f"cannot write {_q(path)}: folder {_q(parent)} does not exist")
    _probe(parent, key, path)
    return p


def _temp_name(parent, prefix: str, suffix: str = "") -> str:
    return os.path.join(parent, f"{prefix}{secrets.token_hex(6)}{suffix}")


def _fsync(path, directory: bool = False) -> None:
    """Flush a file to disk; a folder (the rename in it) on a best-effort basis."""
    try:
        fd = os.open(path, os.O_RDONLY | (os.O_DIRECTORY if directory else 0))
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
    except OSError:
        if not directory:
            raise


@contextlib.contextmanager
def atomic_file(path, key: str = "--output"):
    """Yield a temporary path beside ``path`` (same suffix) to write; on success it is
    flushed to disk and renamed over ``path``. On any failure (a full disk, Ctrl-C, an
    exception of the writer) the temporary is removed and ``path`` keeps its old content.

    A new file's mode follows the umask; a replaced file keeps its mode.

    Raises
    ------
    SceneError
        ``key``: an OSError while writing (e.g. no space left on the device).
    """
    target = Path(path)
    parent = target.parent
    tmp = None
    try:
        while True:  # named before it exists: a signal right after its creation still removes it
            tmp = _temp_name(parent, f".{target.name}.", target.suffix)
            try:
                os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC, 0o666))
                break
            except FileExistsError:
                continue
        with contextlib.suppress(FileNotFoundError):
            old = os.stat(target)
            if stat.S_ISREG(old.st_mode):
                os.chmod(tmp, stat.S_IMODE(old.st_mode))
        yield Path(tmp)
        _fsync(tmp)
        os.replace(tmp, target)
    except BaseException as exc:
        with contextlib.suppress(OSError, TypeError):
            os.unlink(tmp)
        if isinstance(exc, OSError):
            raise SceneError(key, f"cannot write {_q(path)}: {exc.strerror or exc}") from None
        raise
    _fsync(parent, directory=True)


def write_text(path, text: str, key: str = "--output", check=None) -> Path:
    """Write ``text`` (UTF-8) atomically to ``path``; ``check(tmp_path)``, when given, sees
    the written temporary first and raises to refuse it."""
    with atomic_file(path, key) as tmp:
        with open(tmp, "w", encoding="utf-8", newline="\n") as fh:
            fh.write(text)
        if check is not None:
            check(tmp)
    return Path(path)


def check_figure_file(path, key: str = "--plot", inputs=()) -> Path:
    """:func:`check_output_file` for a figure: one of :data:`FIGURE_SUFFIXES`, and an
    existing file only when it is a figure the toolkit wrote (its metadata,
    :func:`.marks.figure_marked`)."""
    from .marks import figure_marked
    return check_output_file(path, key, FIGURE_SUFFIXES, inputs=inputs,
                             earlier=(figure_marked, "a figure servo-toolkit wrote (PNG, SVG, PDF, PS or EPS)"))


def check_stamped_file(path, key: str, command: str, suffixes=None, inputs=()) -> Path:
    """:func:`check_output_file` for a text output of ``command`` written with
    :func:`.marks.stamp`: an existing file only when it is that command's output, unchanged."""
    from .marks import stamped_by
    return check_output_file(path, key, suffixes, inputs=inputs,
                             earlier=(lambda p: stamped_by(p, command),
                                      f"an unchanged output of servo-toolkit {command}"))


def save_figure(fig, path, key: str = "--plot") -> Path:
    """``fig.savefig`` atomically to ``path`` (format from its suffix), marked as the
    toolkit's where the format takes metadata (:func:`.marks.figure_metadata`)."""
    from .marks import figure_metadata
    with atomic_file(path, key) as tmp:
        fig.savefig(tmp, bbox_inches="tight", metadata=figure_metadata(Path(path).suffix))
    return Path(path)


__all__ = ["FIGURE_SUFFIXES", "atomic_file", "check_figure_file", "check_named", "check_output_file",
           "check_stamped_file", "check_output_folder", "same_file", "save_figure",
           "write_text"]
