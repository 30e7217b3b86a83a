"""Sections of the PDF as text pages: every paragraph and table of a section's HTML set as
selectable text (a reader of the PDF alone gets every number of the HTML), columns wrapped
to the page instead of clipped."""

from __future__ import annotations

import textwrap
from html.parser import HTMLParser

from matplotlib.figure import Figure

A4 = (8.27, 11.69)
#: characters per line of the monospaced body text, and lines per page
WIDTH = 104
LINES = 70
TOP, LINE_STEP, LEFT = 0.95, 0.0128, 0.06


class _Blocks(HTMLParser):
    """Paragraphs, list items and tables of an HTML fragment, in order."""

    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.blocks: list = []
        self._text = None
        self._table = None
        self._row = None
        self._cell = None

    def handle_starttag(self, tag, attrs):
        if tag == "table":
            self._table = []
        elif tag == "tr" and self._table is not None:
            self._row = []
        elif tag in ("td", "th") and self._row is not None:
            self._cell = []
        elif tag in ("p", "li") and self._table is None:
            self._text = ["- "] if tag == "li" else []

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self._cell is not None:
            self._row.append(" ".join("".join(self._cell).split()))
            self._cell = None
        elif tag == "tr" and self._row is not None:
            self._table.append(self._row)
            self._row = None
        elif tag == "table" and self._table is not None:
            self.blocks.append(("table", self._table))
            self._table = None
        elif tag in ("p", "li") and self._text is not None:
            self.blocks.append(("text", " ".join("".join(self._text).split())))
            self._text = None

    def handle_data(self, data):
        if self._cell is not None:
            self._cell.append(data)
        elif self._text is not None:
            self._text.append(data)


def blocks(html: str) -> list:
    """``("text", str)`` and ``("table", rows)`` blocks of an HTML fragment."""
    parser = _Blocks()
    parser.feed(html)
    parser.close()
    return parser.blocks


def table_lines(rows, width: int = WIDTH) -> list:
    """A table as text lines, each column wrapped to its share of ``width`` (wider when a
    column's longest word needs it)."""
    if not rows:
        return []
    n = max(len(r) for r in rows)
    rows = [list(r) + [""] * (n - len(r)) for r in rows]
    natural = [max(len(r[c]) for r in rows) for c in range(n)]
    # a column never gets narrower than its longest word: numbers are never split
    floor = [max([4] + [len(w) for r in rows for w in r[c].split()]) for c in range(n)]
    room = width - 2 * (n - 1)
    cols = list(natural)
    while sum(cols) > room and any(c > f for c, f in zip(cols, floor)):
        k = max((c for c in range(n) if cols[c] > floor[c]), key=lambda c: cols[c])
        cols[k] -= 1
    out = []
    for i, r in enumerate(rows):
        wrapped = [textwrap.wrap(r[c], cols[c]) or [""] for c in range(n)]
        for k in range(max(len(w) for w in wrapped)):
            out.append("  ".join((w[k] if k < len(w) else "").ljust(cols[c]) for c, w in enumerate(wrapped)).rstrip())
        if i == 0:
            out.append("  ".join("-" * cols[c] for c in range(n)))
    return out


def section_lines(number: int, section) -> list:
    """The text lines of one section: title, status, paragraphs and tables."""
    lines = [f"{number}. {section.title}  [{section.status}]", ""]
    if section.reason:
        lines += textwrap.wrap(f"Reason: {section.reason}", WIDTH) + [""]
    for kind, value in blocks(section.html):
        lines += (textwrap.wrap(value, WIDTH) if kind == "text" else table_lines(value)) + [""]
    return lines


def text_pages(lines, header: str = ""):
    """A4 figures holding ``lines`` of monospaced text, :data:`LINES` per page."""
    for start in range(0, max(len(lines), 1), LINES):
        fig = Figure(figsize=A4)
        if header:
            fig.text(LEFT, 0.975, header, fontsize=8, color="0.4", va="top")
        y = TOP
        for k, line in enumerate(lines[start:start + LINES]):
            bold = start == 0 and k == 0
            size = 11 if bold else 7.4 * min(1.0, WIDTH / max(len(line), 1))  # a wide table: smaller type
            fig.text(LEFT, y, line, fontsize=size, family="monospace", va="top",
                     weight="bold" if bold else "normal")
            y -= LINE_STEP * (1.6 if bold else 1.0)
        yield fig
