"""From a study's controller to the model it runs: the reduction for its frequencies and
amplitudes, the model options, the model and its notes, in one place.

A sine dwell sweep (:mod:`.sweep`), a multisine (:mod:`.multisine`) and a closed-loop sine
run (:mod:`.time.run`) all take the controller they are given, judge the scene's effects
against their frequencies and amplitudes once (:func:`.reduce.estimates.plan_reduction`)
unless the full model or explicit options are asked for, and build the model on the result.
The full model holds friction (``friction="stick"``): the reduction smooths it only where
its estimate is within the budget, so what a study says it left out is what its runs left
out (:attr:`ModelSetup.left_out`, also for options given).
"""

from __future__ import annotations

from dataclasses import dataclass

from ..plant.linear import DEFAULT_STRUCTURAL_DAMPING


@dataclass(frozen=True)
class ModelSetup:
    """A study's model, with how it was chosen.

    Parameters
    ----------
    options : ModelOptions
        What the model keeps.
    plan : ReductionPlan or None
        The reduction judged for the study (None: the full model or options given).
    model : Model or None
        The model built on ``options`` (None when not asked for).
    notes : tuple of str
        Where the controller came from, the reduction, the model's own notes and the
        friction's cost (see :func:`model_setup`).
    """

    options: object
    plan: object
    model: object
    notes: tuple
    given_left_out: tuple = ()

    @property
    def reduced(self) -> bool:
        """True when the reduction chose the options."""
        return self.plan is not None

    @property
    def left_out(self) -> tuple:
        """``"effect: reason"`` of every effect the runs leave out: the reduction's choice, or
        for options given what they switch off against the full model (friction without
        stick with its estimate and verdict)."""
        if self.plan is None:
            return self.given_left_out
        return tuple(f"{o.effect}: {o.reason}" for o in self.plan.omitted)

    def to_dict(self) -> dict:
        """JSON-ready summary: the options, what was left out and the notes."""
        return {"options": dict(self.options.__dict__), "reduced": self.reduced, "left_out": list(self.left_out),
                "notes": list(self.notes)}


def model_setup(scene, controller, frequencies_hz, amplitudes, *, options=None, full: bool = False, base=None,
                source: str | None = None, build: bool = True, stiffness=None) -> ModelSetup:
    """The model a study at ``frequencies_hz`` and ``amplitudes`` runs with ``controller``.

    Parameters
    ----------
    scene : Scene
    controller : CascadeController
    frequencies_hz : sequence of float
    amplitudes : sequence of float
        Command amplitudes (rad, or m for an output travel).
    options : ModelOptions, optional
        Run exactly these (no reduction).
    full : bool
        The full model (``base``) instead of the reduced one.
    base : ModelOptions, optional
        The full model's options; default the structural damping of the linear loop.
    source : str, optional
        Where the controller came from: noted first as ``controller from SOURCE``.
    build : bool
        Build the model and note its notes and the friction's cost (a sine dwell's
        notes); False: only choose the options (``model`` None, no notes beyond the source).
    stiffness : (float, float), optional
        The factors on the series stiffness a study varies: the reduction keeps what they
        act on (:func:`.reduce.estimates.plan_reduction`).

    Returns
    -------
    ModelSetup
    """
    from ..sim import ModelOptions, build_model
    from .reduce.estimates import FRICTION_EFFECT, friction_cost_note, plan_reduction
    from .reduce.friction import friction_note

    notes = [] if source is None else [f"controller from {source}"]
    plan = None
    given = options is not None
    if options is None:
        options = base or ModelOptions(damping_ratio=DEFAULT_STRUCTURAL_DAMPING, friction="stick")
        if not full:
            plan = plan_reduction(scene, controller, frequencies_hz, amplitudes, base=options,
                                  stiffness=stiffness)
            options = plan.options
            if build:
                notes.append("reduced model (use full=True / --full for the full model)")
    model = None
    cost = None
    if build or given:
        cost = friction_cost_note(scene, controller, frequencies_hz, amplitudes, options)
    if build:
        model = build_model(scene, controller, options)
        notes += list(model.notes)
        if cost:
            notes.append(cost)
        fric = None if plan is None else next((e for e in plan.effects if e.effect == FRICTION_EFFECT), None)
        if fric is not None and not fric.omitted:  # left out, the cost's note says what it left
            notes.append(friction_note(fric.parts, False))
    return ModelSetup(options=options, plan=plan, model=model, notes=tuple(notes),
                      given_left_out=given_left_out(options, cost) if given else ())


#: switches of ModelOptions that leave out an effect when False, with the effect's name
_SWITCHED = (("inductance", "armature inductance"), ("compliance", "drivetrain compliance"),
             ("backlash", "backlash"), ("variable_inertia", "inertia variation"),
             ("efficiency", "drivetrain efficiency"))


def given_left_out(options, friction_cost: str | None = None) -> tuple:
    """``"effect: reason"`` of what model options given to a study leave out against the full
    model: each effect switched off, and friction without stick (``friction_cost``: its
    estimate and verdict, :func:`.reduce.estimates.friction_cost_note`)."""
    out = [f"{name}: switched off (options as given)" for key, name in _SWITCHED if not getattr(options, key)]
    if options.chain == "two_mass":
        out.append("drivetrain modes above the first: the two-mass reduction (options as given)")
    if options.friction != "stick":
        out.append(f"friction that holds (stick): friction model {options.friction!r} (options as given)"
                   + (f"; {friction_cost}" if friction_cost else ""))
    return tuple(out)


def model_line(reduced: bool, left_out, options: dict) -> str:
    """The first line under a study's title: the model its runs ran and what they left out
    (``reduced`` and ``left_out`` of :class:`ModelSetup`, ``options`` its options as a dict)."""
    if reduced:
        return "model: " + ("reduced, left out: " + "; ".join(left_out) if left_out else "reduced: nothing left out")
    if left_out:
        return "model: options as given, left out: " + "; ".join(left_out)
    held = " (friction that holds)" if options.get("friction") == "stick" else ""
    return f"model: full model{held}"


__all__ = ["ModelSetup", "given_left_out", "model_line", "model_setup"]
