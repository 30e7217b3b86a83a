"""HTML and number formatting shared by the Jupyter cards and the report: escaped text, one
number format, tables with trusted cells, status badges."""

from __future__ import annotations

import html
import math
from dataclasses import dataclass


def esc(value) -> str:
    """HTML-escaped text."""
    return html.escape(str(value), quote=True)


def fmt(value, digits: int = 4) -> str:
    """A number for a table: ``digits`` significant digits, inf/nan spelled out."""
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, (int,)) and not isinstance(value, bool):
        return str(value)
    try:
        x = float(value)
    except (TypeError, ValueError):
        return str(value)
    if math.isnan(x):
        return "n/a"
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    return f"{x:.{digits}g}"


def table(header, rows, cls: str = "", table_id: str = "") -> str:
    """An HTML table; cells are escaped unless given as :class:`Raw`."""
    def cell(v, tag):
        text = v.text if isinstance(v, Raw) else esc(v)
        return f"<{tag}>{text}</{tag}>"
    attrs = (f' class="{esc(cls)}"' if cls else "") + (f' id="{esc(table_id)}"' if table_id else "")
    head = "".join(cell(h, "th") for h in header)
    body = "".join("<tr>" + "".join(cell(v, "td") for v in row) + "</tr>" for row in rows)
    return f"<table{attrs}><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


@dataclass(frozen=True)
class Raw:
    """Trusted HTML inside a table cell."""

    text: str


def badge(status: str) -> Raw:
    """A coloured status label."""
    return Raw(f'<span class="badge {esc(status.replace("/", ""))}">{esc(status)}</span>')


def para(*texts: str) -> str:
    """Paragraphs of escaped text."""
    return "".join(f"<p>{esc(t)}</p>" for t in texts)
