"""One document source for the report: the Jinja2 template ``templates/report.html.j2``
renders the HTML page and, with the print stylesheet, the page the PDF is typeset from."""

from __future__ import annotations

import base64
import io
from pathlib import Path

TEMPLATES = Path(__file__).resolve().parent / "templates"
#: the page's pixels per inch of a figure: its width on screen (an SVG's own size is 96 per inch)
DPI = 110


def _css_string(value) -> str:
    """``value`` inside a CSS double-quoted string."""
    return "".join(c if c.isalnum() or c in " .,:;-_+()/*=[]" else f"\\{ord(c):x} " for c in str(value))


def environment():
    """The Jinja2 environment of the report templates (HTML autoescaped)."""
    import jinja2
    env = jinja2.Environment(loader=jinja2.FileSystemLoader(str(TEMPLATES)), autoescape=True,
                             trim_blocks=False, lstrip_blocks=False, undefined=jinja2.StrictUndefined)
    env.filters["css_string"] = _css_string
    return env


def figure_src(fig, sources: dict | None = None) -> str:
    """A figure as a data URI of its SVG (vector: sharp at any zoom on the page and in print).

    ``sources`` keeps each figure's URI by figure, so that the HTML page and the PDF share one
    rendering. A report figure comes laid out and checked
    (:func:`servo_toolkit.report.figures.finish` keeps its layout); any other figure is laid
    out by its first save and keeps that layout."""
    if sources is not None and id(fig) in sources:
        return sources[id(fig)][1]
    buf = io.BytesIO()
    fig.savefig(buf, format="svg")
    uri = "data:image/svg+xml;base64," + base64.b64encode(buf.getvalue()).decode("ascii")
    if fig.get_layout_engine() is not None:
        fig.set_layout_engine("none")
    if sources is not None:
        sources[id(fig)] = (fig, uri)  # the figure is held so that its id stays its own
    return uri


def _verdict(report) -> dict:
    rows = report.requirements
    if not rows:
        return {"status": "na", "text": "no requirement to check for this scene"}
    failed = [r for r in rows if r.status == "fail"]
    missing = [r for r in rows if r.status == "unavailable"]
    if failed:
        return {"status": "fail", "text": f"{len(failed)} of {len(rows)} requirements NOT met: "
                                          + ", ".join(r.id for r in failed)}
    if missing:
        return {"status": "na", "text": f"{len(missing)} of {len(rows)} requirements not evaluated: "
                                        + ", ".join(r.id for r in missing)}
    return {"status": "pass", "text": f"all {len(rows)} requirements met"}


def context(report, target: str, tick=None, sources: dict | None = None) -> dict:
    """The template's variables: identity, verdict, numbered sections and figures (each with
    its SVG, :func:`figure_src`, and its width on the page in pixels), the reference list
    (:data:`servo_toolkit.report.references.REFERENCES`)."""
    from markupsafe import Markup
    sections = []
    for i, s in enumerate(report.sections, 1):
        anchor = s.key or f"s{i}"
        figs = []
        for k, spec in enumerate(s.figures, 1):
            figs.append({"number": f"{i}.{k}", "anchor": f"figure-{i}-{k}", "caption": spec.caption,
                         "src": figure_src(spec.figure, sources),
                         "width": round(spec.figure.get_figwidth() * DPI)})
            if tick is not None:
                tick()
        sections.append({"number": i, "anchor": anchor, "title": s.title, "status": s.status, "reason": s.reason,
                         "html": Markup(s.html), "figures": figs})
    from .references import REFERENCES
    return {"target": target, "scene_name": report.scene_name, "subtitle": report.subtitle,
            "meta": _identity(report.meta), "verdict": _verdict(report), "sections": sections,
            "references": REFERENCES}


def _identity(meta: dict) -> dict:
    """The report's identity with every field the document prints (a report built without
    one, e.g. from Python, still names the toolkit version and the date it was written)."""
    import datetime

    from ..core.version import __version__
    out = {"source": "(built in memory)", "sha256": "(scene not read from a file)", "version": __version__,
           "date": datetime.date.today().isoformat(), "settings": ""}
    out.update(meta or {})
    return out


def render(report, target: str = "html", tick=None, sources: dict | None = None) -> str:
    """The report as one HTML document for ``target`` ``"html"`` (a self-contained page) or
    ``"pdf"`` (A4 pages for a paged-media engine); ``tick()`` after each figure. ``sources``:
    the figures' URIs shared between documents (:func:`figure_src`)."""
    return environment().get_template("report.html.j2").render(**context(report, target, tick, sources))


__all__ = ["DPI", "TEMPLATES", "context", "environment", "figure_src", "render"]
