"""Sections on the designed loop: requirements, plant, controller, loop margins."""

from __future__ import annotations

import math

import numpy as np

from . import figures
from .section import FigureSpec, NotAvailable, Section, badge, esc, fmt, para, table
from .units_table import UNITS

_REQ_TEXT = {
    "bandwidth": "closed-loop bandwidth (-3 dB) at least",
    "max_phase_lag_at_bandwidth": "phase lag at the bandwidth at most",
    "min_gain_margin": "gain margin at least",
    "min_phase_margin": "phase margin at least",
    "max_sensitivity_peak": "sensitivity peak Ms at most",
}
_CHECK_TEXT = {"bandwidth": "closed-loop bandwidth (-3 dB)", "phase_lag_at_bandwidth": "phase lag at the bandwidth",
               "gain_margin": "gain margin", "phase_margin": "phase margin",
               "sensitivity_peak": "sensitivity peak Ms",
               "stable_over_stroke": "closed loop stable over the stroke (fraction of points)",
               "gain_margin_over_stroke": "gain margin, worst over the stroke",
               "phase_margin_over_stroke": "phase margin, worst over the stroke",
               "sensitivity_peak_over_stroke": "sensitivity peak Ms, worst over the stroke"}
F_MIN, F_MAX = 0.1, 1000.0


def _scene_requirements(scene):
    """(name, required value in display units, unit) for each requirement the scene sets."""
    out = []
    for name in _REQ_TEXT:
        value = getattr(scene.requirements, name, None)
        if value is not None:
            unit, factor = UNITS[name]
            out.append((name, value * factor, unit))
    return out


def requirement_rows(ctx):
    """Rows (requirement, required, achieved, shortfall, status) of the requirements table."""
    return ctx.result("requirement_rows", lambda: _requirement_rows(ctx))


def _requirement_rows(ctx):
    wanted = _scene_requirements(ctx.scene)
    try:
        design = ctx.design()
    except NotAvailable as exc:
        if not wanted:
            return ()
        return tuple((_REQ_TEXT[n], f"{fmt(v)} {u}", "not evaluated", "", "unavailable") for n, v, u in wanted) \
            + (("(loop design)", "", str(exc), "", "unavailable"),)
    rows = []
    for c in design.requirements:
        label = _CHECK_TEXT.get(c.name, c.name) + ("" if c.source in ("scene", "always") else f" ({c.source})")
        short = "" if c.passed else f"short by {fmt(c.shortfall)} {c.unit}"
        rows.append((label, f"{c.sense} {fmt(c.required)} {c.unit}", f"{fmt(c.achieved)} {c.unit}", short,
                     "pass" if c.passed else "fail"))
    from .sections_montecarlo import requirement_rows as montecarlo_rows
    from .sections_robust import requirement_rows as robust_rows
    rows += robust_rows(ctx)
    try:
        rows += montecarlo_rows(ctx)
    except Exception as exc:  # noqa: BLE001 - the Monte Carlo section shows the same failure
        rows.append(("robust: nonlinear time runs", "", str(exc), "", "unavailable"))
    stable = bool(design.margins.closed_loop_stable)
    rows.append(("closed loop stable", "yes", "yes" if stable else "no",
                 "" if stable else f"pole at Re = {fmt(design.margins.max_closed_loop_pole_real)} 1/s",
                 "pass" if stable else "fail"))
    return tuple(rows)


def requirements(ctx) -> Section:
    """The pass/fail requirements table (shown at the top of the report)."""
    rows = requirement_rows(ctx)
    if not rows:
        return Section("Requirements", para("The scene sets no [requirements] and has no loop to design."),
                       status="n/a", reason="nothing to check for this scene", key="requirements")
    statuses = {r[4] for r in rows}
    status = "fail" if "fail" in statuses else ("unavailable" if "unavailable" in statuses else "pass")
    body = table(("requirement", "required", "achieved", "shortfall", "status"),
                 [(r[0], r[1], r[2], r[3], badge(r[4])) for r in rows], table_id="requirements-table")
    verdict = {"pass": "Every requirement is met by the designed loop (linear model at the operating point).",
               "fail": "Some requirements are not met; the table says which and by how much.",
               "unavailable": "Some requirements could not be evaluated."}[status]
    reason = next((r[2] for r in rows if r[0] == "(loop design)"), "")
    notes = ""
    if status != "unavailable":
        notes = "".join(f"<p>Note: {esc(n)}</p>" for n in ctx.design().notes)
    return Section("Requirements", para(verdict) + body + notes, status=status, reason=reason, key="requirements")


def _response(sys, f):
    """Complex frequency response of a SISO system at ``f`` (Hz)."""
    import control as ct
    return np.asarray(ct.frequency_response(sys, 2 * np.pi * f).complex).reshape(-1)


def _bode(ax_mag, ax_ph, f, r, label, **kw):
    ax_mag.semilogx(f, 20 * np.log10(np.abs(r)), label=label, **kw)
    ax_ph.semilogx(f, np.degrees(np.unwrap(np.angle(r))), label=label, **kw)


def _mark(axes, f, text, colour="C3", side="right"):
    if math.isfinite(f) and F_MIN < f < F_MAX:
        for ax in axes:
            ax.axvline(f, color=colour, lw=0.9, ls=":")
        x = f * (1.04 if side == "right" else 1 / 1.04)
        axes[0].annotate(text, (x, 0.04), xycoords=("data", "axes fraction"), fontsize="small",
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
    rows = [("operating point q0", fmt(u.show(p.q0)), u.shown),
            ("motor-side inertia J1 (at the output)", fmt(p.J1), u.inertia),
            ("load-side inertia J2", fmt(p.J2), u.inertia),
            ("series stiffness K", fmt(p.K / u.show(1.0)), f"{u.moment}/{u.shown}"),
            ("ratio N", fmt(p.N), "-"), ("efficiency", fmt(p.eta), "-"),
            ("resonance sqrt(K (1/J1 + 1/J2)) / 2 pi", fmt(p.resonance_hz), "Hz"),
            ("anti-resonance sqrt(K / J2) / 2 pi", fmt(p.antiresonance_hz), "Hz"),
            ("electrical time constant L/R", fmt(p.L / p.R * 1e3), "ms")]
    text = para("The linear plant at the operating point: motor electrics, the motor side and the load side "
                "joined by the series stiffness of the chain (two-mass model) or rigidly coupled. The "
                "resonance is where the loop will meet the drivetrain.")
    return Section("Plant Bode with the drivetrain resonance", text + table(("quantity", "value", "unit"), rows),
                   (FigureSpec(fig, f"Plant from armature voltage to {what}, with the rigid model for comparison."),),
                   key="plant")


#: gain or filter parameter -> (meaning, unit with OUT for the output's unit)
_PARAMS = {"kp": ("position gain", "1/s"), "kv": ("speed gain", "A*s/OUT"), "wvi": ("speed PI corner", "rad/s"),
           "kc": ("controller gain", "A/OUT"), "wi": ("integral corner", "rad/s"), "wz": ("lead zero", "rad/s"),
           "wp": ("lead pole", "rad/s"), "wn": ("filter frequency", "rad/s"),
           "zeta_zero": ("notch depth: damping of the zeros", "-"), "zeta_pole": ("notch width: damping of the poles", "-"),
           "zeta": ("low-pass damping", "-")}


def _param_row(kind, name, value, out):
    meaning, unit = _PARAMS.get(name, (name, ""))
    unit = unit.replace("OUT", out)
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


def loop_margins(ctx) -> Section:
    """Open-loop Bode and Nyquist with every crossing and margin marked."""
    d = ctx.design()
    m = d.margins
    f = np.logspace(math.log10(F_MIN), math.log10(F_MAX), 2000)
    f = np.unique(np.concatenate([f, [x for x in m.gain_crossover_hz + m.phase_crossover_hz if F_MIN < x < F_MAX]]))
    lw = _response(d.loop, f)
    mag = 20 * np.log10(np.abs(lw))
    ph = np.degrees(np.unwrap(np.angle(lw)))
    fig, (am, ap) = figures.new_figure(2, 1, size=(7.5, 5.2), sharex=True)
    am.semilogx(f, mag, label="open loop L")
    am.semilogx(f, 20 * np.log10(np.abs(1 / (1 + lw))), "--", label="sensitivity S = 1/(1+L)")
    ap.semilogx(f, ph)
    am.axhline(0, color="k", lw=0.7)
    for fc, pm in zip(m.gain_crossover_hz, m.phase_margins_deg):
        k = int(np.argmin(np.abs(f - fc)))
        ap.plot([fc, fc], [ph[k], ph[k] - pm], "C2", lw=2)
        ap.annotate(f"PM {pm:.1f} deg\n@ {fc:.3g} Hz", (fc, ph[k] - pm), fontsize="small", color="C2")
    for fp, gm in zip(m.phase_crossover_hz, m.gain_margins_db):
        if F_MIN < fp < F_MAX:
            k = int(np.argmin(np.abs(f - fp)))
            am.plot([fp, fp], [mag[k], mag[k] + gm], "C3", lw=2)
            am.annotate(f"GM {gm:.1f} dB\n@ {fp:.3g} Hz", (fp, mag[k] + gm), fontsize="small", color="C3")
    ref = ph[0] - (ph[0] + 180) % 360
    for n in range(-3, 2):
        ap.axhline(ref + 360 * n, color="0.6", lw=0.7)
    ap.set_ylim(ph.min() - 30, ph.max() + 30)
    am.set_ylim(max(mag.min(), -120), mag.max() + 10)
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
    ms = 10 ** (m.sensitivity_peak_db / 20)
    ax.plot(-1 + np.cos(t) / ms, np.sin(t) / ms, "C1--", lw=1, label=f"1/Ms circle (Ms = {m.sensitivity_peak_db:.2f} dB)")
    ax.plot([-1], [0], "r+", ms=12, mew=2)
    for fc in m.gain_crossover_hz:
        r = _response(d.loop, np.array([fc]))[0]
        ax.plot(r.real, r.imag, "C2o")
    for fp in m.phase_crossover_hz:
        r = _response(d.loop, np.array([fp]))[0]
        ax.plot(r.real, r.imag, "C3s")
    ax.set_xlim(-3, 1.5)
    ax.set_ylim(-2.5, 2.0)
    ax.set_aspect("equal")
    ax.grid(True, alpha=0.3)
    ax.set_xlabel("Re L")
    ax.set_ylabel("Im L")
    ax.legend(fontsize="small", loc="lower right")
    ax.set_title("Nyquist near -1 (green: gain crossings, red: phase crossings)")
    rows = [("gain margin (smallest)", fmt(m.gain_margin_db), "dB"),
            ("phase margin (smallest)", fmt(m.phase_margin_deg), "deg"),
            ("delay margin (smallest)", fmt(m.delay_margin_s * 1e3), "ms"),
            ("disk margin alpha (balanced)", fmt(m.disk_margin), "-"),
            ("disk gain / phase margin", f"{fmt(m.disk_gain_margin_db)} dB / {fmt(m.disk_phase_margin_deg)} deg", ""),
            ("sensitivity peak Ms", fmt(m.sensitivity_peak_db), "dB"),
            ("closed-loop bandwidth (-3 dB)", fmt(m.bandwidth_hz), "Hz"),
            (f"closed-loop phase at {fmt(m.phase_at_hz)} Hz", fmt(m.phase_at_freq_deg), "deg"),
            ("closed loop stable", "yes" if m.closed_loop_stable else "NO", "")]
    crossings = [("phase crossing", fmt(fp), f"gain margin {fmt(g)} dB") for fp, g in
                 zip(m.phase_crossover_hz, m.gain_margins_db)]
    crossings += [("gain crossing", fmt(fc), f"phase margin {fmt(p)} deg, delay margin {fmt(dm * 1e3)} ms")
                  for fc, p, dm in zip(m.gain_crossover_hz, m.phase_margins_deg, m.delay_margins_s)]
    return Section("Loop Bode and Nyquist with margins",
                   para("Margins from python-control at every crossing (not only the smallest).")
                   + table(("figure", "value", "unit"), rows) + table(("crossing", "frequency [Hz]", "margin"), crossings),
                   (FigureSpec(fig, "Open-loop Bode with every gain and phase margin marked."),
                    FigureSpec(fig2, "Nyquist plot near the critical point.")), key="loop")
