"""The PDF report: a title page with the requirements table and section statuses, then figures."""

from __future__ import annotations

import textwrap

import matplotlib
from matplotlib.backends.backend_pdf import PdfPages
from matplotlib.figure import Figure

from .pdf_text import section_lines, table_lines, text_pages

A4 = (8.27, 11.69)


def _title_page(report) -> Figure:
    fig = Figure(figsize=A4)
    fig.text(0.08, 0.95, f"Servo report: {report.scene_name}", fontsize=18, weight="bold", va="top")
    fig.text(0.08, 0.915, textwrap.fill(report.subtitle, 95), fontsize=9, va="top")
    fig.text(0.08, 0.87, "Requirements", fontsize=13, weight="bold", va="top")
    rows = [[r[0], r[1], r[2] + (f" ({r[3]})" if r[3] else ""), r[4]] for r in report.requirements] \
        or [["(nothing to check for this scene)", "", "", "n/a"]]
    lines = table_lines([["requirement", "required", "achieved", "status"]] + rows, 100)
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


def write_pdf(report, path, tick=None) -> None:
    """Write ``report`` to ``path`` (title page, then one page per figure); ``tick()`` after
    each figure page."""
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
        info = pdf.infodict()
        info["Title"] = f"Servo report: {report.scene_name}"
        info["Subject"] = report.subtitle
