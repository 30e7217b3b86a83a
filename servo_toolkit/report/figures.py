"""Figures for the report: created without pyplot (no global state), encoded as PNG."""

from __future__ import annotations

import math
import textwrap

import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import LogFormatter

from ..display.units import DisplayUnits



def new_figure(nrows: int = 1, ncols: int = 1, size=(7.0, 3.4), **kwargs):
    """A matplotlib Figure (Agg canvas, not registered with pyplot) and its axes."""
    fig = Figure(figsize=size, layout="constrained")
    axes = fig.subplots(nrows, ncols, squeeze=True, **kwargs)
    return fig, axes


def legends_outside(fig) -> None:
    """One legend for ``fig``, outside its axes at the right edge, so that no legend covers a
    curve: the entries of every axes legend (one per label, the first met) are gathered into
    a figure legend placed by the constrained layout, and the axes legends removed. Every
    report figure passes through here (:func:`servo_toolkit.report.builder.run_section`)."""
    handles, labels, scale = [], [], 1.0
    for ax in fig.axes:
        leg = ax.get_legend()
        if leg is None:
            continue
        scale = max(scale, float(getattr(leg, "markerscale", 1.0)))
        for handle, text in zip(leg.legend_handles, leg.get_texts()):
            label = text.get_text()
            if label and label not in labels:
                handles.append(handle)
                labels.append(label)
        leg.remove()
    if not labels:
        return
    if fig.get_layout_engine() is None:
        fig.set_layout_engine("constrained")
    fig.legend(handles, labels, loc="outside right upper", fontsize="small", markerscale=scale)


class PlainLogFormatter(LogFormatter):
    """Log-axis tick labels as plain numbers ("0.2", "2", "30") instead of "2x10^-1"."""

    def _num_to_string(self, x, vmin, vmax):
        return f"{x:.4g}"


#: a log axis spanning fewer decades than this gets plain tick labels (its minor ticks are
#: labelled too, which matplotlib writes as "2x10^0")
PLAIN_LOG_DECADES = 2.0
#: slack (pixels) allowed between a text's box and its frame, and in an overlap
LAYOUT_SLACK_PX = 1.0


def plain_log_ticks(ax) -> None:
    """Plain tick labels on each log axis of ``ax`` that spans fewer than
    :data:`PLAIN_LOG_DECADES` decades."""
    for axis, lims in ((ax.xaxis, ax.get_xlim()), (ax.yaxis, ax.get_ylim())):
        if axis.get_scale() != "log" or min(lims) <= 0:
            continue
        if math.log10(max(lims) / min(lims)) < PLAIN_LOG_DECADES:
            axis.set_major_formatter(PlainLogFormatter(labelOnlyBase=False))
            axis.set_minor_formatter(PlainLogFormatter(labelOnlyBase=False, minor_thresholds=(2, 0.5)))


def _renderer(fig):
    """The figure's renderer (an Agg canvas is attached to a figure made without one)."""
    if not hasattr(fig.canvas, "get_renderer"):
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        FigureCanvasAgg(fig)
    return fig.canvas.get_renderer()


def _wrap_wide_titles(fig, renderer) -> bool:
    """Wrap each axes title wider than its axes onto more lines; True when one changed."""
    changed = False
    for ax in fig.axes:
        for title in (ax.title, ax._left_title, ax._right_title):
            text = title.get_text()
            if not text or not title.get_visible():
                continue
            width, room = title.get_window_extent(renderer).width, ax.get_window_extent(renderer).width
            if width <= room + LAYOUT_SLACK_PX:
                continue
            longest = max(len(line) for line in text.splitlines())
            chars = max(12, int(longest * room / width) - 1)
            wrapped = textwrap.fill(" ".join(text.split()), chars)
            if wrapped != text:
                title.set_text(wrapped)
                changed = True
    return changed


def finish(fig) -> tuple:
    """Lay a report figure out for the page and say what still does not fit.

    The axes legends are gathered into one figure legend outside the axes
    (:func:`legends_outside`), a log axis of less than two decades gets plain tick labels, a
    title wider than its axes is wrapped, and the laid-out figure is checked
    (:func:`layout_problems`). Every report figure passes through here
    (:func:`servo_toolkit.report.builder.run_section`).

    The layout checked is then kept (the figure's layout engine is set to ``"none"``): the
    documents draw the figure as it was checked, without solving its constrained layout again
    at every save.

    Returns
    -------
    tuple of str
        The layout problems left (empty when every text is within its frame).
    """
    legends_outside(fig)
    for ax in fig.axes:
        plain_log_ticks(ax)
    drawn = False
    for _ in range(3):
        fig.draw_without_rendering()
        drawn = not _wrap_wide_titles(fig, _renderer(fig))
        if drawn:
            break
    problems = _drawn_problems(fig) if drawn else layout_problems(fig)
    fig.set_layout_engine("none")
    return problems


def _boxes(fig, renderer):
    """``[(what, text artist or legend, window extent, frame)]``: the titles, axis labels,
    texts and annotations of every axes (frame: the figure; an axes' own texts: the axes),
    the legends and the figure's own texts."""
    out = []
    for i, ax in enumerate(fig.axes, 1):
        if not ax.get_visible():
            continue
        frame = ax.get_window_extent(renderer)
        for what, t in (("title", ax.title), ("title", ax._left_title), ("title", ax._right_title),
                        ("x label", ax.xaxis.label), ("y label", ax.yaxis.label)):
            if t.get_visible() and t.get_text().strip():
                out.append((f"axes {i} {what} {t.get_text()[:40]!r}", t, t.get_window_extent(renderer), fig.bbox))
        for t in ax.texts:
            if t.get_visible() and t.get_text().strip():
                inside = t.get_transform() is not fig.transFigure
                out.append((f"axes {i} text {t.get_text()[:40]!r}", t, t.get_window_extent(renderer),
                            frame if inside else fig.bbox))
        leg = ax.get_legend()
        if leg is not None and leg.get_visible():
            out.append((f"axes {i} legend", leg, leg.get_window_extent(renderer), fig.bbox))
    for leg in fig.legends:
        out.append(("figure legend", leg, leg.get_window_extent(renderer), fig.bbox))
    for t in fig.texts:
        if t.get_visible() and t.get_text().strip():
            out.append((f"figure text {t.get_text()[:40]!r}", t, t.get_window_extent(renderer), fig.bbox))
    return out


def _outside(box, frame) -> bool:
    s = LAYOUT_SLACK_PX
    return box.x0 < frame.x0 - s or box.x1 > frame.x1 + s or box.y0 < frame.y0 - s or box.y1 > frame.y1 + s


def _overlap(a, b) -> bool:
    s = LAYOUT_SLACK_PX
    return min(a.x1, b.x1) - max(a.x0, b.x0) > s and min(a.y1, b.y1) - max(a.y0, b.y0) > s


def _legend_styles(leg):
    """``[(label, style)]`` of a legend's entries: colour and line style (a marker alone tells
    curves apart poorly)."""
    def key(value):  # a colour or dash pattern as something hashable
        try:
            return tuple(np.round(np.nan_to_num(np.asarray(value, dtype=float).ravel(), nan=-1.0), 3).tolist())
        except (TypeError, ValueError):
            return str(value)
    out = []
    for handle, text in zip(leg.legend_handles, leg.get_texts()):
        style = tuple(key(getattr(handle, get)()) for get in ("get_color", "get_facecolor", "get_linestyle")
                      if hasattr(handle, get))
        out.append((text.get_text(), style))
    return out


def _drawn_tick_labels(ax):
    """The tick labels ``ax`` draws: those of its ticks within the view, with text."""
    out = []
    for axis in (ax.xaxis, ax.yaxis):
        lo, hi = sorted(axis.get_view_interval())
        for tick in axis.get_major_ticks() + axis.get_minor_ticks():
            loc = tick.get_loc()
            if loc is None or not lo <= loc <= hi:
                continue
            out += [t for t in (tick.label1, tick.label2) if t.get_visible() and t.get_text().strip()]
    return out


def layout_problems(fig) -> tuple:
    """What leaves its frame or overlaps in a laid-out figure, one sentence each.

    Checked: every title, axis label, legend and text within the figure, and an axes' texts
    and annotations within that axes; every tick label within the figure; no two of the
    titles, axis labels, legends and texts overlapping; no two legend entries drawn alike
    (same colour and line style) for different curves.
    """
    fig.draw_without_rendering()
    return _drawn_problems(fig)


def _drawn_problems(fig) -> tuple:
    """:func:`layout_problems` of a figure drawn as it stands (no change since its last draw)."""
    renderer = _renderer(fig)
    problems = []
    boxes = _boxes(fig, renderer)
    for what, _, box, frame in boxes:
        if _outside(box, frame):
            where = "its axes" if frame is not fig.bbox else "the figure"
            problems.append(f"{what} runs outside {where}")
    for i, ax in enumerate(fig.axes, 1):
        for label in _drawn_tick_labels(ax):
            if _outside(label.get_window_extent(renderer), fig.bbox):
                problems.append(f"axes {i} tick label {label.get_text()!r} runs outside the figure")
    for k, (what, _, box, _f) in enumerate(boxes):
        for other, _, box2, _f2 in boxes[k + 1:]:
            if _overlap(box, box2):
                problems.append(f"{what} overlaps {other}")
    seen = {}  # across the figure's legends: a reader matches a curve in any panel to any entry
    for leg in [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None] + list(fig.legends):
        for label, style in _legend_styles(leg):
            if style in seen and seen[style] != label:
                problems.append(f"legend entries {seen[style]!r} and {label!r} are drawn alike")
            seen.setdefault(style, label)
    return tuple(problems)


def stroke_grid(drivetrain, points: int = 121) -> np.ndarray:
    """Output angles q over the stroke (rad)."""
    lo, hi = drivetrain.stroke
    return np.linspace(lo, hi, points)


def _x(q, linear: bool):
    """Stroke coordinate for plotting: degrees, or mm for a linear output."""
    return (np.asarray(q) * 1e3, "output travel [mm]") if linear else (np.degrees(q), "output angle [deg]")


def shares_along_stroke(chain, q, ax, linear: bool = False) -> None:
    """Stacked compliance shares of each stage along the stroke."""
    x, xlabel = _x(q, linear)
    ax.stackplot(x, chain.shares * 100, labels=chain.names, alpha=0.85)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("share of compliance [%]")
    ax.set_ylim(0, 100)
    ax.set_xlim(x[0], x[-1])
    ax.legend(fontsize="small", loc="upper left", bbox_to_anchor=(1.01, 1.0))
    ax.set_title("Who is compliant: each stage's share of the series compliance")


def stiffness_along_stroke(chain, q, ax, linear: bool = False, display: DisplayUnits | None = None) -> None:
    """Each stage's stiffness at the output and the series total, in ``display``'s unit
    (default SI: N*m/rad, or N/m for a linear output; log scale)."""
    x, xlabel = _x(q, linear)
    display = display or DisplayUnits()
    scale, unit = display.factor("stiffness", linear), display.stiffness_unit(linear)
    for name, k in zip(chain.names, chain.stage_stiffness):
        ax.semilogy(x, k * scale, label=name)
    ax.semilogy(x, chain.total * scale, "k", lw=2.2, label="series total")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(f"stiffness at the output [{unit}]")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize="small")
    ax.set_title("Stage stiffness reflected to the output (k times ratio squared)")


def ratio_inertia_along_stroke(drivetrain, q, axes, display: DisplayUnits | None = None) -> None:
    """Ratio N(q) and reflected inertia J(q) (at the output, in ``display``'s unit, default
    SI; and at the motor, kg*m^2)."""
    linear = bool(getattr(drivetrain, "output_is_linear", False))
    deg, xlabel = _x(q, linear)
    display = display or DisplayUnits()
    out_unit, j_unit, jf = ("m" if linear else "rad"), display.inertia_unit(linear), display.factor("inertia", linear)
    n, dn = drivetrain.ratio(q)
    j, dj = drivetrain.inertia(q)
    ax1, ax2 = axes
    ax1.plot(deg, n, label="N(q)")
    ax1.set_ylabel(f"ratio N [motor rad / output {out_unit}]")
    ax1b = ax1.twinx()
    ax1b.plot(deg, dn, "C1--", label="dN/dq")
    ax1b.set_ylabel(f"dN/dq [rad/{out_unit}^2]" if linear else "dN/dq [1/rad]", color="C1")
    ax1.set_title("Kinematic ratio along the stroke")
    ax1.grid(True, alpha=0.3)
    ax2.plot(deg, j * jf, label="J(q) at the output")
    ax2.set_ylabel(f"{'mass' if linear else 'J'} at the output [{j_unit}]")
    ax2b = ax2.twinx()
    ax2b.plot(deg, j / n**2, "C2--", label="J / N^2 at the motor")
    ax2b.set_ylabel("J at the motor [kg*m^2]", color="C2")
    ax2.set_title("Reflected inertia along the stroke")
    ax2.grid(True, alpha=0.3)
    for ax in axes:
        ax.set_xlabel(xlabel)
