"""From a study's controller to the model it runs: the reduction for its frequencies and
amplitudes, the model options, the model and its notes, in one place.

A sine dwell sweep (:mod:`.sweep`), a multisine (:mod:`.multisine`) and a closed-loop sine
run (:mod:`.time.run`) all take the controller they are given, judge the scene's effects
against their frequencies and amplitudes once (:func:`.reduce.estimates.plan_reduction`)
unless the full model or explicit options are asked for, and build the model on the result.
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

    @property
    def reduced(self) -> bool:
        """True when the reduction chose the options."""
        return self.plan is not None

    @property
    def left_out(self) -> tuple:
        """``"effect: reason"`` of every effect the reduction left out."""
        return () if self.plan is None else tuple(f"{o.effect}: {o.reason}" for o in self.plan.omitted)

    def to_dict(self) -> dict:
        """JSON-ready summary: the options, what was left out and the notes."""
        return {"options": dict(self.options.__dict__), "reduced": self.reduced, "left_out": list(self.left_out),
                "notes": list(self.notes)}


def model_setup(scene, controller, frequencies_hz, amplitudes, *, options=None, full: bool = False, base=None,
                source: str | None = None, build: bool = True) -> ModelSetup:
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

    Returns
    -------
    ModelSetup
    """
    from ..sim import ModelOptions, build_model
    from .reduce.estimates import friction_cost_note, plan_reduction

    notes = [] if source is None else [f"controller from {source}"]
    plan = None
    if options is None:
        options = base or ModelOptions(damping_ratio=DEFAULT_STRUCTURAL_DAMPING)
        if not full:
            plan = plan_reduction(scene, controller, frequencies_hz, amplitudes, base=options)
            options = plan.options
            if build:
                notes.append("reduced model (use full=True / --full for the full model)")
    model = None
    if build:
        model = build_model(scene, controller, options)
        notes += list(model.notes)
        cost = friction_cost_note(scene, controller, frequencies_hz, amplitudes, options)
        if cost:
            notes.append(cost)
    return ModelSetup(options=options, plan=plan, model=model, notes=tuple(notes))


__all__ = ["ModelSetup", "model_setup"]
