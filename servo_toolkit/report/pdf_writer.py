"""The PDF report: the report template typeset on A4 pages by WeasyPrint (table of contents,
numbered sections and figures, page numbers, a running header with the scene, its SHA-256, the
toolkit version and date, vector figures, a sign-off block). Where WeasyPrint or the system's
Pango is missing, a plainer PDF (matplotlib text pages and figures) is written instead."""

from __future__ import annotations

import textwrap

import matplotlib
from matplotlib.backends.backend_pdf import PdfPages
from matplotlib.figure import Figure

from .pdf_text import WIDTH, section_lines, table_lines, text_pages
from .references import REFERENCES

A4 = (8.27, 11.69)


def _title_page(report) -> Figure:
    fig = Figure(figsize=A4)
    fig.text(0.08, 0.95, f"Servo report: {report.scene_name}", fontsize=18, weight="bold", va="top")
    meta = report.meta
    fig.text(0.08, 0.915, textwrap.fill(report.subtitle, 95) + f"\nscene file SHA-256 {meta.get('sha256', '')}; "
             f"servo_toolkit {meta.get('version', '')}, {meta.get('date', '')}", fontsize=8, va="top")
    fig.text(0.08, 0.87, "Requirements", fontsize=13, weight="bold", va="top")
    rows = [[r.id, r.requirement, r.required, r.achieved + (f" (short by {r.shortfall})" if r.shortfall else ""),
             r.status] for r in report.requirements] or [["", "(nothing to check for this scene)", "", "", "n/a"]]
    lines = table_lines([["ID", "requirement", "required", "achieved", "status"]] + rows, 100)
    y = 0.85
    for line in lines[:22]:
        fig.text(0.08, y, line, fontsize=7.2, family="monospace", va="top")
        y -= 0.0135
    if len(lines) > 22:
        fig.text(0.08, y, "(continued on the requirements page)", fontsize=7.2, family="monospace", va="top")
    fig.text(0.08, 0.52, "Sections", fontsize=13, weight="bold", va="top")
    y = 0.49
    for i, s in enumerate(report.sections, 1):
        line = f"{i:2d}. {s.title}  [{s.status}]"
        if s.reason:
            line += f"  {s.reason}"
        for part in textwrap.wrap(line, 110, subsequent_indent="      "):
            fig.text(0.08, y, part, fontsize=7.5, va="top", family="monospace")
            y -= 0.016
    return fig


def paged_engine():
    """The WeasyPrint module, or None when it (or the Pango library it loads) is missing."""
    return None if engine_problem() else _weasyprint()


def _weasyprint():
    import weasyprint
    return weasyprint


def engine_problem() -> str | None:
    """Why the typeset PDF cannot be written here (one sentence), or None when it can.

    WeasyPrint is a dependency of the toolkit; it loads the system's Pango library when
    imported, which a minimal system may lack."""
    try:
        _weasyprint()
    except ImportError as exc:
        return (f"WeasyPrint cannot be imported ({exc}); reinstall the toolkit "
                "(python -m pip install servo_toolkit) to get it")
    except OSError as exc:
        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        return (f"WeasyPrint cannot load the system's Pango library ({first}); install it "
                "(Debian: apt-get install libpango-1.0-0 libpangoft2-1.0-0)")
    return None


def write_pdf(report, path, tick=None, engine="auto", sources: dict | None = None) -> str:
    """Write ``report`` to ``path``; ``tick()`` after each figure. Returns the engine used:
    ``"weasyprint"`` (the document from the report template) or ``"matplotlib"`` (the
    fallback: a title page, text pages and one page per figure).

    Parameters
    ----------
    engine : str
        ``"auto"`` (WeasyPrint when available), ``"weasyprint"`` or ``"matplotlib"``.
    sources : dict, optional
        The figures' SVG already rendered for the HTML page
        (:func:`servo_toolkit.report.document.figure_src`).
    """
    weasyprint = paged_engine() if engine in ("auto", "weasyprint") else None
    if weasyprint is not None:
        from .document import render
        html = render(report, "pdf", tick, sources)
        weasyprint.HTML(string=html, base_url=".").write_pdf(str(path))
        return "weasyprint"
    if engine == "weasyprint":
        raise ImportError(engine_problem())
    _write_matplotlib_pdf(report, path, tick)
    return "matplotlib"


def _write_matplotlib_pdf(report, path, tick=None) -> None:
    """The fallback PDF: title page, then text pages and one page per figure."""
    with matplotlib.rc_context({"pdf.fonttype": 42}), PdfPages(path) as pdf:
        pdf.savefig(_title_page(report))
        for i, section in enumerate(report.sections, 1):
            for page in text_pages(section_lines(i, section), f"Servo report: {report.scene_name}"):
                pdf.savefig(page)
            for k, spec in enumerate(section.figures, 1):
                fig = spec.figure
                old = fig.get_suptitle() if hasattr(fig, "get_suptitle") else ""
                fig.suptitle(f"{i}. {section.title}  (figure {i}.{k})", fontsize=9)
                pdf.savefig(fig)
                fig.suptitle(old)
                if tick is not None:
                    tick()
        lines = ["References", ""]
        for ref in REFERENCES:
            lines += textwrap.wrap(ref.text(), WIDTH, subsequent_indent="    ") + [""]
        for page in text_pages(lines, f"Servo report: {report.scene_name}"):
            pdf.savefig(page)
        info = pdf.infodict()
        info["Title"] = f"Servo report: {report.scene_name}"
        info["Subject"] = report.subtitle
