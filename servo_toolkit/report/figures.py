"""Figures for the report: created without pyplot (no global state), encoded as PNG."""

from __future__ import annotations

import base64
import io

import numpy as np
from matplotlib.figure import Figure

from ..display.units import DisplayUnits

DPI = 110


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


def png_base64(fig, dpi: int = DPI) -> str:
    """The figure as a base64-encoded PNG."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    return base64.b64encode(buf.getvalue()).decode("ascii")


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
