"""The self-contained HTML page: the report template with inline CSS and figures as base64
SVG, no external URLs."""

from __future__ import annotations

from .document import render


def render_html(report, tick=None, sources: dict | None = None) -> str:
    """The whole report as one HTML document; ``tick()`` is called after each figure.
    ``sources``: figure URIs to share with the PDF (:func:`servo_toolkit.report.document.figure_src`)."""
    return render(report, "html", tick, sources)
