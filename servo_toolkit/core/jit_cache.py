"""Where the compiled simulation kernels are cached, and when the cache is stale.

numba caches a compiled function beside its source (``__pycache__``) and keys it on that
source file alone. Two things go wrong with that for the toolkit: an installation whose
package folder is not writable falls back to a per-user folder keyed on nothing of ours,
and the integration loops inline functions of other files (the right-hand side, the layout
constants, the cam kernels), so editing those leaves a stale compiled loop.

:func:`install` adds a cache locator, consulted before numba's own, for the toolkit's files
only: it puts their compiled code under :func:`cache_dir`, a folder named after the Python
and numba versions and a hash of every kernel source file, so any edit of a kernel starts a
fresh cache. The folder lies in the per-user cache, or in the user's ``NUMBA_CACHE_DIR`` when
that is set (the user chooses where, the hash still decides which code is current). Other
packages' numba functions are not affected.
"""

from __future__ import annotations

import hashlib
import os
import sys
from functools import lru_cache
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1]
#: the files whose code ends up in compiled kernels (any edit invalidates the cache)
KERNEL_SOURCES = ("core/jit_cache.py", "sim/*.py", "components/cam/kernels.py")


@lru_cache(maxsize=1)
def sources_hash() -> str:
    """First 16 hex digits of the SHA-256 of the kernel source files."""
    digest = hashlib.sha256()
    for pattern in KERNEL_SOURCES:
        for path in sorted(PACKAGE.glob(pattern)):
            digest.update(path.relative_to(PACKAGE).as_posix().encode())
            digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def user_cache_root() -> Path:
    """The user's cache folder: ``%LOCALAPPDATA%`` on Windows, ``~/Library/Caches`` on macOS,
    ``$XDG_CACHE_HOME`` or ``~/.cache`` elsewhere."""
    if sys.platform.startswith("win") and os.environ.get("LOCALAPPDATA"):
        return Path(os.environ["LOCALAPPDATA"])
    if sys.platform == "darwin":
        return Path.home() / "Library" / "Caches"
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")


def cache_dir() -> Path:
    """Folder of the toolkit's compiled kernels:
    ``<root>/servo_toolkit/numba/py<X.Y>-numba<version>-<sources hash>``, the root being
    ``NUMBA_CACHE_DIR`` when the user sets it, else the user's cache folder."""
    import numba
    tag = f"py{sys.version_info[0]}.{sys.version_info[1]}-numba{numba.__version__}-{sources_hash()}"
    root = Path(os.environ["NUMBA_CACHE_DIR"]) if os.environ.get("NUMBA_CACHE_DIR") else user_cache_root()
    return root / "servo_toolkit" / "numba" / tag


def _locator_class():
    from numba.core import caching

    class ToolkitCacheLocator(caching._SourceFileBackedLocatorMixin, caching._CacheLocator):
        """The toolkit's kernels: cached under :func:`cache_dir`."""

        def __init__(self, py_func, py_file):
            self._py_file = py_file
            self._lineno = py_func.__code__.co_firstlineno
            self._cache_path = str(cache_dir() / Path(py_file).resolve().relative_to(PACKAGE).parent)

        def get_cache_path(self):
            return self._cache_path

        @classmethod
        def from_function(cls, py_func, py_file):
            if not py_file:
                return None
            try:
                Path(py_file).resolve().relative_to(PACKAGE)
            except ValueError:
                return None
            parent = super(ToolkitCacheLocator, cls)
            return parent.from_function(py_func, py_file)

    return ToolkitCacheLocator


def install() -> None:
    """Register the toolkit's cache locator with numba (once; before any kernel is
    decorated)."""
    from numba.core import caching
    classes = caching.CacheImpl._locator_classes
    if any(getattr(c, "__name__", "") == "ToolkitCacheLocator" for c in classes):
        return
    classes.insert(0, _locator_class())
