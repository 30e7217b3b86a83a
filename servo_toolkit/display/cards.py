"""Rich display in Jupyter: a one-line ``repr`` and an HTML card for every result.

A card shows the few figures that matter (pass/fail with the shortfall, margins with units,
the worst point along the stroke, what a model left out), a compact table and, where one is
natural, the result's own plot rendered as inline SVG. Results keep their plain-text
``table()`` for terminals; :class:`RichDisplay` gives a result class both methods from two
small hooks, ``_repr_line()`` and ``_repr_card()``.
"""

from __future__ import annotations

import io

from .html import Raw, esc, fmt, telling_digits
from .html import table as html_table

#: style of the cards (scoped by the class name, so a notebook's own styles are untouched)
STYLE = ("<style>.st-card{font-family:sans-serif;font-size:13px;border:1px solid #ccd;"
         "border-radius:6px;padding:8px 12px;margin:4px 0;max-width:980px}"
         ".st-card h4{margin:0 0 6px 0;font-size:14px}.st-card table{border-collapse:collapse;margin:4px 0}"
         ".st-card td,.st-card th{border-bottom:1px solid #eee;padding:2px 8px;text-align:right}"
         ".st-card td:first-child,.st-card th:first-child{text-align:left}"
         ".st-pass{color:#fff;background:#2a7;border-radius:3px;padding:0 5px}"
         ".st-fail{color:#fff;background:#c33;border-radius:3px;padding:0 5px}"
         ".st-note{color:#555;font-size:12px;margin:2px 0}</style>")


def num(x, digits: int = 4) -> str:
    """A number for a card: ``digits`` significant digits; inf and NaN in words (the
    report's format, :func:`servo_toolkit.display.html.fmt`)."""
    return fmt(x, digits)


def badge(passed: bool, text: str | None = None) -> str:
    """A green PASS or red FAIL badge (or ``text`` in that colour)."""
    label = text if text is not None else ("PASS" if passed else "FAIL")
    return f'<span class="{"st-pass" if passed else "st-fail"}">{esc(label)}</span>'


def table(head, rows, raw_columns=()) -> str:
    """A compact HTML table; cells are escaped except the columns in ``raw_columns``."""
    return html_table(head, [[Raw(c) if j in raw_columns else c for j, c in enumerate(r)] for r in rows])


def facts(pairs) -> str:
    """A two-column table of (label, value) pairs; values are escaped."""
    return "<table>" + "".join(f"<tr><td>{esc(k)}</td><td>{esc(v)}</td></tr>" for k, v in pairs) + "</table>"


def svg(draw, size=(7.0, 4.2), rows: int = 1, cols: int = 1, sharex: bool = False, height_ratios=None) -> str:
    """Inline SVG of ``draw(axes)`` on a fresh figure (no pyplot state: nothing else is
    displayed; ``height_ratios``: the rows' relative heights); empty when the drawing fails
    (a card never breaks on its plot)."""
    from matplotlib.figure import Figure
    fig = Figure(figsize=size)
    axes = fig.subplots(rows, cols, sharex=sharex, height_ratios=height_ratios)
    try:
        draw(axes)
        fig.tight_layout()
        buf = io.StringIO()
        fig.savefig(buf, format="svg")
    except Exception as exc:  # noqa: BLE001 - the card stays useful without its plot
        return f'<p class="st-note">plot not available: {esc(exc)}</p>'
    text = buf.getvalue()
    return text[text.index("<svg"):]


def card(title: str, *, status: bool | None = None, parts=(), notes=()) -> str:
    """The HTML card: a title with an optional PASS/FAIL badge, then ``parts`` (HTML) and
    ``notes`` (text, at most eight shown)."""
    head = f"<h4>{esc(title)} {badge(status) if status is not None else ''}</h4>"
    notes = list(notes)
    more = f" (+{len(notes) - 8} more)" if len(notes) > 8 else ""
    note_html = "".join(f'<p class="st-note">{esc(n)}</p>' for n in notes[:8]) + (
        f'<p class="st-note">{esc(more)}</p>' if more else "")
    return f'{STYLE}<div class="st-card">{head}{"".join(parts)}{note_html}</div>'


def requirement_rows(checks):
    """Rows (name, required, achieved, badge, shortfall) of requirement checks."""
    return [(c.name, f"{c.sense} {num(c.required)} {c.unit}",
             f"unstable ({c.reason})" if getattr(c, "reason", "") else
             f"{num(c.achieved, telling_digits(c.achieved, c.required, 4))} {c.unit}",
             badge(c.passed), "" if c.passed or getattr(c, "reason", "") else f"{num(c.shortfall, 3)} {c.unit}")
            for c in checks]


def requirements_table(checks) -> str:
    """HTML requirement table with PASS/FAIL badges."""
    return table(("requirement", "required", "achieved", "", "short by"), requirement_rows(checks),
                 raw_columns=(3,))


def esc_lines(text):
    """The non-empty lines of ``text``, stripped and HTML-escaped."""
    return [esc(line.strip()) for line in text.splitlines() if line.strip()]


class RichDisplay:
    """Mixin: ``__repr__`` from ``_repr_line()`` (one line) and ``_repr_html_`` from
    ``_repr_card()``. Dataclasses using it are declared with ``repr=False``."""

    def _repr_line(self) -> str:  # pragma: no cover - every user overrides it
        return type(self).__name__

    def _repr_card(self) -> str:  # pragma: no cover - every user overrides it
        return card(self._repr_line())

    def __repr__(self) -> str:
        return f"<{type(self).__name__}: {self._repr_line()}>"

    def _repr_html_(self) -> str:
        return self._repr_card()


__all__ = ["RichDisplay", "badge", "card", "esc", "esc_lines", "facts", "num", "requirement_rows", "requirements_table",
           "svg", "table"]
