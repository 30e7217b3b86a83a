"""HTML and number formatting shared by the Jupyter cards and the report: escaped text, one
number format, tables with trusted cells, status badges."""

from __future__ import annotations

import html
import math
from dataclasses import dataclass


def esc(value) -> str:
    """HTML-escaped text."""
    return html.escape(str(value), quote=True)


#: a magnitude in [ENG_LOW, ENG_HIGH) is written plainly; others in engineering notation
ENG_LOW, ENG_HIGH = 1e-3, 1e4


def telling_digits(achieved: float, required: float, digits: int) -> int:
    """Significant digits, at least ``digits``, that show a figure apart from its
    requirement when they differ (a gain margin of 5.996 dB against 6 dB is written
    5.996 dB, not 6 dB beside a failed verdict); at most 12."""
    try:
        a, r = float(achieved), float(required)
    except (TypeError, ValueError):
        return digits
    if not (math.isfinite(a) and math.isfinite(r)) or a == r:
        return digits
    d = digits
    while d < 12 and f"{a:.{d}g}" == f"{r:.{d}g}":
        d += 1
    return d


def fmt(value, digits: int = 4) -> str:
    """A number for a table: ``digits`` significant digits, inf/nan spelled out.

    Magnitudes from :data:`ENG_LOW` up to :data:`ENG_HIGH` are written plainly (``0.1403``,
    ``1697``); smaller and larger ones in engineering notation, a mantissa from 1 to 999
    and an exponent that is a multiple of 3 (``804.5e3``, ``1.147e6``, ``12.5e-6``), so the
    numbers of one column read alike. Integers are written whole.
    """
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
    digits = max(1, int(digits))
    rounded = float(f"{x:.{digits}g}")
    if rounded == 0:
        return "0"
    if ENG_LOW <= abs(rounded) < ENG_HIGH:
        return f"{rounded:.0f}" if abs(rounded) >= 10 ** digits else f"{x:.{digits}g}"
    return engineering(x, digits)


def engineering(x: float, digits: int = 4, trim: bool = True) -> str:
    """``x`` in engineering notation with ``digits`` significant digits (``"804.5e3"``);
    ``trim=False`` keeps trailing zeros (``"520.20e3"``), as a table column does."""
    rounded = float(f"{x:.{max(1, digits) - 1}e}")
    if rounded == 0 or not math.isfinite(rounded):
        return f"{x:.{digits}g}"
    exp3 = 3 * math.floor(math.log10(abs(rounded)) / 3)
    mant = rounded / 10.0 ** exp3
    if abs(mant) >= 1000.0 - 1e-9:  # rounding carried into the next group
        exp3, mant = exp3 + 3, mant / 1000.0
    whole = len(str(int(abs(mant))))
    text = f"{mant:.{max(0, digits - whole)}f}"
    if "." in text and trim:
        text = text.rstrip("0").rstrip(".")
    return f"{text}e{exp3}"


def _plain(x: float, digits: int) -> str:
    """``x`` written plainly with ``digits`` significant digits, trailing zeros kept."""
    rounded = float(f"{x:.{digits}g}")
    if abs(rounded) >= 10 ** digits:
        return f"{rounded:.0f}"
    return f"{x:#.{digits}g}".rstrip(".")


def column(values, digits: int = 4) -> list[str]:
    """Numbers of one column (or one block of a table) in ONE format.

    Plain, ``digits`` significant digits (``1696.8``, ``0.1403``), when every finite non-zero
    magnitude lies from :data:`ENG_LOW` up to :data:`ENG_HIGH`; otherwise all in engineering
    notation (``97.219e3``, ``1.6968e3``, ``710.94e0``), so the column never mixes the two.
    Trailing zeros are kept (``520.20e3``, ``136.90``); zero is ``0``, inf and NaN are
    spelled out as :func:`fmt` does.
    """
    digits = max(1, int(digits))
    xs = [float(v) for v in values]
    finite = [abs(float(f"{x:.{digits}g}")) for x in xs if math.isfinite(x) and x != 0]
    plain = all(ENG_LOW <= x < ENG_HIGH for x in finite)
    return [fmt(x, digits) if not math.isfinite(x) or x == 0
            else _plain(x, digits) if plain else engineering(x, digits, trim=False) for x in xs]


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
