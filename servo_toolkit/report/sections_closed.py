"""The closed loop a design review reads: |T| and |S| against the requirements, the Nichols
chart with M-contours, the dynamic stiffness against an external moment, and the step
response with its figures annotated."""

from __future__ import annotations

import math

import numpy as np

from . import figures
from .section import FigureSpec, Section, fmt, para, table

F_MIN, F_MAX = 0.1, 1000.0
#: closed-loop |T| contours of the Nichols chart (dB)
M_LEVELS = (-6.0, -3.0, -1.0, 0.0, 1.0, 3.0, 6.0)


def _response(sys, f):
    import control as ct
    return np.asarray(ct.frequency_response(sys, 2 * np.pi * np.asarray(f, float)).complex).reshape(-1)


def _db(x):
    with np.errstate(divide="ignore"):
        return 20 * np.log10(np.abs(x))


def output_units(scene):
    """(stroke unit, external load unit, display factor of a stiffness, its unit, angle
    factor, angle unit) for an output angle or an output travel; the stiffness in the
    scene's ``[display]`` unit (SI by default)."""
    linear = scene.drivetrain.output_unit == "m"
    k_factor, k_unit = scene.display.factor("stiffness", linear), scene.display.stiffness_unit(linear)
    if linear:
        return "m", "N", k_factor, k_unit, 1e3, "mm"
    return "rad", "N*m", k_factor, k_unit, 180 / math.pi, "deg"


def dynamic_stiffness(design, f):
    """|tau_ext / theta| of the closed loop at ``f`` (Hz), in SI (N*m/rad or N/m): the
    external load needed per unit of output motion it causes."""
    compliance = _response(design.closed_loop_full["theta", "tau_ext"], f)
    with np.errstate(divide="ignore"):
        return 1.0 / np.abs(compliance)


def step_figures(design, t_end=None):
    """Step response of ``theta_ref -> theta`` and python-control's ``step_info`` of it."""
    import control as ct
    bw = design.margins.bandwidth_hz
    if t_end is None:
        t_end = min(2.0, max(0.05, 6.0 / bw)) if math.isfinite(bw) and bw > 0 else 0.5
    t = np.linspace(0.0, t_end, 2001)
    _, y = ct.step_response(design.closed_loop, t)
    info = ct.step_info(design.closed_loop, T=t)
    return t, np.asarray(y).reshape(-1), info


def _nichols(ax, lw, ms_req):
    ph = np.degrees(np.unwrap(np.angle(lw)))
    ph -= 360.0 * np.round((ph[np.argmin(np.abs(_db(lw)))] + 180.0) / 360.0) if np.any(np.isfinite(ph)) else 0.0
    g = _db(lw)
    pg, gg = np.meshgrid(np.linspace(-360, 0, 361), np.linspace(-30, 30, 241))
    L = 10 ** (gg / 20) * np.exp(1j * np.radians(pg))
    with np.errstate(divide="ignore", invalid="ignore"):
        t_db = _db(L / (1 + L))
    levels = sorted(set(M_LEVELS) | ({round(ms_req, 2)} if ms_req else set()))
    cs = ax.contour(pg, gg, t_db, levels=levels, colors="0.65", linewidths=0.7)
    ax.clabel(cs, fmt="%g dB", fontsize="x-small")
    keep = (g > -30) & (g < 30)
    ax.plot(ph[keep], g[keep], "C0", lw=1.5, label="L(j w)")
    ax.plot([-180], [0], "r+", ms=12, mew=2)
    ax.set(xlim=(-360, 0), ylim=(-30, 30), xlabel="open-loop phase [deg]", ylabel="open-loop gain [dB]",
           title="Nichols chart with closed-loop |T| contours")
    ax.grid(True, alpha=0.3)


def closed_loop(ctx) -> Section:
    """|T| and |S| with the requirement lines, Nichols, dynamic stiffness, annotated step."""
    d = ctx.design()
    m = d.margins
    req = ctx.scene.requirements
    f = np.logspace(math.log10(F_MIN), math.log10(F_MAX), 1500)
    lw = _response(d.loop, f)
    T = _response(d.closed_loop, f)
    S = 1.0 / (1.0 + lw)
    fig, ax = figures.new_figure(size=(7.5, 4.0))
    ax.semilogx(f, _db(T), label="|T| (command to output)")
    ax.semilogx(f, _db(S), label="|S| (sensitivity)")
    ax.axhline(-3.0, color="C0", lw=0.8, ls=":", label="-3 dB")
    if req.max_sensitivity_peak is not None:
        ax.axhline(req.max_sensitivity_peak, color="C1", lw=0.9, ls="--",
                   label=f"Ms limit {req.max_sensitivity_peak:g} dB")
    if req.bandwidth is not None:
        ax.axvline(req.bandwidth, color="C3", lw=0.9, ls="--", label=f"required bandwidth {req.bandwidth:g} Hz")
    ax.set(xlabel="frequency [Hz]", ylabel="magnitude [dB]", ylim=(-40, 15),
           title="Closed loop and sensitivity against the requirements")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize="small", loc="lower left")
    fig2, ax2 = figures.new_figure(size=(6.5, 5.0))
    _nichols(ax2, lw, req.max_sensitivity_peak)
    _, load_unit, k_factor, k_unit, a_factor, a_unit = output_units(ctx.scene)
    k = dynamic_stiffness(d, f) * k_factor
    fig3, ax3 = figures.new_figure(size=(7.5, 3.6))
    ax3.loglog(f, k, label="closed loop")
    ax3.set(xlabel="frequency [Hz]", ylabel=f"dynamic stiffness [{k_unit}]",
            title=f"Disturbance rejection: external {load_unit} per {a_unit} of output motion")
    ax3.grid(True, which="both", alpha=0.3)
    kmin = int(np.argmin(k))
    ax3.plot(f[kmin], k[kmin], "C3o", label=f"minimum {fmt(k[kmin])} {k_unit} at {fmt(f[kmin])} Hz")
    ax3.legend(fontsize="small")
    t, y, info = step_figures(d)
    fig4, ax4 = figures.new_figure(size=(7.5, 3.6))
    ax4.plot(t * 1e3, y, label="unit step response")
    ax4.axhline(1.0, color="0.6", lw=0.8)
    for band in (0.98, 1.02):
        ax4.axhline(band * y[-1], color="0.8", lw=0.6, ls=":")
    tr, ts, peak, tp = info["RiseTime"], info["SettlingTime"], info["Peak"], info["PeakTime"]
    right = tp > 0.6 * t[-1]  # a peak late in the plot (no overshoot: at its end) is labelled on its left
    ax4.annotate(f"overshoot {info['Overshoot']:.1f} %", (tp * 1e3, peak), xytext=(-8 if right else 8, -4),
                 textcoords="offset points", ha="right" if right else "left", va="top", fontsize="small", color="C3")
    ax4.axvline(tr * 1e3, color="C2", lw=0.8, ls="--", label=f"rise time (10-90 %) {tr * 1e3:.3g} ms")
    ax4.axvline(ts * 1e3, color="C1", lw=0.8, ls="--", label=f"settling time (2 %) {ts * 1e3:.3g} ms")
    ax4.set(xlabel="time [ms]", ylabel="output / command", title="Linear step response")
    ax4.grid(True, alpha=0.3)
    ax4.legend(fontsize="small", loc="lower right")
    high = dynamic_stiffness(d, [F_MAX])[0] / (2 * math.pi * F_MAX) ** 2
    rows = [("sensitivity peak Ms", fmt(m.sensitivity_peak_db), "dB"),
            ("peak of |T|", fmt(float(np.max(_db(T)))), "dB"),
            ("closed-loop bandwidth (-3 dB)", fmt(m.bandwidth_hz), "Hz"),
            ("minimum dynamic stiffness", fmt(k[kmin]), k_unit),
            ("  at", fmt(f[kmin]), "Hz"),
            (f"dynamic stiffness / w^2 at {F_MAX:g} Hz (inertia seen by the load)",
             fmt(ctx.scene.display.show("inertia", high, load_unit == "N")),
             ctx.scene.display.inertia_unit(load_unit == "N")),
            ("step rise time (10-90 %)", fmt(tr * 1e3), "ms"),
            ("step overshoot", fmt(info["Overshoot"]), "%"),
            ("step settling time (2 %)", fmt(ts * 1e3), "ms")]
    text = para("The loop closed around the linear plant at q0: how the output follows the command (|T|), how much "
                "a disturbance or a model error is amplified (|S|, peak Ms), how the loop sits against the "
                "closed-loop contours (Nichols), how hard an external load must push to move the output "
                "(dynamic stiffness: the external load per unit of the output motion it causes), and the step "
                "figures from python-control's step_info.")
    return Section("Closed loop: sensitivity, Nichols, disturbance rejection, step",
                   text + table(("figure", "value", "unit"), rows, table_id="closed-loop-table"),
                   (FigureSpec(fig, "|T| and |S| with the bandwidth and Ms requirements."),
                    FigureSpec(fig2, "Nichols chart of the open loop with closed-loop |T| contours."),
                    FigureSpec(fig3, "Dynamic stiffness against an external load at the output."),
                    FigureSpec(fig4, "Linear step response with rise, overshoot and settling marked.")),
                   key="closed_loop")
