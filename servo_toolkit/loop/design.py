"""Loop shaping: choose controller gains to meet a scene's requirements.

The nominal search (:mod:`.nominal_search`) evaluates candidate controllers on a frequency
grid with the closed-form plant responses (:mod:`.response`) at a few points of the stroke
(:mod:`.stroke_design`: q0, the ends, the inertia and drivetrain-mode extremes), ranks them
by their smallest normalized slack against the requirements (margins at their worst over the
points, bandwidth and phase lag at q0), and confirms the best with the closed-loop poles at
every point; here a second round adds the first's worst points of the stroke check, and a
robust design goes to :mod:`.robust_design`. The reported figures of the chosen design are
python-control's (:func:`evaluate`, :func:`.margins.loop_margins`).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import replace

import numpy as np

from ..core.output_units import REQUIREMENT_SINE_HZ
from ..lti.system import as_system
from ..scene.argument import as_scene
from ..plant.current_loop import current_loop_gains
from ..plant.linear import DEFAULT_STRUCTURAL_DAMPING, friction_note, plant_block, plant_parameters
from .actuator_bounds import bounded
from .chain_margins import chain_margins
from .closed_loop import closed_loop_block, open_loop_block
from .margins import frequency_grid, loop_margins
from .measured_mode import stiffened
from .nominal_search import _best, _delay_response, _filters
from .requirements import check, requirements_of, unstable_checks
from .result import DesignResult
from .stroke import STROKE_POINTS, operating_point, plant_scan, show_q, stroke_check
from .stroke_design import design_points, missed_points, result_slack
from .structures import FILTERS, STRUCTURES


def design(scene, q0=None, *, structure: str = "cascade", resonance_filter: str = "auto",
           current_bandwidth_hz: float = 1000.0, structural_damping: float = DEFAULT_STRUCTURAL_DAMPING,
           model: str = "auto", require=None, phase_hz: float = REQUIREMENT_SINE_HZ, robust=None,
           progress: bool = True, over_stroke: bool = True, executor=None,
           current_ripple: float | None = None, measured_mode=None) -> DesignResult:
    """Design the position loop of a scene at the operating point ``q0``.

    A nominal design maximizes the smallest slack against the requirements on the nominal
    plant. A robust design (``robust``; by default whenever the scene has ``[robustness]``)
    also holds every parameter variant of the ranges stable with the margins required over
    them: see :mod:`servo_toolkit.loop.robust_design` for the physics (the load inertia
    moves the drivetrain mode, so a notch on the nominal mode is defeated) and the search.

    Parameters
    ----------
    scene : Scene or path-like
        A path is read with :func:`~servo_toolkit.scene.load_scene`.
    q0 : float or pint.Quantity, optional
        Operating point (rad, or m for an output travel; a Quantity is converted). Default: mid-stroke, or, when the motor-side reflected
        inertia varies along the stroke by more than 1.5x, where it is largest (see
        :func:`servo_toolkit.loop.stroke.operating_point`; the notes say so). Whatever the
        operating point, the loop is then checked along the stroke (``result.stroke``, the
        ``stable_over_stroke`` requirement).
    structure : {"cascade", "pid", "lead_lag", "pi"}
        ``cascade`` = current -> speed PI -> position P, the usual EMA structure.
    resonance_filter : {"auto", "none", "notch", "lowpass"}
        Filter on the position path for the drivetrain resonance; ``auto`` tries all three
        and keeps the best (a rigid plant gets none).
    current_bandwidth_hz : float
        Bandwidth of the analog current PI (pole-cancelling tuning).
    structural_damping : float
        Damping ratio assumed for the drivetrain mode.
    model : {"auto", "two_mass", "rigid"}
    require : dict, optional
        Requirement overrides, name -> value in display units (Hz, deg, dB).
    phase_hz : float
        Frequency of the reported closed-loop phase (Hz).
    robust : None, bool or Robustness
        ``None``: robust when the scene has ``[robustness]``; ``False``: nominal design;
        ``True``: robust over the scene's ``[robustness]`` or, when it has none, the default
        ranges (load inertia 0 .. 4 times the scene's, stiffness 0.7..1.3, 1000 Monte Carlo
        variants; :func:`~.robustness.default_variations`);
        a :class:`~servo_toolkit.scene.tables.Robustness`: robust over it.
    progress : bool
        Progress bars for the robust search.
    over_stroke : bool
        Nominal search: rank each candidate by its worst margins over a few stroke points
        (:func:`.stroke_design.design_points`; bandwidth and phase lag at q0) and try the
        resonance filters that cover the mode's walk along the stroke (default). ``False``
        designs on the plant at q0 alone (the check over the stroke still runs).
    executor : concurrent.futures.Executor, optional
        Runs the chunks of a robust design's check over the variants (e.g. a dask
        ``Client.get_executor()``); the result does not depend on it.
    current_ripple : float, optional
        Current ripple (A rms) the motor encoder's quantization and the play's limit cycle
        may each cost a nominal cascade (:mod:`.actuator_bounds`); default the scene's
        ``max_current_ripple``, else ``check``'s default for its ``current_ripple`` row (10 %
        of the continuous current, else 5 % of the current limit). Where the chosen
        speed-loop gain costs more, the search is redone with the gain lowered to what the
        allowance permits, and the notes say which bound held it and by how much.
    measured_mode : MeasuredMode, optional
        The drivetrain mode of a measured plant response (:mod:`.measured_mode`): with
        ``resonance_filter="auto"`` and the measured mode off the model's, the nominal search
        ranks its candidates with the model's mode moved to the measured frequency, so the
        notch lands on it; the notes give both frequencies in Hz. The margins reported stay
        the scene model's. A robust design does not use it (its note says so).

    Returns
    -------
    DesignResult
        With ``.robustness`` (worst cases over the variants) for a robust design. When no
        candidate meets everything the best one is returned and its notes say which
        requirement fails and by how much.
    """
    scene = as_scene(scene)
    spec = robust_spec(scene, robust)
    q0, op_note = operating_point(scene, q0)
    if spec is not None:
        r = _robust_design(scene, spec, q0=q0, structure=structure, current_bandwidth_hz=current_bandwidth_hz,
                           structural_damping=structural_damping, model=model, require=require,
                           phase_hz=phase_hz, progress=progress, resonance_filter=resonance_filter,
                           executor=executor)
        if measured_mode is not None:
            r = replace(r, notes=r.notes + (f"the measured resonance at {measured_mode.resonance_hz:.4g} Hz is not "
                                            "used by the robust design: its filter covers the variants' modes",))
        return r if op_note is None else replace(r, notes=(op_note,) + r.notes)
    if structure not in STRUCTURES:
        from ..errors import SceneError
        raise SceneError("structure", f"unknown loop structure {structure!r}; known: {STRUCTURES}")
    p = plant_parameters(scene, q0, model, structural_damping)
    reqs = requirements_of(scene, require)
    notes = [f"{r.name} {r.sense} {r.value:g} {r.unit}: default (the scene sets none)"
             for r in reqs if r.source == "default"] + ([op_note] if op_note else []) + list(friction_note(scene))
    sample_time = scene.sensors.sample_time
    if sample_time == 0:
        notes.append("continuous controller: the scene gives no sample time")
    kp_i, ki_i = current_loop_gains(scene.motor, current_bandwidth_hz) if p.L > 0 else (0.0, 0.0)
    if p.L == 0:
        notes.append("zero inductance: ideal current loop u = R i_ref + Ke omega_m")
    f_req = next(r.value for r in reqs if r.name == "bandwidth")
    if p.rigid:
        names = ("none",)
    elif resonance_filter == "auto":
        names = FILTERS
    else:
        names = (resonance_filter,)
    scan = plant_scan(scene, p.q0, STROKE_POINTS, model, structural_damping)  # searched over and checked
    if over_stroke:
        qd, stroke_params = design_points(scene, p.q0, model, structural_damping, scan=scan)
    else:
        qd, stroke_params = np.array([p.q0]), (p,)
    factor, search_p = None, p
    if measured_mode is not None:
        factor, mode_note = measured_mode.placement(p, resonance_filter)
        notes.append(mode_note)
        if factor is not None:  # the search's plants carry the measured mode; the figures stay the model's
            search_p, stroke_params = stiffened(p, factor), tuple(stiffened(x, factor) for x in stroke_params)

    def search(kv_cap):
        return _nominal(scene, search_p, reqs, structure, names, f_req, phase_hz, sample_time, (kp_i, ki_i),
                        qd, stroke_params, notes, model, structural_damping, over_stroke, kv_cap, scan, factor)

    return bounded(scene, search(math.inf), search, current_ripple, lambda s: _delay_response(s, sample_time))


def _nominal(scene, p, reqs, structure, names, f_req, phase_hz, sample_time, current_gains, qd, stroke_params,
             notes, model, structural_damping, over_stroke, kv_cap, scan=None, factor=None):
    """The nominal search over the stroke (a second round adds the first's worst points);
    ``scan``: the plants along the stroke (:func:`.stroke.plant_scan`) its check reads;
    ``factor``: the stiffness factor of the search's plants (a measured mode), None for 1."""
    unit = scene.drivetrain.output_unit
    best = None
    for round_ in range(2 if over_stroke else 1):
        filters = _filters(p, names, structural_damping, stroke_params)
        motion, ctrl, found = _best(scene, p, reqs, structure, filters, f_req, phase_hz, sample_time,
                                    current_gains, stroke_params, kv_cap)
        where = ([f"designed on {qd.size} stroke points, q = " + ", ".join(show_q(x, unit) for x in qd)
                  + " (q0, stroke ends, motor-side inertia and anti-resonance extremes"
                  + (", and the worst points of the first search's stroke check" if round_ else "")
                  + "): margins at their worst over them, bandwidth and phase lag at q0"] if over_stroke else [])
        r = evaluate(scene, ctrl, p.q0, reqs=reqs, notes=notes + found + where, motion=motion, model=model,
                     structural_damping=structural_damping, phase_hz=phase_hz, scan=scan)
        if best is None or result_slack(r) > result_slack(best):
            best = r
        extra = [x for x in missed_points(r) if np.min(np.abs(qd - x)) > 1e-9]
        if not extra:
            break
        qd = np.concatenate([qd, extra])
        added = (plant_parameters(scene, x, model, structural_damping) for x in extra)
        stroke_params = stroke_params + tuple(x if factor is None else stiffened(x, factor) for x in added)
    return best



def evaluate(scene, controller, q0=None, *, reqs=None, notes=(), motion=None, model="auto",
             structural_damping=DEFAULT_STRUCTURAL_DAMPING, phase_hz: float = REQUIREMENT_SINE_HZ, closed=None,
             require=None, stroke_points: int = STROKE_POINTS, scan=None) -> DesignResult:
    """Margins and requirement checks of a given controller on a scene (python-control).

    The margins are those at ``q0`` (default mid-stroke). With ``stroke_points`` (> 0) the
    same controller is also evaluated along the stroke (:func:`.stroke.stroke_check`):
    ``result.stroke`` holds the figures per operating point; the ``stable_over_stroke``
    requirement (closed loop stable at every point) and the worst-case margins over the
    stroke (``gain_margin_over_stroke``, ``phase_margin_over_stroke``,
    ``sensitivity_peak_over_stroke``, each with the required value of its point
    requirement) join the requirements, and the notes name the unstable points and each
    worst margin that misses, where and by how much. ``scan``: the plants along the stroke
    when the caller has them (:func:`.stroke.plant_scan`).
    """
    p = plant_parameters(scene, q0, model, structural_damping)
    reqs = requirements_of(scene, require) if reqs is None else reqs
    # a gain schedule's factors at q0 (1 at the design's own q0, up to the table's interpolation)
    at_q0 = controller if getattr(controller, "schedule", None) is None else controller.schedule.scaled(controller, p.q0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cl = as_system(closed) if closed is not None else closed_loop_block(scene, at_q0, p.q0, model,
                                                                             structural_damping)
        loop = open_loop_block(scene, at_q0, p.q0, model, structural_damping)
    cl_siso = cl["theta", "theta_ref"]
    f_req = next(r.value for r in reqs if r.name == "bandwidth")
    mg = loop_margins(loop, cl_siso, phase_hz=phase_hz,
                      omega=frequency_grid(extra=[phase_hz, f_req]))
    if mg.closed_loop_stable:
        lag_at = loop_margins(loop, cl_siso, phase_hz=f_req).phase_at_freq_deg if f_req != phase_hz \
            else mg.phase_at_freq_deg
        checks = check(reqs, {"bandwidth": mg.bandwidth_hz, "phase_lag_at_bandwidth": -lag_at,
                              "gain_margin": abs(mg.gain_margin_db), "phase_margin": mg.phase_margin_deg,
                              "sensitivity_peak": mg.sensitivity_peak_db})
    else:  # no margin, Ms or bandwidth: every row fails with the reason, no placeholder figure
        checks = unstable_checks(reqs, mg.unstable_reason)
    stroke = None
    if stroke_points:
        stroke = stroke_check(scene, controller, p.q0, points=stroke_points, model=model,
                              structural_damping=structural_damping, f_req=f_req, scan=scan)
        checks.append(stroke.requirement())
        checks += stroke.margin_requirements(reqs)
        notes = tuple(notes) + stroke.notes(reqs)
    g = plant_block(scene, p.q0, inductance=True, model=model, structural_damping=structural_damping)
    n_mass = None if p.rigid else chain_margins(scene, controller, p.q0, structural_damping, mg, phase_hz, f_req)
    if n_mass is not None and n_mass.note:
        notes = tuple(notes) + (n_mass.note,)
    return DesignResult(scene_name=scene.name, q0=p.q0, parameters=p, plant=g, controller=controller,
                        loop=loop, closed_loop=cl_siso, margins=mg, requirements=checks,
                        motion=motion, notes=tuple(notes), closed_loop_full=cl, stroke=stroke,
                        output_unit=scene.drivetrain.output_unit, display=scene.display, chain_margins=n_mass)


def robust_spec(scene, robust):
    """The :class:`~servo_toolkit.scene.tables.Robustness` a design must meet, or None (nominal)."""
    from ..scene.loader import Robustness
    if robust is None:
        return scene.robustness
    if robust is False:
        return None
    if robust is True:
        if scene.robustness is not None:
            return scene.robustness
        from .robustness import default_variations
        ranges = default_variations(scene)
        return Robustness(load_inertia=ranges.get("load_inertia"), stiffness=ranges["stiffness"])
    if isinstance(robust, Robustness):
        return robust
    from ..errors import SceneError
    raise SceneError("robust", f"expected None, True, False or a Robustness, got {type(robust).__name__}")


def _robust_design(scene, spec, *, q0, structure, current_bandwidth_hz, structural_damping, model, require,
                   phase_hz, progress, resonance_filter, executor=None):
    """Robust design (cascade search), or a nominal design evaluated over the variants."""
    from .robust_design import confirm_worst_case, robust_search
    from .robustness import robustness
    from .sampling import variant_count_text
    from .vary import ranges_text
    rng = ranges_text({k: (lo, hi) for k, (lo, hi) in spec.ranges.items()}, scene.display,
                      scene.drivetrain.output_is_linear)
    count = variant_count_text(spec.ranges, spec.samples, spec.method == "grid")
    header = f"robust design over {rng} ({count} at q0)"
    if structure != "cascade" or resonance_filter != "auto":
        r = design(scene, q0, structure=structure, resonance_filter=resonance_filter,
                   current_bandwidth_hz=current_bandwidth_hz, structural_damping=structural_damping, model=model,
                   require=require, phase_hz=phase_hz, robust=False)
        rb = robustness(scene, r, spec=spec, progress=progress, structural_damping=structural_damping,
                        executor=executor)
        notes = (f"{header}: the robust search covers the cascade with its own filter choice; this "
                 f"{structure} design (filter {resonance_filter}) is nominal, only evaluated over the variants",)
        r = replace(r, robustness=rb, notes=r.notes + notes)
        return replace(r, notes=r.notes + _failure_notes(r))
    p = plant_parameters(scene, q0, model, structural_damping)
    reqs = requirements_of(scene, require)
    notes = [f"{r.name} {r.sense} {r.value:g} {r.unit}: default (the scene sets none)"
             for r in reqs if r.source == "default"] + list(friction_note(scene))
    sample_time = scene.sensors.sample_time
    kp_i, ki_i = current_loop_gains(scene.motor, current_bandwidth_hz) if p.L > 0 else (0.0, 0.0)

    def evaluate_design(ctrl, motion):
        return evaluate(scene, ctrl, p.q0, reqs=reqs, notes=notes, motion=motion, model=model,
                        structural_damping=structural_damping, phase_hz=phase_hz)

    result, _ = robust_search(scene, p, spec, reqs, (kp_i, ki_i), sample_time, structural_damping,
                              evaluate_design=evaluate_design, progress=progress, executor=executor)
    notes = (header + "; priority: every variant stable, then margins, then bandwidth",
             confirm_worst_case(scene, result, structural_damping))
    result = replace(result, notes=result.notes + notes)
    return replace(result, notes=result.notes + _failure_notes(result))


def _failure_notes(result) -> tuple:
    """One note per failing requirement, with the figures (never hidden); when none fails,
    a robust design's note says which rows it met (its linear loop's, nominal, and its
    robustness rows over the variants), never every requirement: the large-signal, nonlinear
    time and sizing rows are judged after it."""
    out = []
    for c in result.requirements:
        if c.reason:
            out.append(f"the design misses {c.name}: {c.reason}")
        elif not c.passed:
            out.append(f"the design misses {c.name}: achieved {c.achieved:.4g} {c.unit}, required {c.sense} "
                       f"{c.required:g} {c.unit}, short by {c.shortfall:.3g} {c.unit}")
    rb = result.robustness
    for c in ([] if rb is None else rb.failures):
        at = ", ".join(f"{k}={v:.3g}" for k, v in rb.worst.get(c.name, {}).items())
        out.append(f"the design misses worst-case {c.name}: achieved {c.achieved:.4g} {c.unit}, required "
                   f"{c.sense} {c.required:g} {c.unit}, short by {c.shortfall:.3g} {c.unit} (at {at})")
    if not out and rb is not None:  # only the rows judged here: check's rows are judged apart
        out.append(f"the design's {len(result.requirements)} linear-loop requirements met, nominal, and its "
                   f"{len(rb.requirements)} robustness requirements over all {rb.count} variants (the "
                   f"large-signal, nonlinear time and sizing rows are judged apart)")
    return tuple(out)
