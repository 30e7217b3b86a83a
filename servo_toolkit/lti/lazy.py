"""A dataclass field that holds a linear block and reads as a python-control system.

The toolkit builds its blocks as :class:`~.system.StateSpace` (numpy alone); a result hands
them to its user as python-control systems, made on first read and kept. The toolkit's own
analyses read the block as built with :func:`block_of`, so a text verdict never imports
python-control.
"""

from __future__ import annotations

import dataclasses
import sys

from .system import StateSpace, as_system

_NO_DEFAULT = object()
#: :func:`dataclasses.replace` reads every field it is not given; it gets the block as stored
#: (no conversion), so a replaced result keeps the toolkit's own block
_REPLACE_CODES = frozenset(f.__code__ for f in (getattr(dataclasses, n, None) for n in ("replace", "_replace"))
                           if callable(f))


class ControlSystem:
    """Descriptor of a frozen dataclass's field holding a linear block.

    Set (by the dataclass's ``__init__`` or :func:`dataclasses.replace`) to a
    :class:`~.system.StateSpace`, a python-control system or None; read, it is the
    python-control system (converted once, on first read), except to
    :func:`dataclasses.replace`, which carries the block over as stored. ``default``: the
    field's default (none when not given).
    """

    def __init__(self, default=_NO_DEFAULT):
        self.default = default

    def __set_name__(self, owner, name):
        self.name = name
        self.slot = f"_{name}_block"
        self.cache = f"_{name}_control"

    def __get__(self, obj, owner=None):
        if obj is None:
            if self.default is _NO_DEFAULT:
                raise AttributeError(self.name)  # the dataclass field has no default
            return self.default
        if self.cache in obj.__dict__:
            return obj.__dict__[self.cache]
        value = obj.__dict__[self.slot]
        if sys._getframe(1).f_code in _REPLACE_CODES:
            return value
        if isinstance(value, StateSpace):
            value = _control_of(value)
        obj.__dict__[self.cache] = value
        return value

    def __set__(self, obj, value):
        if obj.__dict__.get(self.slot, _NO_DEFAULT) is not _NO_DEFAULT:
            raise AttributeError(f"cannot assign to field {self.name!r}")
        obj.__dict__[self.slot] = value


def _control_of(block: StateSpace):
    """The python-control system of ``block``, made once per block: results that share a
    block (one replaced from the other) read the same python-control object, as they would
    share one they were given."""
    made = block.__dict__.get("_control")
    if made is None:
        made = block.to_control()
        object.__setattr__(block, "_control", made)
    return made


def block_of(obj, name: str) -> StateSpace | None:
    """The block in field ``name`` of ``obj`` as a :class:`~.system.StateSpace` (as built,
    or read from the python-control system it was given as), without python-control."""
    value = obj.__dict__[f"_{name}_block"]
    return None if value is None else as_system(value)
