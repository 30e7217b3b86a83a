"""The ratio choice on one figure: the sweep's figures over the overall ratio, per motor,
against their limits, the feasible ratios shaded (the legend naming the limits that end
them) and the scene's ratio marked."""

from __future__ import annotations

import math
import textwrap

import numpy as np

from ...display.units import label

#: 0 degC in K
KELVIN = 273.15


def _runs(mask) -> list:
    """(first, last) indices of each run of True in ``mask``."""
    idx = np.flatnonzero(np.diff(np.concatenate([[0], np.asarray(mask, int), [0]])))
    return list(zip(idx[::2], idx[1::2] - 1))


#: the y label of the panel drawn as the chain's one value
STIFFNESS = "output stiffness"


def _panels(sw) -> list:
    """(title of the y axis, values per motor (motors, factors), limit per motor or one value,
    the limit's name, a lower bound?) of each panel."""
    lim = sw.limits or tuple({} for _ in sw.motors)
    temp = sw.winding_temperature - KELVIN
    panels = [
        (label("RMS current", "A"), sw.rms_current, [m.get("continuous_current") for m in lim], "continuous", False),
        (label("peak motor torque", "N*m"), sw.peak_torque, [m.get("peak_torque") for m in lim], "peak", False),
        (label("peak motor speed", "rad/s"), sw.peak_speed, [m.get("no_load_speed") for m in lim], "no-load", False),
        (label("peak voltage (hot winding)", "V"), sw.peak_voltage, [m.get("voltage") for m in lim], "supply", False),
        (label("peak winding temperature", "degC"), temp,
         [None if m.get("winding_temperature") is None else m["winding_temperature"] - KELVIN for m in lim],
         "winding", False),
        (label("achievable bandwidth (estimate)", "Hz"), sw.bandwidth, [sw.required_bandwidth], "required", True),
        (label(STIFFNESS, sw.stiffness_unit),
         np.full(sw.ratio.shape, sw.stiffness * sw.stiffness_factor)[None, :], [None], "", False),
    ]
    for part, hours in sw.lives:
        panels.append((label(f"L10 {part}", "h"), np.asarray(hours)[None, :], [sw.required_life], "required", True))
    return panels


def layout(sw) -> tuple:
    """(rows, columns) of the axes :func:`plot_sweep` draws on: a panel per figure and a cell
    for the legend."""
    return 2, math.ceil((len(_panels(sw)) + 1) / 2)


def plot_sweep(sw, axes=None):
    """Draw a :class:`~.sweep.RatioSweep`: RMS current, peak torque, peak speed, peak
    voltage, winding temperature, the bandwidth estimate, the output stiffness and (with a
    swept lead) the screw's lives over the overall ratio; each motor a colour, its limits
    dashed, its feasible ratios shaded (the legend names the limits that end them), the
    scene's ratio a dotted line. A panel held to a lower bound (the required bandwidth or
    life) spans its values and the bound, on a log scale when they span more than a decade.
    Returns the axes (created in the :func:`layout` when not given)."""
    import matplotlib.pyplot as plt
    panels = _panels(sw)
    if axes is None:
        rows, cols = layout(sw)
        _, axes = plt.subplots(rows, cols, figsize=(3.6 * cols, 6.4), sharex=True, layout="constrained")
    cols = np.shape(axes)[1] if np.ndim(axes) == 2 else None
    axes = np.ravel(axes)
    colours = [f"C{i}" for i in range(len(sw.motors))]
    xlabel = label("overall ratio", sw.ratio_unit)
    for ax, (ylabel, values, limits, what, lower) in zip(axes, panels):
        for i, row in enumerate(values):
            ax.plot(sw.ratio, row, color=colours[i], lw=1.5, label=sw.motors[i] if len(values) > 1 else None)
        for i, value in enumerate(limits):
            if value is not None and math.isfinite(value):
                colour = colours[i] if len(limits) > 1 else "k"
                ax.axhline(value, color=colour, ls="--", lw=1, label=f"{what} limit" if i == 0 else None)
        for i in range(len(sw.motors)):
            for a, b in _runs(sw.feasible[i]):
                ax.axvspan(sw.ratio[a], sw.ratio[b], color=colours[i], alpha=0.10, lw=0)
        ax.axvline(sw.scene_ratio, color="k", ls=":", lw=1)
        _frame(ax, values, limits, lower)
        ax.set_ylabel(ylabel)
    stiff = next(i for i, p in enumerate(panels) if p[0].startswith(STIFFNESS))
    axes[stiff].text(0.5, 0.9, "the same at every ratio", ha="center", transform=axes[stiff].transAxes,
                     fontsize="small")
    for ax in axes[len(panels):]:
        ax.axis("off")
    for i, ax in enumerate(axes[:len(panels)]):
        if cols is None or i >= cols or i + cols >= len(panels):   # the lowest panel of each column
            ax.set_xlabel(xlabel)
            ax.xaxis.set_tick_params(labelbottom=True)
    _legend(axes, sw, colours, len(panels))
    axes[0].figure.suptitle(f"Ratio sweep ({sw.swept}): feasible ratios shaded, the scene's ratio dotted",
                            fontsize="medium")
    return axes


def _frame(ax, values, limits, lower: bool = False) -> None:
    """Log ratio axis with plain tick labels. Against an upper limit, the y range kept to
    twice the highest finite limit when the values run far beyond it (a winding near thermal
    runaway); against a lower bound (values far above it are what is asked), the y range
    spans the values and the bound, logarithmic when they span more than a decade."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter
    ax.set_xscale("log")
    ax.xaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
    ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    ax.xaxis.set_minor_formatter(NullFormatter())
    ax.grid(True, alpha=0.3, which="both")
    finite = [v for v in limits if v is not None and math.isfinite(v)]
    data = np.asarray(values, float)
    data = data[np.isfinite(data)]
    if lower:
        shown = np.concatenate([data, finite])
        if shown.size:
            lo, hi = float(shown.min()), float(shown.max())
            if lo > 0 and hi > 10 * lo:
                ax.set_yscale("log")
                ax.yaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
                ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
                ax.yaxis.set_minor_formatter(NullFormatter())
                ax.set_ylim(lo / 1.25, hi * 1.25)
            else:
                pad = 0.05 * (hi - lo) or 0.05 * abs(hi) or 1.0
                ax.set_ylim(lo - pad, hi + pad)
    elif finite and data.size and data.max() > 2 * max(finite) > 0:
        ax.set_ylim(min(float(data.min()), max(finite)) * 0.9, 2 * max(finite))


def _legend(axes, sw, colours, used: int) -> None:
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch
    handles = [Line2D([], [], color=c, lw=1.5, label=m) for m, c in zip(sw.motors, colours)]
    handles += [Patch(color=c, alpha=0.2, label=_feasible_label(sw, i)) for i, c in enumerate(colours)]
    handles += [Line2D([], [], color="k", ls="--", lw=1, label="limit (a motor's in its colour)"),
                Line2D([], [], color="k", ls=":", lw=1, label=f"scene ratio {sw.scene_ratio:.4g}")]
    target = axes[used] if used < len(axes) else axes[0]
    target.legend(handles=handles, loc="center" if used < len(axes) else "best", fontsize="small")


def _feasible_label(sw, motor: int) -> str:
    """A motor's feasible ratios in the legend, with the limits that end them."""
    rng = sw.feasible_range(motor)
    if rng is None:
        return f"{sw.motors[motor]}: no ratio feasible"
    text = f"{sw.motors[motor]}: feasible {rng[0]:.4g} .. {rng[1]:.4g} {sw.ratio_unit}, {sw.limits_text(motor)}"
    return textwrap.fill(text, 40)


def plot_rms_panel(sw, ax):
    """One panel of the sweep: RMS current over the overall ratio with the continuous-current
    limits, the feasible ratios shaded and the scene's ratio marked (the overview's)."""
    title, values, limits, _, _ = _panels(sw)[0]
    for i, row in enumerate(values):
        ax.plot(sw.ratio, row, color=f"C{i}", lw=1.5, label=sw.motors[i])
        if limits[i] is not None:
            ax.axhline(limits[i], color=f"C{i}", ls="--", lw=1)
        for a, b in _runs(sw.feasible[i]):
            ax.axvspan(sw.ratio[a], sw.ratio[b], color=f"C{i}", alpha=0.10, lw=0)
    ax.axvline(sw.scene_ratio, color="k", ls=":", lw=1, label="scene ratio")
    _frame(ax, values, limits)
    ax.set_xlabel(label("overall ratio", sw.ratio_unit))
    ax.set_ylabel(title)
    ax.legend(fontsize="small")
    return ax


__all__ = ["layout", "plot_sweep", "plot_rms_panel"]
