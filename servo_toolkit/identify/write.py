"""The scene file's text with fitted values put in place, line by line.

Each fitted key's line keeps its unit as the file writes it (``"1696.8 N*m/deg"`` becomes
``"1357.4 N*m/deg"``) and gains a trailing comment ``# fitted: was <old value>``; every other
line (comments, order, formatting) stays as it was. A key the file does not write (the
loader's default applied) is added as the first line of its table. A parameter the data
could not identify at all (no influence) keeps its line.
"""

from __future__ import annotations

import math
import re

from ..errors import SceneError
from ..core.units import parse_quantity

_HEADER = re.compile(r"^\s*(\[\[?)\s*([A-Za-z0-9_.\-\"' ]+?)\s*\]\]?\s*(#.*)?$")
_NUMBER = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(.*?)\s*$")


def _table_paths(lines):
    """For each line, the key path of the table it belongs to ("" before the first header),
    and the index of each table's header line."""
    counts: dict = {}
    current, paths, headers = "", [], {}
    for n, line in enumerate(lines):
        m = _HEADER.match(line)
        if m and not line.lstrip().startswith("#"):
            name = m.group(2).replace('"', "").replace("'", "").replace(" ", "")
            if m.group(1) == "[[":
                idx = counts.get(name, 0)
                counts[name] = idx + 1
                current = f"{name}[{idx}]"
            else:
                current = name
            headers[current] = n
        paths.append(current)
    return paths, headers


def _format(value_si: float, written, unit: str, key: str) -> str:
    """The new value in the unit the file writes (SI bare number when it writes none)."""
    if isinstance(written, str):
        m = _NUMBER.match(written)
        if m and m.group(2):
            factor = parse_quantity(f"1 {m.group(2)}", unit, key)
            return f'"{value_si / factor:.6g} {m.group(2)}"'
        return f'"{value_si:.6g} {unit}"'
    return f"{value_si:.6g}"


def calibrated_text(text: str, result) -> str:
    """``text`` (a scene file) with the fitted values of ``result`` in place.

    Parameters
    ----------
    text : str
        The scene file's text.
    result : FitResult

    Returns
    -------
    str

    Raises
    ------
    SceneError
        A key written in a form the line-wise edit cannot change (an inline table).
    """
    lines = text.splitlines()
    paths, headers = _table_paths(lines)
    inserts = []
    for key, value, unit, written, initial, (_, hi) in zip(result.keys, result.values, result.units,
                                                            result.written, result.initial, result.ci95):
        if not math.isfinite(hi):  # not identified: the file keeps its value
            continue
        table, _, name = key.rpartition(".")
        new = _format(float(value), written, unit, key)
        pattern = re.compile(rf"^(\s*{re.escape(name)}\s*=\s*)(.*?)(\s*(#.*)?)$")
        for n, line in enumerate(lines):
            if paths[n] != table:
                continue
            m = pattern.match(line)
            if m and not line.lstrip().startswith("#"):
                old = m.group(2).strip()
                comment = (m.group(4) or "").lstrip("#").strip()
                tail = f"  # fitted: was {old}" + (f"; {comment}" if comment else "")
                lines[n] = f"{m.group(1)}{new}{tail}"
                break
        else:
            if written is not None:
                raise SceneError(key, "written in a form the calibrated scene cannot edit in place "
                                 "(write it as `key = value` in its table)")
            was = f"{initial:.6g} {unit} (default)"
            if table in headers:
                inserts.append((headers[table] + 1, f"{name} = {new}  # fitted: was {was}"))
            else:
                head = f"[{table}]" if "[" not in table else None
                if head is None:
                    raise SceneError(key, "its table is not in the file; add it to fit this key")
                inserts.append((len(lines), f"\n{head}\n{name} = {new}  # fitted: was {was}"))
    for at, line in sorted(inserts, reverse=True):
        lines.insert(at, line)
    return "\n".join(lines) + ("\n" if text.endswith("\n") else "")
