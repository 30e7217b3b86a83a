"""pint's unit registry, its definitions parsed once per pint version and read from the
user's cache afterwards.

Building pint's default registry parses its definitions file, a sizeable part of the start-up
of every command that reads a scene. pint can keep what it parsed in a folder (its
``cache_folder``); the toolkit gives it :func:`cache_folder`,
``<user cache>/servo_toolkit/pint/<pint version>``, written once into a temporary folder
beside it and published by one rename, so that two processes starting together never read a
half-written file and a new pint version starts a new folder. The registry is pint's own
either way, so every quantity parses exactly as without the cache. A cache that cannot be
written (a read-only home) or read (a damaged file) is passed over: the registry is then built
from the definitions, as it always was.
"""

from __future__ import annotations

import os
import pickle
import shutil
import tempfile
from pathlib import Path

import pint

from .user_cache import user_cache_root


def cache_folder() -> Path:
    """Folder of pint's parsed definitions: ``<user cache>/servo_toolkit/pint/<pint version>``
    (:func:`~.user_cache.user_cache_root`: ``$XDG_CACHE_HOME`` or ``~/.cache`` on Linux)."""
    return user_cache_root() / "servo_toolkit" / "pint" / pint.__version__


def _build_and_publish(folder: Path) -> pint.UnitRegistry:
    """A registry parsed from the definitions, its cache written beside ``folder`` and renamed
    into place (left to the process that got there first when two race)."""
    folder.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{folder.name}-", dir=folder.parent))
    try:
        registry = pint.UnitRegistry(cache_folder=tmp)
        try:
            os.rename(tmp, folder)
        except OSError:  # another process published it first (or the folder cannot take it)
            pass
        return registry
    finally:
        shutil.rmtree(tmp, ignore_errors=True)  # gone already when the rename succeeded


def unit_registry() -> pint.UnitRegistry:
    """pint's default registry, its parsed definitions read from :func:`cache_folder` when
    they are there, else parsed and stored there for the next process."""
    folder = cache_folder()
    try:
        if folder.is_dir():
            return pint.UnitRegistry(cache_folder=folder)
        return _build_and_publish(folder)
    except (OSError, EOFError, pickle.UnpicklingError, AttributeError, ImportError, ValueError, TypeError):
        return pint.UnitRegistry()  # an unwritable or damaged cache: parse the definitions here
