"""The self-contained HTML page: inline CSS, figures as base64 PNG, no external URLs."""

from __future__ import annotations

from .figures import png_base64
from .section import esc

CSS = """
body{font-family:system-ui,-apple-system,'Segoe UI',Helvetica,Arial,sans-serif;margin:0 auto;
max-width:1100px;padding:1.5em;color:#1d232a;line-height:1.4}
h1{margin-bottom:.2em}h2{border-bottom:2px solid #d0d7de;padding-bottom:.2em;margin-top:1.8em}
h3{margin-bottom:.3em}
table{border-collapse:collapse;margin:.6em 0;font-size:.9em}
th,td{border:1px solid #d0d7de;padding:.25em .6em;text-align:left;vertical-align:top}
th{background:#f3f5f7}
table.params td:nth-child(2){font-variant-numeric:tabular-nums}
figure{margin:1em 0}figure img{max-width:100%;border:1px solid #e5e8eb}
figcaption{font-size:.85em;color:#57606a}
.badge{display:inline-block;padding:.05em .5em;border-radius:.6em;font-size:.85em;font-weight:600}
.badge.pass{background:#dafbe1;color:#116329}.badge.fail{background:#ffebe9;color:#a40e26}
.badge.info{background:#ddf4ff;color:#0a3069}.badge.na{background:#eaeef2;color:#57606a}
.badge.unavailable{background:#fff8c5;color:#7d4e00}
.unavailable-box{border:2px dashed #bf8700;background:#fff8c5;padding:.7em 1em;border-radius:.4em}
.na-box{border:1px solid #d0d7de;background:#f6f8fa;padding:.7em 1em;border-radius:.4em}
nav ol{columns:2;font-size:.9em}
#requirements-table td:last-child{font-weight:600}
"""


def section_html(section, index: int, tick=None) -> str:
    """One section as HTML (fragment, figures, status box); ``tick()`` after each figure."""
    anchor = esc(section.key or f"s{index}")
    out = [f'<section id="{anchor}" data-status="{esc(section.status)}">',
           f"<h2>{index}. {esc(section.title)}</h2>"]
    if section.status == "unavailable":
        out.append(f'<div class="unavailable-box">not available: {esc(section.reason)}</div>')
    elif section.status == "n/a":
        out.append(f'<div class="na-box">{esc(section.reason)}</div>')
    out.append(section.html)
    for k, spec in enumerate(section.figures, 1):
        data = png_base64(spec.figure)
        alt = esc(spec.caption or section.title)
        out.append(f'<figure><img class="report-figure" alt="{alt}" src="data:image/png;base64,{data}">'
                   f"<figcaption>Figure {index}.{k}. {esc(spec.caption)}</figcaption></figure>")
        if tick is not None:
            tick()
    out.append("</section>")
    return "\n".join(out)


def render_html(report, tick=None) -> str:
    """The whole report as one HTML document; ``tick()`` is called after each figure."""
    toc = "".join(f'<li><a href="#{esc(s.key or f"s{i}")}">{esc(s.title)}</a></li>'
                  for i, s in enumerate(report.sections, 1))
    body = "\n".join(section_html(s, i, tick) for i, s in enumerate(report.sections, 1))
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>Servo report: {esc(report.scene_name)}</title>
<style>{CSS}</style></head>
<body>
<h1>Servo report: {esc(report.scene_name)}</h1>
<p>{esc(report.subtitle)}</p>
<nav><ol>{toc}</ol></nav>
{body}
</body></html>
"""
