"""Output folders written atomically: built beside the target, every file flushed, then
published by one rename-swap (``renameat2(RENAME_EXCHANGE)`` where the kernel has it, else two
renames with SIGINT and SIGTERM held between them), so a failure, Ctrl-C or a second writer
leaves the old folder or the new one, never a mix. The path rules are :mod:`.files`'."""

from __future__ import annotations

import contextlib
import ctypes
import errno
import os
import shutil
import signal
import stat
import threading
from pathlib import Path

from ..errors import SceneError
from .files import _fsync, _lstat, _q, _temp_name


_RENAME_EXCHANGE = 2
_AT_FDCWD = -100
_exchange_state = {}


def _renameat2():
    """libc's renameat2, or None."""
    if "fn" not in _exchange_state:
        fn = None
        with contextlib.suppress(OSError, AttributeError):
            fn = ctypes.CDLL(None, use_errno=True).renameat2
            fn.argtypes = (ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint)
            fn.restype = ctypes.c_int
        _exchange_state["fn"] = fn
    return _exchange_state["fn"]


def _exchange(a, b) -> str:
    """Swap the folders ``a`` and ``b`` in one step: "done", "gone" (``b`` vanished) or
    "unsupported" (no renameat2, or a file system without RENAME_EXCHANGE)."""
    fn = _renameat2()
    if fn is None:
        return "unsupported"
    if fn(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE) == 0:
        return "done"
    err = ctypes.get_errno()
    if err == errno.ENOENT:
        return "gone"
    if err in (errno.EINVAL, errno.ENOSYS, errno.EOPNOTSUPP):
        return "unsupported"
    raise OSError(err, os.strerror(err), str(b))


@contextlib.contextmanager
def _signals_deferred():
    """Hold Ctrl-C and SIGTERM (main thread) while an output is published, then deliver them."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught, saved = [], {}

    def hold(signum, frame):
        caught.append(signum)
    for sig in (signal.SIGINT, signal.SIGTERM):
        old = signal.getsignal(sig)
        if old is not None:
            saved[sig] = old
            signal.signal(sig, hold)
    try:
        yield
    finally:
        for sig, old in saved.items():
            signal.signal(sig, old)
        for sig in dict.fromkeys(caught):
            signal.raise_signal(sig)


def _remove(path) -> None:
    if os.path.isdir(path) and not os.path.islink(path):
        shutil.rmtree(path, ignore_errors=True)
    else:
        with contextlib.suppress(OSError):
            os.unlink(path)


def _publish(tmp: str, target: Path, key: str) -> None:
    """Put the folder ``tmp`` at ``target`` in one rename (or one swap with the old output)."""
    for _ in range(100):  # another writer may be publishing the same folder: retry
        try:
            os.rename(tmp, target)  # absent (or an empty folder)
            return
        except OSError as exc:
            if exc.errno not in (errno.EEXIST, errno.ENOTEMPTY):
                raise
        st = _lstat(target)
        if st is None:
            continue
        if isinstance(st, OSError) or not stat.S_ISDIR(st.st_mode) or stat.S_ISLNK(st.st_mode):
            raise SceneError(key, f"{_q(target)} changed while the output was written; nothing replaced")
        state = _exchange(tmp, target)
        if state == "done":
            _remove(tmp)  # now the old output
            return
        if state == "gone":
            continue
        trash = _temp_name(target.parent, f".{target.name}.old.")
        try:
            os.rename(target, trash)
        except FileNotFoundError:
            continue
        try:
            os.rename(tmp, target)
        except OSError as exc:
            try:
                os.rename(trash, target)
            except OSError as back:
                # the rename failed because a folder with entries stood at the target: another
                # writer's complete output was in place (it may be swapped out again by now)
                if back.errno in (errno.EEXIST, errno.ENOTEMPTY):
                    _remove(trash)
                    continue
                raise SceneError(key, f"could not publish {_q(target)}; the earlier output is kept in "
                                 f"{_q(trash)}") from None
            if exc.errno not in (errno.EEXIST, errno.ENOTEMPTY):
                raise
            continue
        _remove(trash)
        return
    raise SceneError(key, f"could not publish {_q(target)}: other runs keep writing it")


@contextlib.contextmanager
def atomic_folder(path, key: str = "--output", parents: bool = False):
    """Yield a temporary folder beside ``path`` to fill; on success its files are flushed
    and it replaces ``path`` in one step (renameat2's exchange where the system has it,
    else two renames with Ctrl-C held between them), and the old output is removed. On any
    failure the temporary is removed and ``path`` is untouched. Two concurrent writers
    never fail on each other: one complete output stays. The new folder's mode follows
    the umask. With ``parents`` the missing folders above ``path`` are made, and removed
    again (those still empty) when the output fails.

    Raises
    ------
    SceneError
        ``key``: an OSError while writing or publishing.
    """
    target = Path(path).absolute()
    tmp = None
    made = []  # the folders above the output made here, deepest first
    try:
        try:
            if parents:
                above = target.parent
                while not above.exists():
                    made.append(above)
                    above = above.parent
                target.parent.mkdir(parents=True, exist_ok=True)
            while True:
                tmp = _temp_name(target.parent, f".{target.name}.")  # named before it exists: a signal
                try:                                                  # after mkdir still removes it
                    os.mkdir(tmp, 0o777)
                    break
                except FileExistsError:
                    continue
        except OSError as exc:
            tmp = None
            raise SceneError(key, f"cannot write {_q(path)}: {exc.strerror or exc}") from None
        yield Path(tmp)
        for root, _, names in os.walk(tmp):
            for name in names:
                _fsync(os.path.join(root, name))
        _fsync(tmp, directory=True)
        with _signals_deferred():
            _publish(tmp, target, key)
    except BaseException as exc:
        if tmp is not None:
            _remove(tmp)
        for folder in made:  # a concurrent writer's folder is not empty: left as it is
            try:
                os.rmdir(folder)
            except OSError:
                break
        if isinstance(exc, OSError):
            raise SceneError(key, f"cannot write {_q(path)}: {exc.strerror or exc}") from None
        raise
    _fsync(target.parent, directory=True)


__all__ = ["atomic_folder"]
