"""Reading one scene table with key paths in every error."""

from __future__ import annotations

import math
from collections.abc import Mapping

from .errors import SceneError
from .units import parse_quantity

_MISSING = object()


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

    def key(self, name: str) -> str:
        """Full key path of ``name``."""
        return f"{self.path}.{name}" if self.path else name

    def has(self, name: str) -> bool:
        """True when the table defines ``name``."""
        return name in self.table

    def raw(self, name: str, default=_MISSING):
        """The value as written, or ``default``; missing without default is an error."""
        self._used.add(name)
        if name in self.table:
            return self.table[name]
        if default is _MISSING:
            raise SceneError(self.key(name), "missing key (required)")
        return default

    def quantity(self, name: str, unit: str, default=_MISSING, *, rule: str | None = None) -> float:
        """A quantity converted to ``unit``.

        ``rule`` is one of ``"positive"``, ``"nonnegative"``, ``"finite"`` (always
        implied unless the default is infinite) or None.
        """
        value = self.raw(name, default)
        if value is default and default is not _MISSING and not isinstance(default, str):
            return default
        return self._checked(parse_quantity(value, unit, self.key(name)), name, rule)

    def quantity_list(self, name: str, unit: str, default=_MISSING, *, rule=None) -> tuple:
        """A list of quantities converted to ``unit``."""
        value = self.raw(name, default)
        if value is default and default is not _MISSING:
            return tuple(default)
        if not isinstance(value, list):
            raise SceneError(self.key(name), "expected a list")
        return tuple(self._checked(parse_quantity(v, unit, f"{self.key(name)}[{i}]"), name, rule,
                                   f"{self.key(name)}[{i}]") for i, v in enumerate(value))

    def integer(self, name: str, default=_MISSING, *, minimum: int | None = None) -> int:
        """An integer, optionally at least ``minimum``."""
        value = self.raw(name, default)
        if isinstance(value, bool) or not isinstance(value, int):
            raise SceneError(self.key(name), f"expected an integer, got {value!r}")
        if minimum is not None and value < minimum:
            raise SceneError(self.key(name), f"must be at least {minimum} (got {value})")
        return value

    def text(self, name: str, default=_MISSING, choices=None) -> str:
        """A string, optionally one of ``choices``."""
        value = self.raw(name, default)
        if not isinstance(value, str):
            raise SceneError(self.key(name), f"expected a string, got {value!r}")
        if choices is not None and value not in choices:
            raise SceneError(self.key(name), f"must be one of {sorted(choices)} (got {value!r})")
        return value

    def number(self, name: str, default=_MISSING, *, rule=None) -> float:
        """A plain dimensionless number."""
        return self.quantity(name, "dimensionless", default, rule=rule)

    def _checked(self, value: float, name: str, rule, key: str | None = None) -> float:
        key = key or self.key(name)
        if math.isnan(value):
            raise SceneError(key, "value is NaN")
        if rule == "positive" and not value > 0:
            raise SceneError(key, f"must be positive (got {value:g})")
        if rule == "nonnegative" and not value >= 0:
            raise SceneError(key, f"must not be negative (got {value:g})")
        if rule in ("positive", "nonnegative", "finite") and math.isinf(value):
            raise SceneError(key, "must be finite")
        return value

    def check_unknown(self) -> None:
        """Reject keys the component does not know (catches typos)."""
        unknown = sorted(set(self.table) - self._used)
        if unknown:
            raise SceneError(self.key(unknown[0]),
                             f"unknown key; known keys are {sorted(self._used - {'kind'})}")


def require(condition: bool, key: str, rule: str) -> None:
    """Raise :class:`SceneError` for ``key`` with ``rule`` unless ``condition`` holds."""
    if not condition:
        raise SceneError(key, rule)
