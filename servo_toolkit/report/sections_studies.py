"""Sections on the studies: nonlinear sweep, Kv, reduction, solver accuracy."""

from __future__ import annotations

import numpy as np

from ..core.output_units import REQUIREMENT_SINE_HZ, OutputUnit
from . import figures
from .references import EQUIVALENT_ELEMENT, FROZEN_SCHEME, REFERENCES
from .section import FigureSpec, NotApplicable, Section, esc, fmt, para, table


LIGHT_SWEEP_POINTS = 8


def sweep_settings(ctx):
    """``(study name, frequencies_hz, amplitudes_rad, options)`` of the report's sweep.

    Full settings: the scene's sweep study as it stands (see
    :func:`servo_toolkit.studies.sweep.compute.study_points`). Light settings: at most
    :data:`LIGHT_SWEEP_POINTS` log-spaced frequencies over the study's range plus 8 Hz and
    the frequencies where the designed loop peaks (:func:`peak_frequencies`), and a shorter
    dwell (3 settling and 2 estimation cycles).
    """
    from ..studies.sweep.compute import study_points
    name, freqs, amps = study_points(ctx.scene)
    freqs = np.asarray(freqs, dtype=float)
    options = {}
    if ctx.light:
        from ..studies.sine_dwell import DwellPlan as plan_cls
        lo, hi = freqs.min(), freqs.max()
        if freqs.size > LIGHT_SWEEP_POINTS:
            light = np.geomspace(lo, hi, LIGHT_SWEEP_POINTS)
            freqs = np.unique(np.concatenate([light, freqs[np.abs(freqs - REQUIREMENT_SINE_HZ) < 1e-9],
                                              peak_frequencies(ctx.design(), lo, hi)]))
        options["plan"] = plan_cls(settling_cycles=3, estimation_cycles=2, min_settling_time=0.2)
    options["frequencies"] = freqs
    return name, freqs, tuple(amps), options


def peak_frequencies(design, lo: float, hi: float) -> np.ndarray:
    """Frequencies (Hz) in [lo, hi] where the designed closed loop |T| has a local peak (the
    drivetrain mode shows as one) and where |S| peaks, each with a point a sixth of an
    octave either side, so that a light grid resolves them."""
    import control as ct
    f = np.geomspace(lo, hi, 2000)
    lw = np.asarray(ct.frequency_response(design.loop, 2 * np.pi * f).complex).reshape(-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        t, s = np.abs(lw / (1 + lw)), np.abs(1 / (1 + lw))
    inner = np.nonzero((t[1:-1] > t[:-2]) & (t[1:-1] >= t[2:]))[0] + 1
    peaks = [f[k] for k in inner[np.argsort(t[inner])[::-1][:2]]] + [f[int(np.nanargmax(s))]]
    out = (np.asarray(peaks)[:, None] * 2.0 ** (np.array([-1, 0, 1]) / 6.0)).ravel()
    return np.unique(np.clip(out, lo, hi))


def reduced_sweep(ctx):
    """The report's sweep (reduced model, as :func:`servo_toolkit.studies.sweep.compute.sweep` runs
    it by default), computed once and shared by the sweep and reduction sections."""
    from ..studies.sweep.compute import sweep as run_sweep
    controller = ctx.design().controller
    name, _, _, options = sweep_settings(ctx)
    return ctx.result("sweep", lambda: run_sweep(ctx.scene, name, controller=controller, executor=ctx.executor,
                                                 progress=False, **options))


def sweep(ctx) -> Section:
    """Nonlinear sine-dwell sweep against the linear closed loop."""
    from ..studies.sweep.kind import SWEEP
    ctx.require_drivetrain("the frequency sweep")
    res = reduced_sweep(ctx)
    fig, axes = figures.new_figure(2, 1, size=(7.5, 5.4), sharex=True)
    res.plot(axes=axes)
    u = res.unit
    head = (f"amplitude [{u.shown}]", "frequency [Hz]", "gain [dB]", "phase [deg]", "linear gain [dB]",
            "linear phase [deg]", "flags")
    rows = []
    g, p, lg, lp = res.gain_db, res.phase_deg, res.linear_gain_db, res.linear_phase_deg
    for a, amp in enumerate(res.amplitudes_rad):
        for k, f in enumerate(res.frequencies_hz):
            err = res.errors[a * res.frequencies_hz.size + k]
            flags = ("saturated " if res.saturated[a, k] else "") + (f"failed: {err}" if err else "")
            rows.append((fmt(u.show(amp)), fmt(f), fmt(g[a, k]), fmt(p[a, k]), fmt(lg[k]), fmt(lp[k]),
                         flags.strip()))
    dg = np.abs(g - lg[None, :])
    dp = np.abs(p - lp[None, :])
    lin = ~res.saturated

    def worst(a, mask):
        return (f"{np.nanmax(dg[a][mask[a]]):.2f} dB and {np.nanmax(dp[a][mask[a]]):.1f} deg"
                if np.any(mask[a] & np.isfinite(dg[a])) else "no point")
    settings = (f"light settings: {res.frequencies_hz.size} frequencies and short dwells (report --full runs "
                "the study as defined)" if ctx.light else "the study as defined")
    text = [f"Sine dwell at each frequency (settling cycles, then estimation cycles; amplitude and phase of the "
            f"fundamental by correlation), compared with the linear closed loop. Study: {res.study or 'default'}; "
            f"{settings}.",
            "Largest difference from the linear loop where no limit was reached: " + ", ".join(
                f"{u.text(amp, 3)} amplitude: {worst(a, lin)}" for a, amp in enumerate(res.amplitudes_rad))
            + "."]
    if res.saturated.any():
        text.append("At the points flagged saturated the current or voltage limit was reached and the loop is no "
                    "longer linear: " + ", ".join(f"{u.text(amp, 3)} amplitude: {worst(a, ~lin)}"
                                                 for a, amp in enumerate(res.amplitudes_rad)) + ".")
    if res.reduced:
        names = [item.split(": ", 1)[0] for item in res.left_out]
        text.append("The sweep ran the reduced model (see 'What the model leaves out'); left out: "
                    + (", ".join(names) or "nothing") + ".")
    text += list(getattr(res, "notes", ()))
    return Section(SWEEP.section_title, para(*text) + table(head, rows),
                   (FigureSpec(fig, "Closed-loop Bode: linear loop (line) and nonlinear sine dwell (markers)."),),
                   key=SWEEP.section_key)


def _cell(value, digits: int = 4) -> str:
    """A table cell of a figure the chain may not have (no screw, no rod): ``-`` for None,
    as ``servo-toolkit kv`` prints it."""
    return "-" if value is None else fmt(value, digits)


def kv_tables(ctx) -> Section:
    """Kv tables of the scene's kv studies (the equivalent-element method, Ref. [1]): inverse
    dynamics along the motion."""
    ctx.require_drivetrain("the Kv study")
    from ..studies.kv.kind import KV
    from ..studies.run import run_study
    studies = ctx.scene.studies_of_kind(KV.name)
    if not studies:
        raise NotApplicable(f"the scene defines no [studies.NAME] of kind \"{KV.name}\"")
    results = [run_study(ctx.scene, s.name, samples_per_period=400 if ctx.light else 2000,
                         executor=ctx.executor, progress=False) for s in studies]
    parts = [para("Kv, the dynamic-load factor: the peak load of a motion with the external inertia over the "
                  f"peak of the same motion at zero external inertia, as defined in {REFERENCES[0].cite}, from "
                  f"inverse dynamics with the reflected mass matrix and Jacobians of the {EQUIVALENT_ELEMENT}.")]
    figs = []
    for res in results:
        u, shown = res.unit, ctx.scene.display
        head = (f"amplitude [{u.shown}]", "frequency [Hz]",
                f"load {'mass' if u.linear else 'inertia'} [{shown.inertia_unit(u.linear)}]",
                "peak motor torque [N*m]", "Kv motor", "peak screw thrust [N]", "Kv screw", "peak rod force [N]",
                "Kv rod")
        rows = [(fmt(u.show(c.amplitude)), fmt(c.frequency), fmt(shown.show("inertia", c.load_inertia, u.linear)),
                 fmt(c.peak_motor_torque),
                 fmt(c.kv_motor, 3), _cell(c.peak_screw_thrust), _cell(c.kv_screw, 3), _cell(c.peak_rod_force),
                 _cell(c.kv_rod, 3)) for c in res.cases]
        parts.append(f"<h3>{esc(res.study)}: {esc(res.motion)}</h3>")
        parts.append(para(f"Amplitudes at the {res.amplitude_at}; stage losses: {res.losses}.", *res.notes))
        parts.append(table(head, rows, cls=KV.section_key))
        fig, ax = figures.new_figure(size=(6.5, 3.4))
        res.plot(ax=ax)
        figs.append(FigureSpec(fig, f"Kv against the external inertia, study {res.study}."))
    return Section(KV.section_title, "".join(parts), tuple(figs), key=KV.section_key)


#: the fixed-step methods of the accuracy study by name (the solver's keys ``rk4``, ``paper``)
METHOD_NAMES = {"rk4": "RK4 (classical fixed step)", "paper": f"frozen-configuration scheme ({REFERENCES[2].cite})"}


def accuracy(ctx) -> Section:
    """Solver error against run time: RK4 and the frozen-configuration scheme (Ref. [3]) at a ladder of steps
    against the tight-tolerance reference, with the observed order of convergence."""
    ctx.require_drivetrain("the solver accuracy study")
    from ..studies.accuracy import accuracy_study
    from ..sim import build_model
    from ..studies.time.reference import run_spec
    controller = ctx.design().controller
    model = build_model(ctx.scene, controller)
    duration = 0.05 if ctx.light else 0.2
    command = run_spec(ctx.scene)[0]  # servo-toolkit accuracy's default: 2 deg, or 1 mm for a travel, at 8 Hz
    res = accuracy_study(model, command, duration, progress=False)
    u = OutputUnit(res.output_unit)
    rows = [(METHOD_NAMES.get(r["method"], r["method"]), "adaptive" if r["dt_s"] is None else fmt(r["dt_s"]),
             fmt(r["wall_s"] * 1e3), fmt(r["error"], 3)) for r in res.runs]
    fig, (a1, a2) = figures.new_figure(1, 2, size=(10.0, 3.6))
    res.plot(ax=a1)
    for line in a1.lines:  # the methods by their names, not the solver's keys
        line.set_label(METHOD_NAMES.get(line.get_label(), line.get_label()))
    a1.legend()
    a1.set_title("Error against run time")
    a1.grid(True, which="both", alpha=0.3)
    for method, marker in (("rk4", "o-"), ("paper", "s--")):
        rs = [r for r in res.runs if r["method"] == method and r["dt_s"]]
        if rs:
            a2.loglog([r["dt_s"] for r in rs], [max(r["error"], 1e-16) for r in rs], marker,
                      label=METHOD_NAMES[method])
    rk = [r for r in res.runs if r["method"] == "rk4" and r["dt_s"]]
    if rk and rk[0]["error"] > 0:
        dts = [r["dt_s"] for r in rk]
        a2.loglog(dts, [rk[0]["error"] * (d / dts[0]) ** 4 for d in dts], color="0.5", ls="-.", lw=0.8,
                  label="slope 4")
    a2.set(xlabel="step dt [s]", ylabel="max error / amplitude", title="Convergence")
    a2.grid(True, which="both", alpha=0.3)
    a2.legend(fontsize="small")
    text = para(f"{res.description}.",
                f"Observed order of convergence: {res.order_text()}. Against the reference, the order is fitted "
                "over the steps whose errors are above the reference's own accuracy (4 on a smooth run; less when "
                "the run has non-smooth events); self-convergence compares successive halvings of the step and "
                f"needs no reference. Against the reference the {FROZEN_SCHEME}'s error levels "
                f"off at the difference between its play operator ({REFERENCES[2].cite}, eqs 6-8) and the "
                "elasto-backlash law of the reference model, not at a step-size error.",
                f"Error is the largest difference of the output {'travel' if u.linear else 'angle'} from the "
                f"reference, over the motion amplitude of {u.text(res.amplitude_rad, 3)} (an error of 1e-6 is "
                f"{fmt(u.show(1e-6 * res.amplitude_rad), 3)} {u.shown}); each wall time is the best of {res.repeats} identical runs.")
    return Section("Solver accuracy", text + table(("method", "dt [s]", "wall [ms]", "error / amplitude"), rows),
                   (FigureSpec(fig, "Error of the fixed-step methods against run time and step."),), key="accuracy")
