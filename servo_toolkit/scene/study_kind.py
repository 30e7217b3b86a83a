"""Study kinds: what a ``[studies.NAME]`` table's ``kind`` names, described once.

A :class:`StudyKind` says everything the toolkit needs to know about one kind of study: the
keys its table takes (checked when the scene loads), the function that runs it, the class of
its result, the command that runs it, its report section, and the few facts other steps ask
of it (whether its sine amplitudes must fit the stroke, whether its runs are time
simulations, whether another kind's study may run as it). The scene defines this
interface; the studies provide it (a dependency inversion: the scene layer names the
runners by string and imports them only when a study runs).

The registry, :func:`study_kinds`, holds

- every ``KINDS`` tuple of a ``kind.py`` module in a subpackage of
  :mod:`servo_toolkit.studies` (adding a built-in kind is adding one folder: ``kind.py``,
  its computation and its result), and
- every entry point of the group ``servo_toolkit.studies`` (each a :class:`StudyKind`), so
  that an installed package adds a kind without editing the toolkit.

A descriptor module imports only the scene's and core's helpers, never a study's
computation, so that loading a scene stays quick.
"""

from __future__ import annotations

import functools
import sys
from dataclasses import dataclass, field, replace
from importlib import import_module, metadata
from pathlib import Path
from types import MappingProxyType

from ..errors import SceneError

#: the entry-point group of the study kinds installed packages add
ENTRY_POINT_GROUP = "servo_toolkit.studies"
#: the package whose subpackages hold the built-in kinds (each in its ``kind.py``)
BUILTIN_PACKAGE = "servo_toolkit.studies"
#: the command that runs a study of any kind
GENERIC_COMMAND = "study"
#: how a kind's sine amplitudes are checked against the stroke when the scene loads:
#: about the design's operating point, or about the study's ``offset`` (default mid-stroke)
STROKE_CENTRES = ("operating_point", "offset")


@dataclass(frozen=True)
class StudyKind:
    """One kind of ``[studies.NAME]`` table.

    Attributes
    ----------
    name : str
        The ``kind`` string of the scene's table.
    summary : str
        One line: what a study of this kind computes.
    schema : mapping
        Key -> ``(unit, rule)`` of the table, in :mod:`servo_toolkit.scene.study_schema`'s
        format (a unit, ``[unit]`` for a list, a tuple of choices for text, or one of its
        named readers; the rule of :func:`servo_toolkit.core.fields.Fields.quantity`).
    run : str
        ``"module:function"``; the function is ``run(scene, study, **options) -> result``.
    result : str
        ``"module:Class"`` of the result (``to_dict()``, ``plot()``, ``repr``).
    command : str
        The command that runs it (``servo-toolkit COMMAND``); every kind also runs with
        ``servo-toolkit study SCENE NAME``.
    section : str or None
        ``"module:function"`` building its report section from the report's context, or
        None for the generic section (each study's result table and figure).
    section_title, section_key : str
        Title and key of that section (defaults: from the name).
    section_rank : int
        Place of its section among the study kinds' sections (lower first).
    in_report : bool
        False: the report shows no section of its own for this kind (its studies appear in
        another section, or nowhere).
    stroke : {"operating_point", "offset"} or None
        How the scene's loader checks the study's sine amplitudes against the stroke (about
        the design's operating point, or about the study's ``offset``); None: not checked.
    time_run : bool
        Its runs are time simulations of the scene's model (a model reduced for the scene
        serves them, and its frequencies count among the scene's).
    runs_other_kinds : bool
        A study of another kind may run as this kind (``run_study(..., as_kind=NAME)``).
    mechanism_only : bool
        It runs only as a seed-mechanism study of a matching scene (no runner of its own).
    origin : str
        Where the registry found it (its ``kind.py`` module or its entry point); set by
        :func:`study_kinds`.
    """

    name: str
    summary: str
    schema: MappingProxyType
    run: str
    result: str
    command: str = GENERIC_COMMAND
    section: str | None = None
    section_title: str = ""
    section_key: str = ""
    section_rank: int = 100
    in_report: bool = True
    stroke: str | None = None
    time_run: bool = False
    runs_other_kinds: bool = False
    mechanism_only: bool = False
    origin: str = field(default="", compare=False)

    def __post_init__(self):
        if not self.name or not isinstance(self.name, str) or not self.name.isidentifier():
            raise ValueError(f"a study kind's name must be an identifier (got {self.name!r})")
        if self.stroke not in (None, *STROKE_CENTRES):
            raise ValueError(f"study kind {self.name!r}: stroke must be None or one of {STROKE_CENTRES}")
        for name in ("run", "result") + (("section",) if self.section is not None else ()):
            value = getattr(self, name)
            if not (isinstance(value, str) and value.count(":") == 1 and all(value.split(":"))):
                raise ValueError(f"study kind {self.name!r}: {name} must be 'module:name' (got {value!r})")
        object.__setattr__(self, "schema", MappingProxyType(dict(self.schema)))
        object.__setattr__(self, "section_title", self.section_title or f"Studies of kind {self.name}")
        object.__setattr__(self, "section_key", self.section_key or self.name)

    @property
    def commands(self) -> str:
        """The commands that run a study of this kind, as a user types them: e.g.
        ``"servo-toolkit kv or servo-toolkit study"``."""
        return " or ".join(f"servo-toolkit {c}" for c in dict.fromkeys((self.command, GENERIC_COMMAND)))

    def resolve(self, name: str):
        """The object named by field ``name`` (``"run"``, ``"result"`` or ``"section"``),
        imported now."""
        target = getattr(self, name)
        if target is None:
            raise ValueError(f"study kind {self.name!r} names no {name}")
        module, _, attr = target.partition(":")
        return getattr(import_module(module), attr)


def _builtin_modules() -> list:
    """Names of the ``kind.py`` modules of the subpackages of :data:`BUILTIN_PACKAGE`,
    found by scanning its folder (nothing is imported to find them)."""
    package = import_module(BUILTIN_PACKAGE)
    out = []
    for folder in package.__path__:
        for sub in sorted(Path(folder).iterdir()):
            if (sub / "__init__.py").is_file() and (sub / "kind.py").is_file():
                out.append(f"{BUILTIN_PACKAGE}.{sub.name}.kind")
    return out


def _add(found: dict, kind, origin: str) -> None:
    if not isinstance(kind, StudyKind):
        raise TypeError(f"{origin} gives {type(kind).__name__}, not a StudyKind")
    if kind.name in found:
        raise ValueError(f"study kind {kind.name!r} is registered twice: by {found[kind.name].origin} and by {origin}")
    found[kind.name] = replace(kind, origin=origin)


@functools.lru_cache(maxsize=8)
def _registry(path: tuple) -> MappingProxyType:
    """The registry for the import path ``path`` (a cache: a changed ``sys.path`` reads
    the entry points again)."""
    found = {}
    for module in _builtin_modules():
        for kind in getattr(import_module(module), "KINDS", ()):
            _add(found, kind, module)
    for entry in sorted(metadata.entry_points(group=ENTRY_POINT_GROUP), key=lambda e: e.name):
        _add(found, entry.load(), f"the entry point {entry.name!r} ({entry.value})")
    return MappingProxyType(found)


def study_kinds() -> MappingProxyType:
    """Every registered study kind: name -> :class:`StudyKind` (built-in ones, then those
    of the ``servo_toolkit.studies`` entry points).

    Raises
    ------
    ValueError
        Two kinds of one name.
    TypeError
        An entry point that is not a :class:`StudyKind`.
    """
    return _registry(tuple(sys.path))


def study_kind(name: str, key: str = "kind") -> StudyKind:
    """The registered kind ``name``.

    Raises
    ------
    SceneError
        Naming ``key``: no such kind; the message lists the registered ones.
    """
    kinds = study_kinds()
    if name not in kinds:
        raise SceneError(key, f"unknown study kind {name!r}; must be one of the registered kinds "
                              f"{', '.join(sorted(kinds))}")
    return kinds[name]


__all__ = ["ENTRY_POINT_GROUP", "GENERIC_COMMAND", "STROKE_CENTRES", "StudyKind", "study_kind", "study_kinds"]
