"""A time simulation as a study: the reduced model by default, saying what it left out.

The closed-loop sine runs of ``servo-toolkit simulate`` (the default 8 Hz sine and the
scene's ``simulate`` / ``kv`` sine studies) are judged by
:func:`~.reduce_estimates.plan_reduction` at their frequency and amplitude, as sweeps are,
and run the reduced model unless the full one is asked for. Open-loop voltage runs and
explicit ``ModelOptions`` run as given.
"""

from __future__ import annotations

from dataclasses import replace

from ...core.output_units import output_unit
from ...errors import SceneError, SimulationError
from ...sim import ModelOptions, build_model, controller_for, simulate
from ...sim.model_slots import FRICTION_CHOICES
from ...sim.simulate import with_feedforward
from .reference import run_spec


def simulate_study(scene, study: str | None = None, *, method: str | None = None, dt: float | None = None,
                   full: bool = False, amplitude: float | None = None, frequency: float | None = None,
                   feedforward=None, shaper=None, schedule=None, friction: str | None = None,
                   controller=None, controller_source: str | None = None, spec=None):
    """Run a scene's time-simulation study (default: the 8 Hz, 2 deg sine for 1 s).

    Parameters
    ----------
    scene : Scene
    study : str or Study, optional
        A ``[studies.NAME]`` with a sine (``simulate`` or ``kv`` kind) or a ``voltage``.
    method : {"rk4", "paper", "reference", "auto"}, optional
        Default: the study's ``method``, else ``"auto"`` (``"rk4"`` when ``dt`` is given).
    dt : float, optional
        Fixed step (s) of the fixed-step methods; default the study's ``sample_time`` for
        them. See :func:`resolve_method`.
    full : bool
        Run the full model; by default a closed-loop sine runs the reduced model.
    amplitude, frequency : float, optional
        Replace the sine command's amplitude (rad, or m for an output travel) and
        frequency (Hz).
    feedforward : Feedforward or {"off", "gains", "model"}, optional
        The controller's feedforward (:func:`servo_toolkit.sim.simulate.with_feedforward`);
        None: the designed controller's (none).
    shaper : InputShaper or {"off", "zv", "zvd"}, optional
        Command shaper on the sine (None: none).
    schedule : bool or GainSchedule, optional
        Gains scheduled along the stroke (None: none).
    friction : {"stick", "smooth", "off"}, optional
        The friction model (``ModelOptions.friction``); None: chosen by need, friction that
        holds unless the reduction's estimate allows the smooth model
        (:func:`sine_run_options`); an open-loop voltage run holds (``"stick"``).
    controller : CascadeController, optional
        The loop's controller, designed once by the caller; default the designed loop
        (:func:`servo_toolkit.sim.controller_for`). An open-loop voltage run takes none.
    controller_source : str, optional
        Where a given ``controller`` came from, noted as ``controller from SOURCE``
        (default ``"given"``).
    spec : tuple, optional
        The run resolved once by the caller, :func:`resolve_run`'s
        ``(reference, duration, voltage, method, dt)``: ``study``, ``method``, ``dt``,
        ``amplitude`` and ``frequency`` are then not read again.

    Returns
    -------
    SimulationResult
        Its ``notes`` say which model ran and, for the reduced one, what it left out and
        the a-priori bound on what that costs.
    """
    if spec is None:
        study = getattr(study, "name", study)  # a Study or its name
        spec = resolve_run(scene, study, method=method, dt=dt, amplitude=amplitude, frequency=frequency)
    reference, duration, voltage, method, dt = spec
    if voltage is not None:
        return simulate(scene, None, duration=duration, method=method, dt=dt, voltage=voltage,
                        feedforward=feedforward, shaper=shaper, schedule=schedule,
                        options=ModelOptions(friction="stick" if friction is None else check_friction(friction)))
    if controller is None:
        controller, source = controller_for(scene)
    else:
        source = controller_source or "given"
    controller = with_feedforward(controller, feedforward, scene, shaper=shaper, schedule=schedule)
    options, notes = sine_run_options(scene, controller, reference, full, friction=friction)
    notes.insert(0, f"controller from {source}")
    result = simulate(scene, controller, reference=reference, duration=duration, method=method, dt=dt,
                      options=options)
    return replace(result, notes=tuple(notes) + tuple(result.notes))


def resolve_run(scene, study: str | None = None, *, method: str | None = None, dt: float | None = None,
                amplitude: float | None = None, frequency: float | None = None, key: str = "dt"):
    """The run a time study takes, resolved once: ``(reference, duration, voltage, method, dt)``,
    :func:`~.reference.run_spec` with its method and step from :func:`resolve_method`.

    Raises
    ------
    SceneError
        As :func:`~.reference.run_spec` and :func:`resolve_method` (the step's error
        named ``key``).
    """
    reference, duration, voltage, study_method, study_dt = run_spec(scene, study, amplitude=amplitude,
                                                                    frequency=frequency)
    method, dt = resolve_method(method, study_method, dt, study_dt, key=key)
    return reference, duration, voltage, method, dt


def resolve_method(method, study_method, dt, study_dt, key: str = "dt"):
    """The method and step a run takes: ``(method, dt)``.

    A step given without a method (neither ``method`` nor the study's) runs fixed-step RK4
    at that step; the fixed-step methods (``"rk4"``, ``"paper"``) without a step take the
    study's ``sample_time``.

    Raises
    ------
    SceneError
        Named ``key``: a step given with a method that chooses its own (``"auto"``,
        ``"reference"``), where it would be ignored.
    """
    if dt is not None and method is None and study_method is None:
        return "rk4", dt
    method = method or study_method or "auto"
    if dt is not None and method not in ("rk4", "paper"):
        raise SceneError(key, f"applies to the fixed-step methods rk4 and paper; method {method!r} chooses its "
                              f"own step and would ignore it (got {dt:g} s)")
    if dt is None and method in ("rk4", "paper"):
        dt = study_dt
    return method, dt


def check_friction(friction: str) -> str:
    """``friction`` when it names a friction model (``ModelOptions.friction``), else a
    SceneError naming the option."""
    if friction not in FRICTION_CHOICES:
        raise SceneError("friction", f"must be one of {', '.join(FRICTION_CHOICES)} (got {friction!r})")
    return friction


def sine_run_options(scene, controller, reference, full: bool = False, friction: str | None = None,
                     stiffness=None):
    """Model options of a closed-loop sine run: the reduced model for its frequency and
    amplitude (:func:`~.reduce_estimates.plan_reduction`), or the full one. Both start from
    friction that holds (``"stick"``) at every node; the reduction smooths it (the smooth
    model) only where its node-by-node estimate (:mod:`.reduce_friction`) is within the budget.
    A ``friction`` model given (``"stick"``, ``"smooth"``, ``"off"``) is kept in either: the
    reduction judges the other effects. ``stiffness``, the smallest and largest factor on the
    series stiffness a study varies, keeps in the reduced model what the factor acts on
    (:func:`~.reduce_estimates.plan_reduction`), and a note says so.

    Returns
    -------
    options : ModelOptions
    notes : list of str
        Which model, and for the reduced one what it left out and the a-priori bound, the
        friction at each node (held, smoothed or left out, with its estimate), and the choice
        of the chain's modes (``options.chain_note``: the model does not note it again).
    """
    from ...plant.linear import DEFAULT_STRUCTURAL_DAMPING
    from ..model_setup import model_setup
    from ..reduce.estimates import FRICTION_EFFECT
    from ..reduce.friction import friction_note

    options = ModelOptions(damping_ratio=DEFAULT_STRUCTURAL_DAMPING, friction="stick")
    chosen = [] if friction is None else [f"friction model {check_friction(friction)} (as asked)"]
    if full:
        options = replace(options, chain="full", friction=friction or options.friction)
        return options, ["full model (every modelled effect kept, every drivetrain mode, friction that holds)"] + chosen
    plan = model_setup(scene, controller, [reference.frequency], [abs(reference.amplitude)], base=options,
                       build=False, stiffness=stiffness).plan
    left = [f"{e.effect} (estimate {e.estimate:.2g})" for e in plan.omitted]
    amp = abs(reference.amplitude)
    size = output_unit(scene).text(amp, 3)
    notes = [f"reduced model for {reference.frequency:g} Hz, {size}: left out {', '.join(left) or 'nothing'}; "
             f"a-priori bound {plan.tolerance:g} on the relative response (servo-toolkit reduce SCENE for "
             "the reasoning, --full for the full model)"]
    estimate = {e.effect: e.estimate for e in plan.effects}
    notes += [f"{effect} kept whatever its estimate ({estimate[effect]:.2g} at the nominal parameters): {why}"
              for effect, why in plan.kept]
    fric = next((e for e in plan.effects if e.effect == FRICTION_EFFECT), None)
    if fric is not None and friction is None:
        notes.append(friction_note(fric.parts, fric.omitted))
    options = plan.options
    if plan.chain_choice is not None and options.compliance and options.chain == plan.chain_choice.chain:
        # simulate's rule (unless the modes are kept for a varied stiffness: noted above), with
        # the steps and the cost; the model built on it carries the choice
        notes.append(plan.chain_choice.note)
        options = replace(options, chain_note=plan.chain_choice.note)
    if friction is not None:
        return replace(options, friction=friction), notes + chosen
    return options, notes


#: the start of sine_run_options' note on the chain's modes kept for a varied stiffness
MODES_KEPT = "drivetrain modes above the first kept whatever its estimate"


def lumped_if_reshaped_at(scene, controller, options, notes, ends: dict, why_form: str):
    """``(options, notes)`` at ``ends`` (label -> the scene at a varied key's end):
    the chain's modes kept for a varied stiffness (the note :data:`MODES_KEPT`) are lumped
    again when the full chain built at one of them changes form (``why_form`` says how, in
    words) or does not build; the note then says that the softest variants carry the
    lumping's cost. A Monte Carlo over the load inertia and a tolerance study over scene keys
    call it at the ends of what they vary."""
    i = next((j for j, n in enumerate(notes) if n.startswith(MODES_KEPT)), None)
    if i is None or not ends or options.chain != "full":
        return options, notes
    nominal = build_model(scene, controller, options)
    for label, end in ends.items():
        try:
            m = build_model(end, controller, options)
        except (SceneError, SimulationError):
            m = None
        if m is None or m.P.size != nominal.P.size or m.T.shape != nominal.T.shape:
            why = notes[i][notes[i].index(": ") + 2:]
            note = (f"drivetrain modes above the first lumped into the two-mass reduction although {why}: the full "
                    f"chain changes form at {label} ({why_form}), so the softest variants carry that cost")
            return replace(options, chain="two_mass", chain_note=note), [*notes[:i], note, *notes[i + 1:]]
    return options, notes
