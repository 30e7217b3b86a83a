"""The reduced model a study allows: which effects to leave out, and the model options that
leave out one effect or several (:mod:`.estimates` judges them).

The reduced model leaves out effects, smallest estimate first, while the sum of their
estimates stays within half the tolerance; the drivetrain chain's modes above the first follow
``simulate``'s own rule (:func:`servo_toolkit.sim.chain_choice.choose_chain`). Limits reached
in the linear prediction keep the electrical path (inductance).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ...core.output_units import OutputUnit
from ...display.cards import RichDisplay, card, num, svg, table
from .friction import without_stick

#: switches that leave out a part of the compliance, all left out with the whole of it
_WITH_COMPLIANCE = ("backlash", "stiffness_scale", "chain")


def _db(e):
    return 20 * math.log10(1 + e) if math.isfinite(e) else math.inf


def _deg(e):
    return math.degrees(math.asin(min(e, 1.0))) if math.isfinite(e) else math.inf


@dataclass(frozen=True)
class Effect:
    """One effect of the model judged against a study.

    Attributes
    ----------
    effect : str
        What it is (``"armature inductance"``, ``"compliance of <stage>"``, ...).
    switch : str or None
        The :class:`~servo_toolkit.sim.ModelOptions` field leaving it out (None: no switch).
    quantity : str
        The numbers compared, in words.
    estimate : float
        A-priori relative response error if left out (see the module docstring).
    omitted : bool
    reason : str
    share : float
        A stage's compliance share (``switch == "stiffness_scale"``): leaving it out raises the
        series stiffness by 1 / (1 - share).
    parts : tuple
        The parts of an effect judged node by node (the friction's
        :class:`~.friction.FrictionNode`, each with its own estimate; the effect's
        estimate is their sum).
    """

    effect: str
    switch: str | None
    quantity: str
    estimate: float
    omitted: bool = False
    reason: str = ""
    share: float = 0.0
    parts: tuple = ()

    def to_dict(self) -> dict:
        """JSON-ready."""
        out = {"effect": self.effect, "switch": self.switch, "quantity": self.quantity,
               "estimate_relative": self.estimate, "estimate_dB": _db(self.estimate),
               "estimate_deg": _deg(self.estimate), "left_out": self.omitted, "reason": self.reason}
        if self.parts:
            out["parts"] = [x.to_dict() for x in self.parts]
        return out

    def details(self, indent: str) -> list:
        """The text lines under the effect's row: the quantity compared, then each part's
        worst case."""
        return [f"{indent}{self.quantity}"] + [f"{indent}  {x.label}: {x.where}" for x in self.parts]


@dataclass(frozen=True, repr=False)
class ReductionPlan(RichDisplay):
    """The a-priori part of a reduction: effects, the reduced options and the bound.

    Attributes
    ----------
    effects : tuple of Effect
    options : ModelOptions
        The reduced model's options.
    tolerance : float
        A-priori bound on the relative full/reduced response difference.
    predicted : float
        Sum of the estimates of the effects left out (<= tolerance / 2).
    frequencies_hz : numpy.ndarray
    amplitudes_rad : tuple
        Command amplitudes in SI (rad, or m for an output travel; see ``output_unit``).
    notes : tuple of str
    output_unit : {"rad", "m"}
    chain_choice : ChainChoice or None
        Whether the drivetrain chain's modes above the first are kept
        (:func:`servo_toolkit.sim.chain_choice.choose_chain`); None for a chain with one mode.
    kept : tuple of (str, str)
        ``(effect, why)`` of each effect kept whatever its estimate (a study varying a
        parameter that acts on it: :func:`~.estimates.plan_reduction`'s ``stiffness``).
    """

    effects: tuple
    options: object
    tolerance: float
    predicted: float
    frequencies_hz: np.ndarray
    amplitudes_rad: tuple
    notes: tuple = ()
    output_unit: str = "rad"
    chain_choice: object = None
    kept: tuple = ()

    @property
    def omitted(self) -> tuple:
        """The effects left out."""
        return tuple(e for e in self.effects if e.omitted)

    def on(self, base) -> "ReductionPlan":
        """The same choice on another full model: ``base`` (ModelOptions) with the effects
        this plan leaves out left out. The estimates read the full model's damping, chain and
        friction, not its stroke end: a plan judged once serves a run whose full model stops
        at the stroke end where the plan's raised an error."""
        return replace(self, options=chosen_options(base, self.effects))

    def to_dict(self) -> dict:
        """JSON-ready."""
        out = {"effects": [e.to_dict() for e in self.effects],
               "left_out": [e.effect for e in self.omitted],
               "tolerance_relative": self.tolerance, "tolerance_dB": _db(self.tolerance),
               "tolerance_deg": _deg(self.tolerance), "predicted_relative": self.predicted,
               "frequencies_hz": self.frequencies_hz.tolist(),
               OutputUnit(self.output_unit).key("amplitudes"):
                   [float(OutputUnit(self.output_unit).show(a)) for a in self.amplitudes_rad],
               "notes": list(self.notes)}
        if self.kept:
            out["kept_whatever_the_estimate"] = [{"effect": e, "why": why} for e, why in self.kept]
        return out

    def plot(self, ax=None):
        """Each effect's a-priori estimate (relative response error if left out), left out or
        kept, against the budget of the effects left out (half the tolerance) and the
        tolerance; an estimate of 0 is drawn at the axis' foot."""
        if ax is None:
            import matplotlib.pyplot as plt
            _, ax = plt.subplots(figsize=(7.0, 0.8 + 0.35 * len(self.effects)))
        est = np.array([e.estimate for e in self.effects], dtype=float)
        finite = est[np.isfinite(est) & (est > 0)]
        foot = min(float(finite.min()) if finite.size else self.tolerance, self.tolerance) / 10
        shown = np.where(np.isfinite(est) & (est > 0), est, foot)
        y = np.arange(len(self.effects))[::-1]
        ax.barh(y, shown - foot, left=foot, color=["C0" if e.omitted else "C7" for e in self.effects])
        ax.set_xscale("log")
        ax.set_yticks(y, [f"{e.effect} ({'left out' if e.omitted else 'kept'})" for e in self.effects],
                      fontsize="small")
        ax.axvline(self.tolerance / 2, color="k", ls="--", lw=1, label="budget of the effects left out")
        ax.axvline(self.tolerance, color="r", lw=1, label="tolerance")
        ax.set_xlabel("a-priori estimate |reduced / full - 1|")
        ax.set_title(f"Reduction at {self.frequencies_hz[0]:.3g}-{self.frequencies_hz[-1]:.3g} Hz: left out "
                     f"{num(self.predicted, 3)} of {num(self.tolerance / 2, 3)}", fontsize="small")
        ax.legend(fontsize="small")
        return ax

    def _repr_line(self) -> str:
        left = ", ".join(e.effect for e in self.omitted) or "nothing"
        return (f"{len(self.effects)} effects at {self.frequencies_hz[0]:.3g}-{self.frequencies_hz[-1]:.3g} Hz; "
                f"left out {left}: estimates {num(self.predicted, 3)} of the budget {num(self.tolerance / 2, 3)}")

    def _repr_card(self) -> str:
        rows = [(e.effect, num(e.estimate, 3), num(_db(e.estimate), 3), num(_deg(e.estimate), 3),
                 "left out" if e.omitted else "kept", e.reason) for e in self.effects]
        parts = [table(("effect", "estimate (relative)", "[dB]", "[deg]", "decision", "why"), rows),
                 svg(self.plot, size=(7.0, 0.8 + 0.35 * len(self.effects)))]
        return card(f"A-priori reduction (tolerance {num(self.tolerance, 3)})", parts=parts, notes=self.notes)


def options_without(base, effects):
    """``base`` (a :class:`~servo_toolkit.sim.ModelOptions`) with each of ``effects`` left out:
    its switch changed, and nothing else."""
    omitted = {e.switch for e in effects}
    opts = base
    if "chain" in omitted:
        opts = replace(opts, chain="two_mass")
    if "compliance" in omitted:
        opts = replace(opts, compliance=False)
    else:
        if "backlash" in omitted:
            opts = replace(opts, backlash=False)
        shares = [e.share for e in effects if e.switch == "stiffness_scale"]
        if shares:
            opts = replace(opts, stiffness_scale=opts.stiffness_scale / (1 - sum(shares)))
    if "inductance" in omitted:
        opts = replace(opts, inductance=False)
    if "variable_inertia" in omitted:
        opts = replace(opts, variable_inertia=False)
    if "friction" in omitted:
        opts = without_stick(opts)
    return opts


def chosen_options(base, effects):
    """``base`` (the full model's :class:`~servo_toolkit.sim.ModelOptions`) with the chosen
    ``effects`` (those marked omitted) left out; the chain's modes kept whole when the choice
    judged them and kept them."""
    opts = options_without(base, [e for e in effects if e.omitted])
    if opts.chain != "two_mass" and any(e.switch == "chain" for e in effects):
        opts = replace(opts, chain="full")  # kept: every mode, whatever "auto" would choose
    return opts


def choose(effects, rigid_effect, base, tol, limited, freqs, amps, notes, choice=None, keep=None) -> ReductionPlan:
    """The effects to leave out (module docstring) and the reduced model's options.

    Parameters
    ----------
    effects : list of Effect
    rigid_effect : Effect or None
        The whole drivetrain compliance (left out together with its backlash).
    base : ModelOptions
        The full model's.
    tol : float
    limited : bool
        The linear loop reaches a limit: the inductance is kept.
    freqs, amps, notes
        For the plan.
    choice : ChainChoice, optional
        ``simulate``'s rule for the chain's modes above the first.
    keep : dict, optional
        Switch -> why the study needs it (``{"compliance": "..."}``): effects with these
        switches (``"chain"``: the chain's modes above the first) are kept whatever their
        estimate, e.g. by a study that varies a parameter acting on them.
    """
    keep = keep or {}
    budget = tol / 2
    used = 0.0
    chosen = set()
    modes = [e for e in effects if e.switch == "chain"]
    if modes and choice is not None and choice.chain == "two_mass" and "chain" not in keep:
        chosen.add(modes[0].effect)  # simulate's rule lumps them
        used += modes[0].estimate
    by_switch = [e for e in effects if e.switch is not None and e.switch != "chain"]
    backlash = [e for e in by_switch if e.switch == "backlash"]
    if rigid_effect is not None and rigid_effect.switch not in keep:
        bl = backlash[0].estimate if backlash else 0.0
        if rigid_effect.estimate + bl <= budget:
            chosen.add(rigid_effect.effect)
            used += rigid_effect.estimate + bl
    for e in sorted(by_switch, key=lambda x: x.estimate):
        if rigid_effect is not None and rigid_effect.effect in chosen and e.switch in _WITH_COMPLIANCE:
            continue
        if (e.switch == "inductance" and limited) or e.switch in keep:
            continue
        if used + e.estimate <= budget:
            chosen.add(e.effect)
            used += e.estimate
    out = []
    for e in effects + ([rigid_effect] if rigid_effect is not None else []):
        if e.switch is None:
            out.append(e)
        elif e.effect in chosen:
            why = (f"simulate's rule: {choice.note}" if e.switch == "chain" else
                   f"{e.estimate:.2g} within the budget (sum of omissions <= {budget:.2g})")
            out.append(replace(e, omitted=True, reason=f"left out: {why}"))
        elif rigid_effect is not None and rigid_effect.effect in chosen and e.switch in _WITH_COMPLIANCE:
            out.append(replace(e, omitted=True, reason="left out with the whole compliance"))
        elif e.switch in keep:
            out.append(replace(e, reason=f"kept: {keep[e.switch]}"))
        elif e.switch == "inductance" and limited:
            out.append(replace(e, reason="kept: limits reached, where the inductive voltage matters"))
        elif e.switch == "chain":
            out.append(replace(e, reason="kept: " + choice.note))
        else:
            out.append(replace(e, reason=f"kept: {e.estimate:.2g} exceeds the remaining budget "
                                         f"{max(budget - used, 0):.2g}"))
    kept = tuple((e.effect, keep[e.switch]) for e in out if e.switch in keep)
    return ReductionPlan(effects=tuple(out), options=chosen_options(base, out), tolerance=tol, predicted=used,
                         frequencies_hz=freqs, amplitudes_rad=amps, notes=tuple(notes), chain_choice=choice,
                         kept=kept)


__all__ = ["Effect", "ReductionPlan", "choose", "chosen_options", "options_without"]
