"""The designed loop on a measured plant response (``report --plant-frf``): the margins on
the model and on the measurement side by side, the model's mismatch per band and the Bode
plots of both, points of poor coherence marked."""

from __future__ import annotations

import math

import numpy as np

from . import figures
from .section import FigureSpec, NotApplicable, Section, esc, fmt, para, table

#: the section's place in the report: after this section's key
AFTER = "loop"


def measured_result(ctx):
    """The :class:`~servo_toolkit.loop.measured_result.MeasuredLoop` of the report's design
    on the measured response the report was given (``ctx.plant_frf``)."""
    data = ctx.plant_frf
    if data is None:
        raise NotApplicable("no measured plant response was given (servo-toolkit report --plant-frf FRF.csv)")

    def compute():
        from ..loop.measured import measured_loop
        d = ctx.design()
        f_req = next((c.required for c in d.requirements if c.name == "bandwidth"), None)
        return measured_loop(d, ctx.scene.motor, data.frequency_hz, data.complex, data.coherence,
                             signal=ctx.plant_frf_signal, source=data.source, required_bandwidth_hz=f_req,
                             averages=data.averages, resolution_sd=data.resolution_sd)
    return ctx.result("measured_loop", compute)


def _cell(x, unit: str) -> str:
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "not decided"
    return x if isinstance(x, str) else f"{fmt(x, 4)} {unit}".strip()


def _bode(m):
    """Plant response and open loop, model and measured, points of poor coherence marked."""
    f, poor = m.frequency_hz, m.poor
    fig, axes = figures.new_figure(2, 2, size=(11.0, 6.0), sharex=True)
    pairs = (((m.model_response, m.response), "plant: motor current to " + m.signal, "response"),
             ((m.model_loop, m.loop), "open loop L (broken at the position error)", "L"))
    for col, ((model, measured), title, what) in enumerate(pairs):
        am, ap = axes[0, col], axes[1, col]
        ph_model = np.degrees(np.unwrap(np.angle(model)))
        ph_meas = np.degrees(np.unwrap(np.angle(measured)))
        ph_meas += 360.0 * round((ph_model[0] - ph_meas[0]) / 360.0)  # on the model's branch
        am.semilogx(f, 20 * np.log10(np.abs(model)), "C0-", label="model")
        ap.semilogx(f, ph_model, "C0-", label="model")
        am.semilogx(f, 20 * np.log10(np.abs(measured)), "C1.", ms=3, label="measured")
        ap.semilogx(f, ph_meas, "C1.", ms=3, label="measured")
        if poor.any():
            am.semilogx(f[poor], 20 * np.log10(np.abs(measured[poor])), "o", mfc="none", mec="C3", ms=5,
                        label=f"coherence below {m.poor_coherence:g} (decides nothing)")
            ap.semilogx(f[poor], ph_meas[poor], "o", mfc="none", mec="C3", ms=5)
        if col == 1:
            am.axhline(0, color="k", lw=0.7)
            for c in (*m.gain_crossings, *m.phase_crossings):
                if c.source == "measured":
                    for ax in (am, ap):
                        ax.axvline(c.frequency_hz, color="C2" if c.kind == "gain" else "C3", lw=0.8, ls=":")
        unit = {"motor_angle_rad": "rad/A", "motor_speed_rad_s": "rad/s/A", "output_angle_rad": "rad/A",
                "output_travel_m": "m/A"}.get(m.signal, "") if col == 0 else ""
        am.set_ylabel(f"|{what}| [dB{' re 1 ' + unit if unit else ''}]")
        ap.set_ylabel(f"arg {what} [deg]")
        ap.set_xlabel("frequency [Hz]")
        am.set_title(title)
        for ax in (am, ap):
            ax.grid(True, which="both", alpha=0.3)
        am.legend(fontsize="small")
    return fig


def measured_plant(ctx) -> Section:
    """Margins on the model and on the measured plant, the mismatch per band, the Bode plots."""
    m = measured_result(ctx)
    d = ctx.design()
    n_poor = int(m.poor.sum())
    f = m.frequency_hz
    intro = (f"Measured response from the motor current to {m.signal}, {f.size} points from {fmt(f[0])} to "
             f"{fmt(f[-1])} Hz ({m.source or 'given in memory'}), {n_poor} of them with a coherence below "
             f"{m.poor_coherence:g}. The designed controller, the sampling delay and the current loop's electrical "
             "side are the model's; the mechanics at each measured frequency are the measured ones.")
    verdict = ("Verdict: the requirements table judges both, the model's rows and the measured plant's "
               "(measured_*, the same required values): a requirement counts as met only where both are. The "
               "measured rows rest on the points of good coherence alone; a figure that rests on a poor point "
               "leaves its row without a verdict.")
    mode_notes = [n for n in d.notes if n.startswith(("measured anti-resonance", "measured resonance",
                                                      "the measured response shows"))]
    spans = m.intervals()
    margins = table(("figure", "model", "measured plant", "95 % interval"),
                    [(name + (f" [{unit}]" if unit else ""), _cell(a, unit), _cell(b, unit),
                      "" if spans.get(name) is None else f"{fmt(spans[name][0], 4)} .. {fmt(spans[name][1], 4)} {unit}")
                     for name, unit, a, b in m.side_by_side()], table_id="measured-margins-table")
    bands = table(("band [Hz]", "points", "poor coherence", "mean |gain| [dB]", "max |gain| [dB]",
                   "mean |phase| [deg]", "max |phase| [deg]"),
                  [(f"{fmt(lo)} .. {fmt(hi)}", str(n), str(bad), *(_cell(v, "") for v in (mdb, xdb, mdeg, xdeg)))
                   for lo, hi, n, bad, mdb, xdb, mdeg, xdeg in m.bands], table_id="measured-mismatch-table")
    crossings = "<ul>" + "".join(f"<li>{esc(c.text())}</li>" for c in (*m.gain_crossings, *m.phase_crossings)) \
        + "</ul>"
    notes = "".join(f"<p>Note: {esc(n)}</p>" for n in (*mode_notes, *m.notes()))
    html = (para(intro, verdict) + "<h3>Margins: model and measured plant</h3>" + margins
            + para("Model: python-control's margins of the continuous loop. Measured plant: crossings interpolated "
                   "between the measured points, each below with the two points bracketing it. The 95 % interval "
                   "is the H1 estimate's random error, from the coherence and the number of spectra averaged, "
                   "carried to the margins (see the notes); a file without that number gets none.") + crossings
            + "<h3>The model against the measurement, per band</h3>"
            + para("The model's response over the measured one (points of good coherence): the mean and largest "
                   "gain difference in dB and phase difference in deg.") + bands + notes)
    stable = m.stable
    status = "fail" if stable is False else "info"
    return Section("The loop on the measured plant", html,
                   (FigureSpec(_bode(m), "Bode plots of the plant response and of the open loop: the model's "
                                         "(line) and the measured (dots), points of poor coherence circled, the "
                                         "measured loop's crossings dotted."),),
                   status=status, key="measured")
