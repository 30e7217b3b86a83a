"""Sections on the designed loop: plant, controller, loop margins (the requirements table:
:mod:`.sections_requirements`)."""

from __future__ import annotations

import math

import numpy as np

from ..display.units import DIMENSIONLESS
from ..loop.structures import PARAMETERS, parameter_unit
from . import figures
from .section import FigureSpec, Section, fmt, para, table
from .sections_drivetrain import ratio_row, two_mass_stiffness

F_MIN, F_MAX = 0.1, 1000.0


def _response(sys, f):
    """Complex frequency response of a SISO system at ``f`` (Hz)."""
    import control as ct
    return np.asarray(ct.frequency_response(sys, 2 * np.pi * f).complex).reshape(-1)


def _bode(ax_mag, ax_ph, f, r, label, **kw):
    ax_mag.semilogx(f, 20 * np.log10(np.abs(r)), label=label, **kw)
    ax_ph.semilogx(f, np.degrees(np.unwrap(np.angle(r))), label=label, **kw)


#: a label to the right of a mark past this fraction of the log frequency axis goes to its left
#: (and a line higher), so it stays within the axes
RIGHT_ROOM = 0.62


def _mark(axes, f, text, colour="C3", side="right"):
    """A dotted line at ``f`` on every axes and its label on the first, beside the line on
    ``side`` (to the left, a line higher, when the right has no room left)."""
    if math.isfinite(f) and F_MIN < f < F_MAX:
        for ax in axes:
            ax.axvline(f, color=colour, lw=0.9, ls=":")
        y = 0.04
        if side == "right" and math.log(f / F_MIN) / math.log(F_MAX / F_MIN) > RIGHT_ROOM:
            side, y = "left", 0.14
        x = f * (1.04 if side == "right" else 1 / 1.04)
        axes[0].annotate(text, (x, y), xycoords=("data", "axes fraction"), fontsize="small",
                         ha="left" if side == "right" else "right", va="bottom", color=colour)


def plant_bode(ctx) -> Section:
    """Plant Bode plot (voltage to output angle) with the drivetrain resonance marked."""
    d = ctx.design()
    p = d.parameters
    from ..plant.linear import rigid_plant as plant_mod
    f = np.logspace(math.log10(F_MIN), math.log10(F_MAX), 1500)
    fig, (am, ap) = figures.new_figure(2, 1, size=(7.5, 5.2), sharex=True)
    _bode(am, ap, f, _response(d.plant["theta", "u"], f), "plant model used by the design")
    rigid = plant_mod(ctx.scene, p.q0)
    _bode(am, ap, f, _response(rigid["theta", "u"], f), "rigid drivetrain", ls="--", color="0.5")
    _mark((am, ap), p.resonance_hz, f"resonance {p.resonance_hz:.3g} Hz")
    _mark((am, ap), p.antiresonance_hz, f"anti-resonance {p.antiresonance_hz:.3g} Hz", "C2", side="left")
    u = d.unit
    am.set_ylabel(f"|q / u| [dB {u.si}/V]")
    ap.set_ylabel("phase [deg]")
    ap.set_xlabel("frequency [Hz]")
    am.legend(fontsize="small", loc="upper right")
    for ax in (am, ap):
        ax.grid(True, which="both", alpha=0.3)
    what = "output travel" if u.linear else "output angle"
    am.set_title(f"Plant at q0 = {u.text(p.q0)}: armature voltage to {what}")
    shown = ctx.scene.display
    n_label, n_unit = ratio_row(u.linear)
    k_rows, k_text = two_mass_stiffness(ctx.scene, p, u.linear)
    rows = [("operating point q0", fmt(u.show(p.q0)), u.shown),
            ("motor-side inertia J1 (at the output)", fmt(shown.show("inertia", p.J1, u.linear)),
             shown.inertia_unit(u.linear)),
            ("load-side inertia J2", fmt(shown.show("inertia", p.J2, u.linear)), shown.inertia_unit(u.linear)),
            *k_rows, (n_label, fmt(p.N), n_unit), ("efficiency", fmt(p.eta), DIMENSIONLESS),
            ("resonance sqrt(K (1/J1 + 1/J2)) / 2 pi", fmt(p.resonance_hz), "Hz"),
            ("anti-resonance sqrt(K / J2) / 2 pi", fmt(p.antiresonance_hz), "Hz"),
            ("electrical time constant L/R", fmt(p.L / p.R * 1e3), "ms")]
    text = para("The linear plant at the operating point: motor electrics, the motor side J1 and the load side "
                "J2 joined by the two-mass model's stiffness K, or rigidly coupled. The resonance is where the "
                "loop will meet the drivetrain.", *filter(None, [k_text]))
    return Section("Plant Bode with the drivetrain resonance", text + table(("quantity", "value", "unit"), rows),
                   (FigureSpec(fig, f"Plant from armature voltage to {what}, with the rigid model for comparison."),),
                   key="plant")


def _param_row(kind, name, value, out):
    meaning, unit = PARAMETERS.get(name, (name, ""))[0], parameter_unit(name, out)
    shown = f"{fmt(value)} {unit}".rstrip()
    if unit == "rad/s":
        shown += f" ({fmt(value / (2 * math.pi))} Hz)"
    return (f"{kind} {name}: {meaning}", shown)


def _polys(sys):
    """Numerator and denominator of a SISO system as text, highest power first."""
    import control as ct
    tf = ct.ss2tf(sys)
    num, den = (np.atleast_1d(np.squeeze(x)) for x in (tf.num[0][0], tf.den[0][0]))
    scale = den[0] if den.size and den[0] != 0 else 1.0
    return " ".join(f"{v / scale:.6g}" for v in num), " ".join(f"{v / scale:.6g}" for v in den)


def _forms(motion, sample_time):
    """Rows of the continuous and (Tustin) discrete transfer functions of each channel."""
    import control as ct
    rows = []
    for inp, label in (("theta_ref", "position error -> i_ref"), ("omega_m", "motor speed -> i_ref")):
        sub = motion["i_ref", inp]
        if not (sub.nstates or np.any(sub.D)):
            continue
        num, den = _polys(sub)
        rows.append((f"{label}, continuous (s)", f"num [{num}] / den [{den}]"))
        if sample_time > 0:
            dnum, dden = _polys(ct.sample_system(sub, sample_time, method="tustin"))
            rows.append((f"{label}, discrete (z, Tustin, Ts = {fmt(sample_time * 1e3)} ms)",
                         f"num [{dnum}] / den [{dden}]"))
    return rows


def controller(ctx) -> Section:
    """The designed controller: structure, every gain and filter parameter with its unit,
    continuous and discrete forms, sampling."""
    d = ctx.design()
    info = d.to_dict().get("controller", {})
    out = "m" if ctx.scene.drivetrain.output_unit == "m" else "rad"
    rows = [("structure", info.get("structure") or "-"), ("description", info.get("description", "-"))]
    rows += [_param_row("gain", k, v, out) for k, v in (info.get("gains") or {}).items()]
    rows += [("resonance filter", info.get("filter") or "none")]
    rows += [_param_row("filter", k, v, out) for k, v in (info.get("filter_params") or {}).items()]
    rows += [("current loop kp", f"{fmt(info.get('current_kp_v_per_a'))} V/A"),
             ("current loop ki", f"{fmt(info.get('current_ki_v_per_a_s'))} V/(A*s)"),
             ("sample time", f"{fmt((info.get('sample_time_s') or 0.0) * 1e3)} ms")]
    rows += _forms(d.controller.motion, info.get("sample_time_s") or 0.0)
    motion = d.controller.motion
    f = np.logspace(math.log10(F_MIN), math.log10(F_MAX), 800)
    fig, (am, ap) = figures.new_figure(2, 1, size=(7.5, 4.6), sharex=True)
    _bode(am, ap, f, _response(motion["i_ref", "theta_ref"], f), "position error to current command")
    if np.any(motion["i_ref", "omega_m"].D) or motion["i_ref", "omega_m"].nstates:
        r = _response(motion["i_ref", "omega_m"], f)
        if np.any(np.abs(r) > 0):
            _bode(am, ap, f, -r, "motor speed feedback (sign flipped)", ls="--")
    am.set_ylabel("magnitude [dB]")
    ap.set_ylabel("phase [deg]")
    ap.set_xlabel("frequency [Hz]")
    am.legend(fontsize="small")
    for ax in (am, ap):
        ax.grid(True, which="both", alpha=0.3)
    am.set_title("Motion controller (continuous; sampled by Tustin at the sample time)")
    return Section("Designed controller", para(
        "The cascade the simulation runs: an analog current PI inside, the motion controller below "
        "sampled at the sensor sample time.") + table(("item", "value"), rows, table_id="controller-table"),
        (FigureSpec(fig, "Frequency response of the motion controller."),), key="controller")


def plotted_range(m) -> float:
    """Upper frequency (Hz) of the loop plots: :data:`F_MAX`, or past the last crossing."""
    last = [x for x in list(m.gain_crossover_hz) + list(m.phase_crossover_hz) if math.isfinite(x)]
    return max([F_MAX] + [1.5 * x for x in last])


def phase_at(sys, f_hz: float) -> float:
    """Phase (deg, in (-360, 0] for a lagging loop) of a SISO system at ``f_hz``."""
    if not math.isfinite(f_hz):
        return math.nan
    r = _response(sys, np.array([f_hz]))[0]
    ph = math.degrees(np.angle(r))
    return ph - 360.0 if ph > 0 else ph


def _margin_bar(ax, x, y0, y1, text, color, span) -> None:
    """A margin drawn as a bar at frequency ``x`` from ``y0`` to ``y1``, its label beside the
    bar's middle on the side with room (left of a bar in the right part of the log ``span``),
    on a white ground so that a curve under it does not hide it."""
    ax.plot([x, x], [y0, y1], color, lw=2)
    right = math.log(x / span[0]) / math.log(span[1] / span[0]) > 0.6
    ax.annotate(text, (x, 0.5 * (y0 + y1)), xytext=(-5 if right else 5, 0), textcoords="offset points",
                ha="right" if right else "left", va="center", fontsize="small", color=color,
                bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none", "alpha": 0.85})


def loop_margins(ctx) -> Section:
    """Open-loop Bode and Nyquist with every crossing and margin marked."""
    d = ctx.design()
    m = d.margins
    f_hi = plotted_range(m)
    f_req = next((c.required for c in d.requirements if c.name == "bandwidth"), m.phase_at_hz)
    f = np.logspace(math.log10(F_MIN), math.log10(f_hi), 2000)
    f = np.unique(np.concatenate([f, [x for x in m.gain_crossover_hz + m.phase_crossover_hz if F_MIN < x < f_hi]]))
    lw = _response(d.loop, f)
    mag = 20 * np.log10(np.abs(lw))
    ph = np.degrees(np.unwrap(np.angle(lw)))
    fig, (am, ap) = figures.new_figure(2, 1, size=(7.5, 5.2), sharex=True)
    am.semilogx(f, mag, label="open loop L")
    am.semilogx(f, 20 * np.log10(np.abs(1 / (1 + lw))), "--", label="sensitivity S = 1/(1+L)")
    ap.semilogx(f, ph)
    am.axhline(0, color="k", lw=0.7)
    bottoms = []
    for fc, pm in zip(m.gain_crossover_hz, m.phase_margins_deg):
        k = int(np.argmin(np.abs(f - fc)))
        _margin_bar(ap, fc, ph[k], ph[k] - pm, (f"PM {pm:.1f} deg " if m.closed_loop_stable else "") + f"@ {fc:.4g} Hz",
                    "C2", (F_MIN, f_hi))
    for fp, gm in zip(m.phase_crossover_hz, m.gain_margins_db):
        if F_MIN < fp < f_hi:
            k = int(np.argmin(np.abs(f - fp)))
            bottoms.append(mag[k])
            _margin_bar(am, fp, mag[k], mag[k] + gm, (f"GM {gm:.1f} dB " if m.closed_loop_stable else "")
                        + f"@ {fp:.4g} Hz", "C3", (F_MIN, f_hi))
    ref = ph[0] - (ph[0] + 180) % 360
    for n in range(-3, 2):
        ap.axhline(ref + 360 * n, color="0.6", lw=0.7)
    ap.set_ylim(ph.min() - 30, ph.max() + 30)
    am.set_ylim(min([max(mag.min(), -120)] + bottoms) - 10, mag.max() + 10)  # every margin's bar whole
    am.set_ylabel("magnitude [dB]")
    ap.set_ylabel("phase [deg]")
    ap.set_xlabel("frequency [Hz]")
    am.legend(fontsize="small")
    for ax in (am, ap):
        ax.grid(True, which="both", alpha=0.3)
    am.set_title("Open loop broken at the position error")
    fig2, ax = figures.new_figure(size=(5.5, 5.0))
    full = np.concatenate([np.conj(lw[::-1]), lw])
    ax.plot(full.real, full.imag, "C0", lw=1.2, label="L(j w)")
    t = np.linspace(0, 2 * np.pi, 200)
    ax.plot(np.cos(t), np.sin(t), color="0.6", lw=0.8, label="unit circle")
    if m.closed_loop_stable:  # an unstable closed loop has no Ms
        ms = 10 ** (m.sensitivity_peak_db / 20)
        ax.plot(-1 + np.cos(t) / ms, np.sin(t) / ms, "C1--", lw=1,
                label=f"1/Ms circle (Ms = {m.sensitivity_peak_db:.2f} dB)")
    ax.plot([-1], [0], "k+", ms=14, mew=2.2, label="critical point -1")
    for k, fc in enumerate(m.gain_crossover_hz):
        r = _response(d.loop, np.array([fc]))[0]
        ax.plot(r.real, r.imag, "C2o", label="gain crossing" if k == 0 else None)
    for k, fp in enumerate(m.phase_crossover_hz):
        r = _response(d.loop, np.array([fp]))[0]
        ax.plot(r.real, r.imag, "C3s", label="phase crossing" if k == 0 else None)
    ax.set_xlim(-3, 1.5)
    ax.set_ylim(-2.5, 2.0)
    ax.set_aspect("equal")
    ax.grid(True, alpha=0.3)
    ax.set_xlabel("Re L")
    ax.set_ylabel("Im L")
    ax.legend(fontsize="small", loc="upper left", bbox_to_anchor=(1.02, 1.0))
    ax.set_title("Nyquist near -1")
    rows = [("gain margin (smallest)", fmt(m.gain_margin_db), "dB"),
            ("phase margin (smallest)", fmt(m.phase_margin_deg), "deg"),
            ("delay margin (smallest)", fmt(m.delay_margin_s * 1e3), "ms"),
            ("disk margin alpha (balanced)", fmt(m.disk_margin), DIMENSIONLESS),
            ("disk gain / phase margin", f"{fmt(m.disk_gain_margin_db)} dB / {fmt(m.disk_phase_margin_deg)} deg", ""),
            ("sensitivity peak Ms", fmt(m.sensitivity_peak_db), "dB"),
            ("closed-loop bandwidth (-3 dB)", fmt(m.bandwidth_hz), "Hz"),
            (f"closed-loop phase at {fmt(f_req)} Hz (the required bandwidth)", fmt(phase_at(d.closed_loop, f_req)),
             "deg"),
            (f"closed-loop phase at the achieved bandwidth, {fmt(m.bandwidth_hz)} Hz",
             fmt(phase_at(d.closed_loop, m.bandwidth_hz)), "deg"),
            ("closed loop stable", "yes" if m.closed_loop_stable else f"NO: {m.instability}", "")]
    if m.closed_loop_stable:
        crossings = [("phase crossing", fmt(fp), f"gain margin {fmt(g)} dB") for fp, g in
                     zip(m.phase_crossover_hz, m.gain_margins_db)]
        crossings += [("gain crossing", fmt(fc), f"phase margin {fmt(p)} deg, delay margin {fmt(dm * 1e3)} ms")
                      for fc, p, dm in zip(m.gain_crossover_hz, m.phase_margins_deg, m.delay_margins_s)]
        intro = "Margins from python-control at every crossing (not only the smallest)"
    else:  # where L crosses, but no margins: the closed loop is unstable
        crossings = [("phase crossing", fmt(fp), f"|L| = {fmt(-g)} dB (not a margin)") for fp, g in
                     zip(m.phase_crossover_hz, m.gain_margins_db)]
        crossings += [("gain crossing", fmt(fc), f"phase of L {fmt(p - 180)} deg (not a margin)")
                      for fc, p in zip(m.gain_crossover_hz, m.phase_margins_deg)]
        intro = (f"The closed loop is unstable ({m.instability}): it has no gain, phase or delay margin, no disk "
                 "margin, Ms or bandwidth (a margin measures how far a stable loop is from instability), so these "
                 "are n/a; the crossings of L are listed")
    return Section("Loop Bode and Nyquist with margins",
                   para(f"{intro}; the plots span {fmt(F_MIN)} to {fmt(f_hi)} Hz, so every crossing listed is "
                        "marked on them.")
                   + table(("figure", "value", "unit"), rows) + table(("crossing", "frequency [Hz]", "margin"), crossings,
                                                                 table_id="crossings-table"),
                   (FigureSpec(fig, "Open-loop Bode with every gain and phase margin marked."),
                    FigureSpec(fig2, "Nyquist plot near the critical point.")), key="loop")
