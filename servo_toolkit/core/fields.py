"""Reading one scene table with key paths in every error."""

from __future__ import annotations

import difflib
import math
from collections.abc import Mapping
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass

from ..errors import SceneError
from .ranges import conditioned_range, range_rule
from .units import argument_value, is_bare_number, parse_quantity

_MISSING = object()

#: the reads being collected by :func:`recording_reads` in this context (None: not collecting)
_READS: ContextVar = ContextVar("servo_toolkit_scene_reads", default=None)
#: the notes being collected by :func:`collecting_notes` in this context (None: not collecting)
_NOTES: ContextVar = ContextVar("servo_toolkit_scene_notes", default=None)


def nearest_key(name: str, known) -> str | None:
    """The known key ``name`` most likely misspells (difflib's closest match, or a known key
    inside it: ``gear_ratio`` -> ``ratio``), None when none is close."""
    known = [k for k in known if k != name]
    close = difflib.get_close_matches(name, known, n=1, cutoff=0.6)
    if close:
        return close[0]
    inside = sorted((k for k in known if len(k) >= 3 and (k in name or name in k)), key=len, reverse=True)
    return inside[0] if inside else None


def _edits(a: str, b: str) -> int:
    """Levenshtein distance: the single-character edits that turn ``a`` into ``b``."""
    row = list(range(len(b) + 1))
    for i, ca in enumerate(a, 1):
        prev, row[0] = row[0], i
        for j, cb in enumerate(b, 1):
            prev, row[j] = row[j], min(row[j] + 1, row[j - 1] + 1, prev + (ca != cb))
    return row[-1]


def misspelling_of(name: str, written) -> str | None:
    """The key of ``written`` (keys a table writes that were not read) that misspells the
    required key ``name`` by a typo (at most one edit per five characters, ``leed``,
    ``resistanse``); stricter than :func:`nearest_key`, since a key not read yet may be
    another key of the table (``back_emf_constant`` is no misspelling of ``torque_constant``)."""
    typos = sorted((_edits(name, k), k) for k in written if k != name and _edits(name, k) <= max(1, len(name) // 5))
    return typos[0][1] if typos else None


def holder_of(name: str, written) -> str | None:
    """The shortest key of ``written`` whose name holds the required key ``name``
    (``gear_ratio`` holds ``ratio``): maybe meant for it, maybe another key of the table
    not read yet (``thermal_resistance_winding`` beside a missing ``resistance``)."""
    holding = sorted((k for k in written if len(name) >= 3 and name in k and k != name), key=len)
    return holding[0] if holding else None


def unknown_key_rule(name: str, known) -> str:
    """The rule an unknown key breaks: the nearest known key ("did you mean ratio?") and the
    known keys."""
    near = nearest_key(name, known)
    hint = f"did you mean {near}? " if near else ""
    return f"unknown key; {hint}known keys are {sorted(known)}"


@contextmanager
def collecting_notes():
    """Collect the notes :class:`Fields` makes while the block runs (a bare number far from
    its key's typical values).

    Yields
    ------
    list of str
        Filled as tables are read.
    """
    yield from _collecting(_NOTES)


def _collecting(var: ContextVar):
    """A fresh list set in ``var`` while the caller's block runs (the body of a collector)."""
    items: list = []
    token = var.set(items)
    try:
        yield items
    finally:
        var.reset(token)


@dataclass(frozen=True)
class KeyRead:
    """One key read by the scene loader, as :func:`recording_reads` collects it.

    Attributes
    ----------
    table : str
        Key path of the table, e.g. ``drivetrain[1]`` or ``studies.step``.
    kind : str or None
        The table's ``kind`` (stage, study or mechanism kind), if it has one.
    key : str
        The key's name inside the table.
    reader : str
        ``"quantity"``, ``"quantity list"``, ``"integer"``, ``"text"``, ``"number"``,
        ``"value"`` (read as written) or ``"optional"`` (asked whether it is present).
    unit : str or None
        SI unit the value is converted to.
    required : bool
        The loader has no default for it.
    default : object
        The default when absent (None when required).
    rule : str or None
        ``"positive"``, ``"nonnegative"``, ``"finite"``, ``"at least N"`` or None.
    choices : tuple or None
        Allowed values of a text key.
    written : object
        The value as the table writes it (None when absent).
    bounds : tuple or None
        ``(low, high)``: the range a finite value must lie in (see
        :mod:`servo_toolkit.core.ranges`), None when no range applies.
    """

    table: str
    kind: str | None
    key: str
    reader: str
    unit: str | None = None
    required: bool = False
    default: object = None
    rule: str | None = None
    choices: tuple | None = None
    written: object = None
    bounds: tuple | None = None


@contextmanager
def recording_reads():
    """Collect every key the scene loader reads while the block runs.

    Yields
    ------
    list of KeyRead
        Filled as tables are read; the scene reference of the documentation is generated
        from it, so it names exactly the keys, units, defaults and rules the loader applies.
    """
    yield from _collecting(_READS)


def _range_of(unit, rule, bounds):
    """The range a key in ``unit`` with ``rule`` is checked against (for the reference)."""
    return conditioned_range(unit, bounds) if unit is not None else None


class Fields:
    """Typed access to one TOML table; every error names ``path.key`` and the rule.

    Parameters
    ----------
    table : Mapping
        The parsed TOML table.
    path : str
        Key path of the table inside the scene, e.g. ``drivetrain[1]``.
    """

    def __init__(self, table: Mapping, path: str):
        if not isinstance(table, Mapping):
            raise SceneError(path, f"expected a table, got {type(table).__name__}")
        self.table = table
        self.path = path
        self._used = {"kind", "name"}

    def _note(self, name: str, reader: str, default=_MISSING, unit=None, rule=None, choices=None,
              bounds=None) -> None:
        reads = _READS.get()
        if reads is not None:
            kind = self.table.get("kind") if isinstance(self.table.get("kind"), str) else None
            required = default is _MISSING
            reads.append(KeyRead(self.path, kind, name, reader, unit, required,
                                 None if required else default, rule,
                                 tuple(sorted(choices)) if choices is not None else None,
                                 self.table.get(name), bounds))

    def key(self, name: str) -> str:
        """Full key path of ``name``."""
        return f"{self.path}.{name}" if self.path else name

    def has(self, name: str) -> bool:
        """True when the table defines ``name`` (a key of the table: an unknown key's error
        lists it among the known ones)."""
        self._note(name, "optional", None)
        self._used.add(name)
        return name in self.table

    def raw(self, name: str, default=_MISSING):
        """The value as written, or ``default``; missing without default is an error."""
        self._note(name, "value", default)
        self._used.add(name)
        if name in self.table:
            return self.table[name]
        if default is _MISSING:
            written = [k for k in self.table if k not in self._used and isinstance(k, str)]
            near = misspelling_of(name, written)
            if near is not None:  # a misspelt key is what the user wrote: name it, not the missing one
                raise SceneError(self.key(near), f"unknown key; did you mean {name}? ({name} is required and "
                                                 "not given)")
            holder = holder_of(name, written)
            if holder is not None:  # the table's other keys are not known yet: the missing one is the fact
                raise SceneError(self.key(name), f"missing key (required); the table writes {holder}: if that "
                                                 f"was meant for {name}, name it {name}")
            raise SceneError(self.key(name), "missing key (required)")
        return default

    def quantity(self, name: str, unit: str, default=_MISSING, *, rule: str | None = None,
                 bounds=None, typical=None) -> float:
        """A quantity converted to ``unit``.

        ``rule`` is one of ``"positive"``, ``"nonnegative"``, ``"finite"`` (always
        implied unless the default is infinite) or None. A finite value must also lie in
        the range its model is conditioned for: ``bounds`` ``(low, high)``, else the
        unit's range (:mod:`servo_toolkit.core.ranges`); an infinite one is allowed only
        where the rule is None (a rigid stage, no limit). ``typical`` ``(low, high)``: the
        values the key's physics makes plausible; a bare number (no unit written) outside
        them is read in ``unit`` all the same, with a note naming that unit
        (:func:`collecting_notes`): ``sample_time = 0.2`` is 0.2 s, most likely a slip for 0.2 ms;
        a third element is the unit the note's example is written in (default ``deg`` for an
        angle, else the unit with the prefix ``m``).
        """
        self._note(name, "quantity", default, unit, rule, bounds=_range_of(unit, rule, bounds))
        value = self.raw(name, default)
        if value is default and default is not _MISSING and not isinstance(default, str):
            return default
        result = self._checked(parse_quantity(value, unit, self.key(name)), name, rule, unit=unit, bounds=bounds)
        if typical is not None and is_bare_number(value) and result != 0 and math.isfinite(result) \
                and not typical[0] <= abs(result) <= typical[1]:
            self._note_unusual(name, result, unit, typical)
        return result

    def _note_unusual(self, name: str, value: float, unit: str, typical) -> None:
        """Note a bare number outside its key's typical values, naming the unit it was read in."""
        notes = _NOTES.get()
        if notes is not None:
            notes.append(f"{self.key(name)} = {value:g} has no unit and is read in {unit} (SI): "
                         f"{value:g} {unit} is outside the typical {typical[0]:g}..{typical[1]:g} {unit}; "
                         f"write the unit if another was meant (e.g. \"{value:g} "
                         f"{typical[2] if len(typical) > 2 else ('deg' if unit == 'rad' else 'm' + unit)}\")")

    def quantity_list(self, name: str, unit: str, default=_MISSING, *, rule=None, bounds=None) -> tuple:
        """A list of quantities converted to ``unit``, each checked as :meth:`quantity` does."""
        self._note(name, "quantity list", default, unit, rule, bounds=_range_of(unit, rule, bounds))
        value = self.raw(name, default)
        if value is default and default is not _MISSING:
            return tuple(default)
        if not isinstance(value, list):
            raise SceneError(self.key(name), "expected a list")
        return tuple(self._checked(parse_quantity(v, unit, f"{self.key(name)}[{i}]"), name, rule,
                                   f"{self.key(name)}[{i}]", unit=unit, bounds=bounds)
                     for i, v in enumerate(value))

    def integer(self, name: str, default=_MISSING, *, minimum: int | None = None) -> int:
        """An integer, optionally at least ``minimum``."""
        self._note(name, "integer", default, rule=None if minimum is None else f"at least {minimum}")
        value = self.raw(name, default)
        if isinstance(value, bool) or not isinstance(value, int):
            raise SceneError(self.key(name), f"expected an integer, got {value!r}")
        if minimum is not None and value < minimum:
            raise SceneError(self.key(name), f"must be at least {minimum} (got {value})")
        return value

    def text(self, name: str, default=_MISSING, choices=None) -> str:
        """A string, optionally one of ``choices``."""
        self._note(name, "text", default, choices=choices)
        value = self.raw(name, default)
        if not isinstance(value, str):
            raise SceneError(self.key(name), f"expected a string, got {value!r}")
        if choices is not None and value not in choices:
            raise SceneError(self.key(name), f"must be one of {sorted(choices)} (got {value!r})")
        return value

    def number(self, name: str, default=_MISSING, *, rule=None, bounds=None) -> float:
        """A plain dimensionless number."""
        self._note(name, "number", default, rule=rule)
        return self.quantity(name, "dimensionless", default, rule=rule, bounds=bounds)

    def _checked(self, value: float, name: str, rule, key: str | None = None, *, unit=None,
                 bounds=None) -> float:
        key = key or self.key(name)
        check_rule(value, rule, key)
        if math.isfinite(value) and unit is not None:
            broken = range_rule(value, rule if rule is not None or value <= 0 else "positive", unit, bounds)
            if broken:
                raise SceneError(key, broken)
        return value

    def check_unknown(self) -> None:
        """Reject keys the component does not know (catches typos)."""
        unknown = sorted(set(self.table) - self._used)
        if unknown:
            raise SceneError(self.key(unknown[0]), unknown_key_rule(unknown[0], self._used - {"kind"}))


def check_rule(value: float, rule: str | None, key: str) -> None:
    """SceneError naming ``key`` when ``value`` breaks a key's sign rule: ``"positive"``,
    ``"nonnegative"``, ``"finite"`` (each finite), ``"limit"`` (positive, infinity for none)
    or None (any number but NaN)."""
    if math.isnan(value):
        raise SceneError(key, "value is NaN")
    if rule in ("positive", "limit") and not value > 0:
        raise SceneError(key, f"must be positive (got {value:g})")
    if rule == "nonnegative" and not value >= 0:
        raise SceneError(key, f"must not be negative (got {value:g})")
    if rule in ("positive", "nonnegative", "finite") and math.isinf(value):
        raise SceneError(key, "must be finite")


def field_value(value, unit: str, rule: str | None, key: str) -> float:
    """A component's field as set from Python (a dataclass's ``__post_init__``, so that
    ``dataclasses.replace`` meets the scene file's rule): a real number in SI or a pint
    Quantity (converted), checked with :func:`check_rule`; SceneError naming ``key``."""
    value = argument_value(value, unit, key, finite=False)
    check_rule(value, rule, key)
    return value


def require(condition: bool, key: str, rule: str) -> None:
    """Raise :class:`SceneError` for ``key`` with ``rule`` unless ``condition`` holds."""
    if not condition:
        raise SceneError(key, rule)
