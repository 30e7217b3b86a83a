"""The self-contained HTML page: the report template with inline CSS and figures as base64
PNG, no external URLs."""

from __future__ import annotations

from .document import render


def render_html(report, tick=None) -> str:
    """The whole report as one HTML document; ``tick()`` is called after each figure."""
    return render(report, "html", tick)
