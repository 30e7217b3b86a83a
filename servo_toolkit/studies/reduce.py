"""Leave out what a study does not need: the reduced model, why, and its measured error.

:func:`reduce` judges every modelled effect against a study's frequencies and amplitudes
(:func:`.reduce_estimates.plan_reduction`: numbers, a-priori error estimates, the choice),
then runs the study on the full and on the reduced model and measures their difference:

- a ``frequency_sweep`` study: the sine-dwell responses of both models (:func:`.sweep.sweep`),
  difference ``|H_reduced / H_full - 1|`` per point;
- a ``kv`` or ``simulate`` study with a sine motion: the output-angle traces of both models
  over the steady part of the run, difference ``RMS(q_reduced - q_full) / RMS(q_full - q0)``
  (for a sinusoid the same measure as above, plus any harmonics).

The a-priori bound is the reduction's tolerance (module :mod:`.reduce_estimates` explains
why it holds in the linear range); points where a run reached the current or voltage limit
are outside that statement and are reported separately.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from ..errors import SceneError, SimulationError
from ..core.output_units import OutputUnit, output_unit
from ..core.parallel import run_cases
from ..plant.linear import DEFAULT_STRUCTURAL_DAMPING
from .reduce_estimates import DEFAULT_TOLERANCE, ReductionPlan, plan_reduction
from .sine_dwell import DwellPlan
from .sweep import linear_response, study_points, sweep
from ..display.cards import RichDisplay
from ..display.cards import card, facts, num, svg, table

TIME_KINDS = ("kv", "simulate")


@dataclass(frozen=True, repr=False)
class ReductionResult(RichDisplay):
    """What a study's reduced model leaves out, and how much that changes the study.

    Attributes
    ----------
    scene : str
    study : str or None
    measure : str
        ``"sweep"`` (sine-dwell responses) or ``"trace"`` (time-trace RMS).
    plan : ReductionPlan
        Effects, estimates, the reduced options and the tolerance (the a-priori bound).
    frequencies_hz : numpy.ndarray
    amplitudes_rad : numpy.ndarray
        Command amplitudes in SI (rad, or m for an output travel; see ``output_unit``).
    difference : numpy.ndarray
        (n_a, n_f) measured relative difference full/reduced (NaN: a run failed in both).
    saturated : numpy.ndarray
        (n_a, n_f) bool: a limit was reached in either run (outside the linear statement).
    full_options, reduced_options : dict
    notes : tuple of str
    output_unit : {"rad", "m"}
        Unit of the output coordinate; amplitudes are shown in deg or mm after it.
    """

    scene: str
    study: str | None
    measure: str
    plan: ReductionPlan
    frequencies_hz: np.ndarray
    amplitudes_rad: np.ndarray
    difference: np.ndarray
    saturated: np.ndarray
    full_options: dict
    reduced_options: dict
    notes: tuple = field(default_factory=tuple)
    output_unit: str = "rad"

    @property
    def bound(self) -> float:
        """The a-priori bound on the relative difference (the tolerance)."""
        return self.plan.tolerance

    @property
    def measured(self) -> float:
        """Largest measured relative difference over the points within the limits."""
        ok = ~self.saturated & ~np.isnan(self.difference)
        return float(np.max(self.difference[ok])) if ok.any() else math.nan

    @property
    def measured_saturated(self) -> float:
        """Largest measured relative difference over the points that reached a limit."""
        sat = self.saturated & ~np.isnan(self.difference)
        return float(np.max(self.difference[sat])) if sat.any() else math.nan

    @property
    def bound_applies(self) -> bool:
        """True when at least one point stayed within the current and voltage limits (and ran
        on both models): the a-priori bound is a statement about the linear range only."""
        return bool(np.any(~self.saturated & ~np.isnan(self.difference)))

    @property
    def within_bound(self) -> bool | None:
        """Measured difference (within the limits) <= the a-priori bound; None (not
        applicable) when no point stayed within the limits."""
        if not self.bound_applies:
            return None
        return bool(self.measured <= self.bound)

    @property
    def verdict(self) -> str:
        """``"within"``, ``"NOT within"`` or ``"not applicable"`` (no point within the limits)."""
        return {True: "within", False: "NOT within", None: "not applicable"}[self.within_bound]

    def to_dict(self) -> dict:
        """JSON-ready."""
        def db(e):
            return 20 * math.log10(1 + e) if math.isfinite(e) else e

        def deg(e):
            return math.degrees(math.asin(min(e, 1.0))) if math.isfinite(e) else e
        u = OutputUnit(self.output_unit)
        return {"scene": self.scene, "study": self.study, "measure": self.measure,
                **self.plan.to_dict(),
                "bound_relative": self.bound, "measured_relative": self.measured,
                "measured_dB": db(self.measured), "measured_deg": deg(self.measured),
                "measured_saturated_relative": self.measured_saturated,
                "within_bound": self.within_bound, "bound_applies": self.bound_applies,
                "points": [{"frequency_hz": float(f), u.key("amplitude"): float(u.show(a)),
                            "difference_relative": float(self.difference[i, k]),
                            "saturated": bool(self.saturated[i, k])}
                           for i, a in enumerate(self.amplitudes_rad) for k, f in enumerate(self.frequencies_hz)],
                "full_options": self.full_options, "reduced_options": self.reduced_options,
                "notes": list(self.notes)}

    def table(self) -> str:
        """Plain-text report: effects, estimates, choice, bound and measured difference."""
        p = self.plan
        lines = [f"Reduction of {self.scene} for study {self.study or '(default sweep)'}: "
                 f"{self.frequencies_hz.size} frequencies {self.frequencies_hz[0]:.3g}..{self.frequencies_hz[-1]:.3g} Hz, "
                 f"amplitudes {', '.join(OutputUnit(self.output_unit).text(a, 3) for a in self.amplitudes_rad)}",
                 f"{'effect':34s} {'estimate':>9} {'[dB]':>7} {'[deg]':>6}  decision",
                 "-" * 96]
        for e in p.effects:
            lines.append(f"{e.effect[:34]:34s} {e.estimate:9.2e} {_db(e.estimate):7.3f} {_deg(e.estimate):6.2f}  "
                         f"{e.reason or ('left out' if e.omitted else 'kept')}")
            lines.append(f"{'':34s}   {e.quantity}")
        lines.append("-" * 96)
        left = [e.effect for e in p.omitted]
        lines.append("left out: " + (", ".join(left) if left else "nothing"))
        lines.append(f"a-priori: sum of estimates of the omissions {p.predicted:.2e}; bound (tolerance) "
                     f"{self.bound:.2e} = {_db(self.bound):.3f} dB / {_deg(self.bound):.2f} deg")
        what = "sine-dwell response" if self.measure == "sweep" else "output-angle RMS"
        if self.bound_applies:
            lines.append(f"measured ({what}, full vs reduced): {self.measured:.2e} = {_db(self.measured):.3f} dB / "
                         f"{_deg(self.measured):.2f} deg -> {self.verdict} the bound")
        else:
            sat = self.measured_saturated
            lines.append(f"measured ({what}, full vs reduced): no point stayed within the current and voltage "
                         f"limits, so the linear bound does not apply (not applicable); difference at the "
                         f"saturated points {sat:.2e} = {_db(sat):.3f} dB / {_deg(sat):.2f} deg")
        if np.any(self.saturated) and self.bound_applies:
            lines.append(f"points that reached a limit (outside the linear statement): largest difference "
                         f"{self.measured_saturated:.2e}")
        lines += [f"note: {n}" for n in p.notes + self.notes]
        return "\n".join(lines)

    def plot(self, ax=None):
        """Measured relative difference per point, with the bound and the a-priori sum."""
        import matplotlib.pyplot as plt
        if ax is None:
            _, ax = plt.subplots(figsize=(7, 3.5))
        for i, a in enumerate(self.amplitudes_rad):
            d = np.where(np.isnan(self.difference[i]), np.nan, np.maximum(self.difference[i], 1e-12))
            line, = ax.loglog(self.frequencies_hz, d, "o-", ms=4, label=f"measured, {OutputUnit(self.output_unit).text(a, 3)}")
            sat = self.saturated[i]
            if sat.any():
                ax.loglog(self.frequencies_hz[sat], d[sat], "o", mfc="none", ms=8, color=line.get_color(),
                          label="reached a limit")
        ax.axhline(self.bound, color="r", lw=1, label="a-priori bound")
        if self.plan.predicted > 0:
            ax.axhline(self.plan.predicted, color="k", ls="--", lw=1, label="sum of estimates")
        ax.set_xlabel("frequency [Hz]")
        ax.set_ylabel("|reduced / full - 1|")
        ax.set_title(f"{self.scene}: reduced model left out " +
                     (", ".join(e.effect for e in self.plan.omitted) or "nothing"), fontsize="small")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize="small")
        return ax

    def _repr_line(self) -> str:
        return _card_line(self)

    def _repr_card(self) -> str:
        return _card_html(self)


def _db(e):
    return 20 * math.log10(1 + e) if math.isfinite(e) else math.inf


def _deg(e):
    return math.degrees(math.asin(min(e, 1.0))) if math.isfinite(e) else math.inf


def time_points(study):
    """``(frequencies_hz, amplitudes_rad)`` of a kv or simulate study with a sine motion."""
    p = study.params
    if "voltage" in p:
        raise SceneError(study.key("voltage"), "an open-loop study has no closed loop to reduce")
    if p.get("trajectory", "sine") != "sine":
        raise SceneError(study.key("trajectory"), "only sine motions can be reduced")
    freq = p.get("frequency")
    if freq is None and p.get("period"):
        freq = 1.0 / p["period"]
    amps = p.get("amplitudes") or ([p["amplitude"]] if p.get("amplitude") is not None else None)
    if freq is None or not amps:
        raise SceneError(study.key("kind"), "needs a frequency (or period) and amplitude(s)")
    return np.array([float(freq)]), tuple(float(a) for a in amps)


def _trace_case(case):
    """One closed-loop sine run; returns times, output angle and whether a limit was reached
    in the compared window (``t >= t_settle``, as the sweep flags its dwell window) and
    before it (the start-up transient: the command starts with its full slope)."""
    from ..sim import Reference, run
    model, amp, freq, duration, limits, t_settle = case
    try:
        # RK4 with the step it needs: shrunk where a mode stiffens along the run (an end stop)
        res = run(model, Reference.sine(amp, freq), duration, "auto")
    except SimulationError as exc:
        return {"error": str(exc)}
    hit = ((np.abs(res.current_reference) >= limits[0] * (1 - 1e-9))
           | (np.abs(res.motor_voltage) >= limits[1] * (1 - 1e-9)))
    window = res.times >= t_settle
    return {"t": res.times, "q": res.output_angle - model.q0, "saturated": bool(np.any(hit[window])),
            "startup_saturated": bool(np.any(hit[~window])), "error": None}


def _trace_difference(full, red, t_settle):
    if full["error"] or red["error"]:
        return (math.nan if full["error"] and red["error"] else math.inf), True
    keep = full["t"] >= t_settle
    q_red = np.interp(full["t"][keep], red["t"], red["q"])
    q_full = full["q"][keep]
    ref = np.sqrt(np.mean((q_full - q_full.mean()) ** 2))
    return float(np.sqrt(np.mean((q_red - q_full) ** 2)) / ref), full["saturated"] or red["saturated"]


def reduce(scene, study=None, *, tolerance: float = DEFAULT_TOLERANCE, controller=None, plan=None,
           executor=None, progress: bool = True, frequencies=None, amplitudes=None) -> ReductionResult:
    """Reduce the scene's model for a study and measure the reduction on that study.

    Parameters
    ----------
    scene : Scene
    study : str or Study, optional
        A ``frequency_sweep``, ``kv`` or ``simulate`` (sine) study; default the scene's sweep
        plus 8 Hz (see :func:`.sweep.study_points`).
    tolerance : float
        A-priori bound on the relative response difference between full and reduced model.
    controller : CascadeController, optional
        Default: the designed loop.
    plan : DwellPlan, optional
        Settling and estimation cycles.
    executor : concurrent.futures.Executor, optional
    progress : bool
    frequencies : sequence of float, optional
        Hz, replacing a sweep study's frequencies (8 Hz is then not added).
    amplitudes : sequence of float, optional
        Command amplitudes (rad, or m for an output travel), replacing the study's.

    Returns
    -------
    ReductionResult
    """
    from ..sim import ModelOptions, build_model, controller_for

    notes = []
    if controller is None:
        controller, source = controller_for(scene)
        notes.append(f"controller from {source}")
    if isinstance(study, str):
        study = scene.study(study)
    if study is None or study.kind == "frequency_sweep":
        name, freqs, amps = _sweep_points(scene, study, frequencies)
        freqs, measure = np.asarray(freqs), "sweep"
    elif study.kind in TIME_KINDS:
        if frequencies is not None:
            raise SceneError(study.key("kind"), f"is {study.kind!r}; frequencies replace a frequency_sweep "
                             "study's only (a time study's motion sets its frequency)")
        name = study.name
        freqs, amps = time_points(study)
        measure = "trace"
    else:
        raise SceneError(study.key("kind"), f"is {study.kind!r}; reduce handles frequency_sweep, kv and "
                         "simulate studies")
    if amplitudes is not None:
        amps = tuple(float(a) for a in np.atleast_1d(amplitudes))
        if not amps or not all(math.isfinite(a) and a > 0 for a in amps):
            raise ValueError("amplitudes must be non-empty, positive and finite")
    stop = "stop" if measure == "trace" else "error"
    full = ModelOptions(damping_ratio=DEFAULT_STRUCTURAL_DAMPING, stroke_end=stop, chain="full", friction="stick")
    rplan = plan_reduction(scene, controller, freqs, amps, base=full, tolerance=tolerance)
    reduced = rplan.options
    dwell = plan or DwellPlan()
    if measure == "sweep":
        kw = dict(frequencies=freqs, amplitudes=amps, controller=controller, plan=dwell, executor=executor,
                  progress=progress)
        s_full = sweep(scene, name, options=full, **kw)
        s_red = sweep(scene, name, options=reduced, **kw)
        with np.errstate(invalid="ignore"):
            diff = np.abs(s_red.response / s_full.response - 1.0)
        failed_one = np.isnan(s_full.response) ^ np.isnan(s_red.response)
        diff[failed_one] = math.inf
        sat = s_full.saturated | s_red.saturated | failed_one
        if np.isnan(diff).any():
            notes.append(f"{int(np.isnan(diff).sum())} point(s) failed on both models (e.g. "
                         f"{next(e for e in s_full.errors if e)}); not compared")
    else:
        notes.append("time runs with an elastic stroke-end stop on both models")
        _, decay = linear_response(scene, controller, freqs, full.damping_ratio)
        f = float(freqs[0])
        settle, est = dwell.cycles(f, decay)
        limits = (scene.motor.current_limit, scene.motor.voltage_limit)
        runs = {}
        for key, opts in (("full", full), ("reduced", reduced)):
            model = build_model(scene, controller, opts)
            runs[key] = run_cases(_trace_case, [(model, a, f, (settle + est) / f, limits, settle / f) for a in amps],
                                  executor=executor, progress=progress, description=f"{key} model")
        pairs = [_trace_difference(a, b, settle / f) for a, b in zip(runs["full"], runs["reduced"])]
        diff = np.array([[d] for d, _ in pairs])
        sat = np.array([[s] for _, s in pairs])
        notes.append(f"compared over t >= {settle / f:.3g} s of {(settle + est) / f:.3g} s "
                     f"(settling: {dwell.settling_time_constants:g} time constants of the slowest loop mode); "
                     "a point counts as saturated when a limit was reached in that window")
        early = [output_unit(scene).text(a, 3) for a, r_f, r_r in zip(amps, runs["full"], runs["reduced"])
                 if r_f.get("startup_saturated") or r_r.get("startup_saturated")]
        if early:
            notes.append(f"the start-up transient (the sine command starts with its full slope) reached a limit "
                         f"before the compared window at {', '.join(early)}; it has "
                         "decayed by then")
    return ReductionResult(scene=scene.name, study=name, measure=measure, plan=rplan, frequencies_hz=freqs,
                           amplitudes_rad=np.asarray(amps, dtype=float), difference=diff, saturated=sat,
                           full_options=dict(full.__dict__), reduced_options=dict(reduced.__dict__),
                           notes=tuple(notes),
                           output_unit=output_unit(scene).si)


def _sweep_points(scene, study, frequencies):
    """:func:`.sweep.study_points`, with ``frequencies`` (Hz) replacing the study's."""
    name, freqs, amps = study_points(scene, study)
    if frequencies is not None:
        freqs = tuple(sorted(float(f) for f in np.atleast_1d(frequencies)))
        if not freqs or not all(math.isfinite(f) and f > 0 for f in freqs):
            raise ValueError("frequencies must be non-empty, positive and finite")
    return name, freqs, amps


def reduced_options(scene, study=None, *, tolerance: float = DEFAULT_TOLERANCE, controller=None,
                    frequencies=None, amplitudes=None):
    """Only the a-priori part: ``(ModelOptions, ReductionPlan)`` for a study (no runs).

    A time simulation can adopt the reduction with
    ``simulate(scene, options=reduced_options(scene, name)[0], ...)``.
    """
    from ..sim import ModelOptions, controller_for
    if controller is None:
        controller, _ = controller_for(scene)
    if isinstance(study, str):
        study = scene.study(study)
    if study is None or study.kind == "frequency_sweep":
        _, freqs, amps = _sweep_points(scene, study, frequencies)
    else:
        freqs, amps = time_points(study)
    if amplitudes is not None:
        amps = tuple(float(a) for a in np.atleast_1d(amplitudes))
    rplan = plan_reduction(scene, controller, freqs, amps,
                           base=ModelOptions(damping_ratio=DEFAULT_STRUCTURAL_DAMPING, chain="full",
                                             friction="stick"),
                           tolerance=tolerance)
    return replace(rplan.options), rplan


def _card_line(r) -> str:
    """The one-line repr of a result of this module."""
    left = ", ".join(e.effect for e in r.plan.omitted) or "nothing"
    return f"{r.scene}: left out {left}; measured {num(r.measured, 3)} vs bound {num(r.bound, 3)} ({r.verdict})"


def _card_html(r) -> str:
    """The Jupyter card (HTML) of a result of this module."""
    rows = [(e.effect, num(e.estimate, 3), "left out" if e.omitted else "kept", e.reason) for e in r.plan.effects]
    parts = [table(("effect", "estimate (relative)", "decision", "why"), rows),
             facts((("a-priori bound", num(r.bound, 3)), ("measured difference", num(r.measured, 3)),
                    ("verdict", r.verdict))),
             svg(lambda ax: r.plot(ax), size=(7.0, 3.4))]
    return card(f"Reduction of {r.scene}", status=r.within_bound if r.within_bound is not None else None,
                parts=parts, notes=r.notes)
