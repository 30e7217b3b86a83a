"""What a drawn figure gets wrong in its layout: texts cut at its edges, legends over data.

:func:`layout_faults` draws the figure as ``fig.savefig`` would (its layout engine, if any,
runs) and lists, one sentence each, every title, axis label, tick label, legend or text that
leaves the figure or overlaps another (the report's own check,
:func:`servo_toolkit.report.figures.layout_problems`), and every legend that covers a point
of a curve (the segments between the points too) or a bar drawn within its axes.
"""

from __future__ import annotations

import numpy as np

#: slack (pixels) of an overlap
SLACK_PX = 1.0
#: points laid along each segment of a drawn line, so a line crossing a legend is caught
SEGMENT_POINTS = 20


def _inside(points, box, slack=SLACK_PX):
    x, y = points[:, 0], points[:, 1]
    return (x > box.x0 + slack) & (x < box.x1 - slack) & (y > box.y0 + slack) & (y < box.y1 - slack)


def _line_points(line):
    """The drawn points of a line in display pixels, with points along its segments."""
    xy = np.asarray(line.get_xydata(), float)
    xy = xy[np.all(np.isfinite(xy), axis=1)]
    if xy.size == 0:
        return np.empty((0, 2))
    pts = line.get_transform().transform(xy)
    if line.get_linestyle() not in ("None", "none", "", " ") and len(pts) > 1:
        s = np.linspace(0.0, 1.0, SEGMENT_POINTS, endpoint=False)[:, None, None]
        pts = np.concatenate([(pts[:-1] + s * (pts[1:] - pts[:-1])).reshape(-1, 2), pts[-1:]])
    return pts


def legend_faults(fig) -> list:
    """Each legend that covers a curve's point or a bar within its axes (drawn figure)."""
    renderer = fig.canvas.get_renderer()
    legends = [(f"axes {i} legend", ax.get_legend()) for i, ax in enumerate(fig.axes, 1) if ax.get_legend()]
    legends += [("figure legend", leg) for leg in fig.legends]
    faults = []
    for name, leg in legends:
        box = leg.get_window_extent(renderer)
        for i, ax in enumerate(fig.axes, 1):
            frame = ax.get_window_extent(renderer)
            for line in ax.get_lines():
                if not line.get_visible():
                    continue
                pts = _line_points(line)
                pts = pts[_inside(pts, frame, slack=-SLACK_PX)]
                hit = int(np.sum(_inside(pts, box)))
                if hit:
                    faults.append(f"{name} covers {hit} points of axes {i}'s line {line.get_label()!r}")
            bars = {id(p): c.get_label() for c in ax.containers for p in getattr(c, "patches", ())}
            for patch in ax.patches:
                bar = patch.get_window_extent(renderer)
                x0, x1 = max(bar.x0, frame.x0, box.x0), min(bar.x1, frame.x1, box.x1)
                y0, y1 = max(bar.y0, frame.y0, box.y0), min(bar.y1, frame.y1, box.y1)
                if patch.get_visible() and x1 - x0 > SLACK_PX and y1 - y0 > SLACK_PX:
                    faults.append(f"{name} covers axes {i}'s bar {bars.get(id(patch), patch.get_label())!r}")
    return faults


def layout_faults(fig) -> list:
    """Every text outside the figure or over another text, every legend over data (each a
    sentence); empty for a clean figure. Draws the figure."""
    from servo_toolkit.report.figures import layout_problems
    problems = list(layout_problems(fig))
    return problems + legend_faults(fig)
