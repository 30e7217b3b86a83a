"""A study result's scalars as a table with units, read from its ``to_dict()``.

A result of a study kind without a table of its own (:mod:`servo_toolkit.scene.study_kind`)
is shown by the ``study`` command and the report's generic section as the scalars of its
``to_dict()``: each number, text or flag at the top level (lists and nested tables are left
to its JSON and figure). A key's unit is read from its suffix, the toolkit's convention for
JSON keys (``peak_speed_rad_s`` -> rad/s, ``energy_J`` -> J), or from a ``units`` mapping
of the dictionary (key -> unit); a key with neither shows ``-``.
"""

from __future__ import annotations

import math

#: key suffix -> unit, longest first where one suffix ends another
UNIT_SUFFIXES = (("_rad_s2", "rad/s^2"), ("_rad_s", "rad/s"), ("_m_s2", "m/s^2"), ("_m_s", "m/s"),
                 ("_kg_m2", "kg*m^2"), ("_Nm", "N*m"), ("_rad", "rad"), ("_deg", "deg"), ("_mm", "mm"),
                 ("_Hz", "Hz"), ("_kg", "kg"), ("_J", "J"), ("_W", "W"), ("_N", "N"), ("_A", "A"), ("_V", "V"),
                 ("_m", "m"), ("_s", "s"), ("_pct", "%"), ("_dB", "dB"))


def unit_of(key: str, units=None) -> str:
    """The unit of JSON key ``key``: from ``units`` (a mapping), else from its suffix, else ``-``."""
    if units and key in units:
        return str(units[key])
    return next((unit for suffix, unit in UNIT_SUFFIXES if key.endswith(suffix) and len(key) > len(suffix)), "-")


def _text(value) -> str:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return str(value)
    if isinstance(value, int):
        return str(value)
    return f"{value:.6g}" if math.isfinite(value) else str(value)


def scalar_rows(data: dict) -> list:
    """``(key, value text, unit)`` of each scalar of ``data`` (a result's ``to_dict()``) in order."""
    units = data.get("units") if isinstance(data.get("units"), dict) else None
    return [(key, _text(value), unit_of(key, units)) for key, value in data.items()
            if isinstance(value, (str, int, float, bool)) or value is None]


def text_table(rows, head=("quantity", "value", "unit")) -> str:
    """``rows`` as aligned plain-text columns under ``head``."""
    rows = [tuple(head)] + [tuple(r) for r in rows]
    widths = [max(len(r[i]) for r in rows) for i in range(len(head))]
    return "\n".join("  ".join(cell.ljust(w) for cell, w in zip(r, widths)).rstrip() for r in rows)


__all__ = ["UNIT_SUFFIXES", "scalar_rows", "text_table", "unit_of"]
