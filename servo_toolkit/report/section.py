"""A report section: title, an HTML fragment, figures and a status; small HTML helpers."""

from __future__ import annotations

import html
import math
from dataclasses import dataclass, field

#: Section statuses. ``info`` carries results without a verdict; ``pass``/``fail`` judge the
#: scene's requirements; ``n/a`` means the section does not apply to this scene; ``unavailable``
#: means the capability is missing or raised, and the section shows why.
STATUSES = ("info", "pass", "fail", "n/a", "unavailable")


@dataclass(frozen=True)
class FigureSpec:
    """A matplotlib figure with its caption (the figure is rendered by the writers)."""

    figure: object
    caption: str = ""


@dataclass(frozen=True)
class Section:
    """One block of the report.

    Parameters
    ----------
    title : str
    html : str
        HTML fragment (no figures; they follow the fragment).
    figures : tuple of FigureSpec
    status : str
        One of :data:`STATUSES`.
    reason : str
        Why a section is ``unavailable`` or ``n/a``.
    key : str
        Short identifier (``stiffness``, ``loop``, ...), used as the HTML anchor.
    """

    title: str
    html: str = ""
    figures: tuple = ()
    status: str = "info"
    reason: str = ""
    key: str = ""

    def __post_init__(self):
        if self.status not in STATUSES:
            raise ValueError(f"status must be one of {STATUSES}, got {self.status!r}")

    def to_dict(self) -> dict:
        """JSON-ready summary (no figures)."""
        return {"key": self.key, "title": self.title, "status": self.status, "reason": self.reason,
                "figures": len(self.figures)}


class NotAvailable(Exception):
    """A section cannot be built: the capability is missing or does not apply."""


class NotApplicable(NotAvailable):
    """The section does not apply to this scene (e.g. no motor-driven drivetrain)."""


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


@dataclass
class Notes:
    """Collects short remarks for a section (mutable helper used while building one)."""

    items: list = field(default_factory=list)

    def add(self, text: str) -> None:
        """Add a remark."""
        self.items.append(text)

    def html(self) -> str:
        """The remarks as an HTML list."""
        return "<ul>" + "".join(f"<li>{esc(t)}</li>" for t in self.items) + "</ul>" if self.items else ""
