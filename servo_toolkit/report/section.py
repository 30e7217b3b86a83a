"""A report section: title, an HTML fragment, figures and a status; small HTML helpers."""

from __future__ import annotations

from dataclasses import dataclass, field

from ..display.html import Raw, badge, esc, fmt
from ..display.html import table as _table
from ..display.html import para as _para
from .plain_text import plain

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
    layout : tuple of str
        What leaves its frame or overlaps in the laid-out figures, ``"figure K: ..."``
        (:func:`servo_toolkit.report.figures.layout_problems`); empty when all fits.
    """

    title: str
    html: str = ""
    figures: tuple = ()
    status: str = "info"
    reason: str = ""
    key: str = ""
    layout: tuple = ()

    def __post_init__(self):
        if self.status not in STATUSES:
            raise ValueError(f"status must be one of {STATUSES}, got {self.status!r}")

    def to_dict(self) -> dict:
        """JSON-ready summary (no figures)."""
        return {"key": self.key, "title": self.title, "status": self.status, "reason": self.reason,
                "figures": len(self.figures), "layout": list(self.layout)}


def para(*texts: str) -> str:
    """Paragraphs of escaped plain text (docstring markup removed, :func:`.plain_text.plain`)."""
    return _para(*(plain(t) for t in texts))


#: a table with more columns than this is set in the report's narrow type with its headings
#: wrapped (inside a ``div.wide-table``), so that it stays within the page
WIDE_COLUMNS = 7


def table(header, rows, cls: str = "", table_id: str = "") -> str:
    """An HTML table (:func:`servo_toolkit.display.html.table`); one with more than
    :data:`WIDE_COLUMNS` columns comes inside ``<div class="wide-table">`` (narrow type,
    wrapped headings)."""
    header = list(header)
    html = _table(header, rows, cls=cls, table_id=table_id)
    return f'<div class="wide-table">{html}</div>' if len(header) > WIDE_COLUMNS else html


class NotAvailable(Exception):
    """A section cannot be built: the capability is missing or does not apply."""


class NotApplicable(NotAvailable):
    """The section does not apply to this scene (e.g. no motor-driven drivetrain)."""


@dataclass
class Notes:
    """Collects short remarks for a section (mutable helper used while building one)."""

    items: list = field(default_factory=list)

    def add(self, text: str) -> None:
        """Add a remark."""
        self.items.append(text)

    def html(self) -> str:
        """The remarks as an HTML list."""
        return "<ul>" + "".join(f"<li>{esc(plain(t))}</li>" for t in self.items) + "</ul>" if self.items else ""


__all__ = ["FigureSpec", "NotApplicable", "NotAvailable", "Notes", "Raw", "STATUSES", "Section", "WIDE_COLUMNS", "badge",
           "esc", "fmt", "para", "plain", "table"]
