"""The result of the tolerance study: the yield of every requirement with its confidence
interval, the ranking of the tolerances on each figure, and the worst corner run again."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...core.sensitivity import R2_LINEAR
from ...display.cards import RichDisplay, card, facts, svg, table
from ...display.html import fmt
from ...display.units import DisplayUnits

#: a ranking's method in words
METHODS = {"src": "standardized regression", "sobol": "Sobol total indices"}
#: the dimensionless units (shown without a unit)
_NO_UNIT = ("", "1", "dimensionless")
#: corners evaluated one by one up to this many (2**10); beyond, the regression's signs choose
MAX_CORNERS = 1024


def shown_unit(key: str, unit: str, display: DisplayUnits | None = None, linear: bool = False) -> tuple:
    """``(unit, factor)`` a tolerance's SI values are shown in: the scene's ``[display]`` unit
    for a stiffness, or an inertia (a mass at an output travel), in the output's SI unit (a
    motor's own rotor inertia stays in kg*m^2, as everywhere); else the SI ``unit`` itself
    (factor 1).

    Parameters
    ----------
    key : str
        The tolerance's key path.
    unit : str
        Its SI unit.
    display : DisplayUnits, optional
    linear : bool
        The scene's output is a travel.
    """
    import pint

    from ...core.units import UREG
    display = display or DisplayUnits()
    for quantity in ("stiffness", "inertia"):
        if getattr(display, quantity) is None or (quantity == "inertia" and key.startswith("motor.")):
            continue
        try:
            same = UREG.Unit(unit) == UREG.Unit(DisplayUnits().unit(quantity, linear))
        except (pint.errors.PintError, ValueError, TypeError):  # a unit pint does not read: shown as it is
            same = False
        if same:
            return display.unit(quantity, linear), display.factor(quantity, linear)
    return unit, 1.0


@dataclass(frozen=True)
class WorstCorner:
    """The corner of the tolerance box (every tolerance at an end) with the smallest margin
    to the requirements, run again on its own.

    Attributes
    ----------
    values : dict
        Key -> value (SI) at the corner (tolerances that enter no figure at their nominal
        value).
    score : float
        Its smallest relative margin to a requirement (negative: short; each shortfall
        divided by its limit), over :attr:`basis`; -inf for an unstable loop or a time run
        that failed by its physics (the stroke end reached).
    figure : str
        The requirement that margin belongs to (``"stable"`` for an unstable loop).
    corners : int
        Corners evaluated (all of them up to 2**10; else the one the regression's signs
        point to).
    figures : dict
        The vectorized study's figures at the corner.
    reference : dict
        python-control's ``stability_margins`` (its arithmetic, :mod:`servo_toolkit.lti`) of the
        corner's plant built exactly
        (``gain_margin_db``, ``phase_margin_deg``) and its closed-loop stability.
    simulation : SimulationResult or None
        The nonlinear closed-loop run of the corner's scene (``simulate``'s command).
    run_error : str
        Why the corner's run could not be carried out ("" when it was).
    basis : str
        What the corner is the worst in: ``"the linear figures"``, or ``"every requirement
        (margins and time runs)"`` when the study judges time requirements (every corner
        then runs in time, batched).
    time_figures : dict
        The corner's batched time run in its requirements' units (``tracking_error`` in deg
        or mm, ``peak_current`` in A; NaN when it failed by its physics, ``failed`` saying
        why); empty without time requirements.
    notes : tuple of str
    units : dict
        Key -> the SI unit of its value in :attr:`values`.
    total : int
        Corners of the tolerance box (2 ** the tolerances that enter a figure; 0: not
        known).
    """

    values: dict
    score: float
    figure: str
    corners: int
    figures: dict
    reference: dict = field(default_factory=dict)
    simulation: object = None
    run_error: str = ""
    basis: str = "the linear figures"
    time_figures: dict = field(default_factory=dict)
    notes: tuple = ()
    units: dict = field(default_factory=dict)
    total: int = 0

    def evaluated(self) -> str:
        """How many corners were evaluated, in words: ``16 corners evaluated``, or ``1 of
        4096 corners evaluated, the one the regression's signs point to (every corner up to
        1024)``."""
        n = f"{self.corners} corner{'' if self.corners == 1 else 's'}"
        if self.total > self.corners:
            return (f"{self.corners} of {self.total} corners evaluated, the one the regression's signs point to "
                    f"(every corner up to {MAX_CORNERS})")
        return f"{n} evaluated"

    def run_figures(self) -> dict | None:
        """The corner's time run as ``max_tracking_error`` (SI: rad or m) and
        ``peak_current`` (A); None without a run."""
        sim = self.simulation
        if sim is None:
            return None
        return {"max_tracking_error": float(np.max(np.abs(sim.output_angle - sim.reference_angle))),
                "peak_current": float(np.max(np.abs(sim.motor_current)))}

    def run_text(self) -> str:
        """The corner's time run in words with units, or why it could not run."""
        run = self.run_figures()
        if run is None:
            return f"its time run could not be carried out: {self.run_error}" if self.run_error else ""
        unit = self.simulation.unit
        return (f"its time run (simulate's command): tracking error {fmt(unit.show(run['max_tracking_error']), 4)} "
                f"{unit.shown}, "
                f"peak current {fmt(run['peak_current'], 4)} A")

    def verdict(self) -> str:
        """How the corner fails, e.g. ``phase_margin margin 12.5 %``, ``closed loop unstable (a
        pole at real part 13 1/s)`` or ``its time run fails by its physics (stroke end ...)``."""
        if np.isfinite(self.score):
            return f"{self.figure} margin {fmt(100 * self.score, 3)} %"
        if self.figure != "stable":
            return f"its time run fails by its physics ({self.time_figures.get('failed', self.figure)})"
        return "closed loop unstable" + (f" (a pole at real part {fmt(self.figures['max_pole_real'], 4)} 1/s)"
                                         if "max_pole_real" in self.figures else "")

    def to_dict(self) -> dict:
        """JSON-ready (the simulation as its two figures, SI)."""
        out = {"values": {k: float(v) for k, v in self.values.items()}, "score": self.score, "figure": self.figure,
               "units": dict(self.units),
               "basis": self.basis, "corners_evaluated": self.corners, "corners_total": self.total,
               "figures": {k: float(v) for k, v in self.figures.items()}, "reference": self.reference}
        if self.time_figures:
            out["time_figures"] = dict(self.time_figures)
        if self.run_figures() is not None:
            out["simulation"] = self.run_figures()
        if self.run_error:
            out["run_error"] = self.run_error
        return out


@dataclass(frozen=True, repr=False)
class ToleranceResult(RichDisplay):
    """Yield and sensitivity of a design over a scene's tolerances.

    Attributes
    ----------
    scene_name : str
    tolerances : Tolerances
    values : dict of numpy.ndarray
        Key -> values per variant (SI).
    figures : dict of numpy.ndarray
        The linear loop's figures per variant (:func:`servo_toolkit.loop.robustness.variant_figures`).
    runs : ToleranceRuns or None
        The nonlinear time runs (when a time requirement is set or asked for).
    requirements : tuple of Requirement
        What each variant must achieve (display units).
    passes : dict of numpy.ndarray
        Requirement name (and ``"all"``) -> bool per variant.
    yields : tuple of Yield
        Per requirement, then ``all`` (every requirement at once).
    sensitivities : tuple of Sensitivity
        Per figure of a requirement.
    worst : WorstCorner or None
    settings : dict
        ``samples``, ``method``, ``seed``, how the plants were mapped.
    notes : tuple of str
    display : DisplayUnits
        The units the text, card and report show a stiffness and an inertia in (the scene's
        ``[display]``; the values and JSON stay SI, each with its unit).
    linear : bool
        The scene's output is a travel.
    """

    scene_name: str
    tolerances: object
    values: dict
    figures: dict
    runs: object
    requirements: tuple
    passes: dict
    yields: tuple
    sensitivities: tuple
    worst: object = None
    settings: dict = field(default_factory=dict)
    notes: tuple = ()
    display: DisplayUnits = DisplayUnits()
    linear: bool = False

    @property
    def count(self) -> int:
        """Number of variants."""
        return int(next(iter(self.values.values())).size)

    @property
    def overall(self):
        """The yield of every requirement at once."""
        return self.yields[-1]

    @property
    def passed(self) -> bool:
        """The required yield is met by the lower end of its interval (True when the scene
        requires none)."""
        return self.overall.met

    def yield_of(self, name: str):
        """The :class:`~servo_toolkit.core.yields.Yield` of requirement ``name``."""
        return next(y for y in self.yields if y.name == name)

    def sensitivity(self, figure: str):
        """The :class:`~servo_toolkit.core.sensitivity.Sensitivity` on ``figure``."""
        return next(s for s in self.sensitivities if s.figure == figure)

    def to_dict(self) -> dict:
        """JSON-ready summary (yields, rankings, worst corner; not every variant)."""
        return {"scene": self.scene_name, "variants": self.count, **self.settings,
                "tolerances": [t.to_dict() for t in self.tolerances.items],
                "min_yield": self.tolerances.min_yield, "passed": self.passed,
                "yields": [y.to_dict() for y in self.yields],
                "sensitivity": [s.to_dict() for s in self.sensitivities],
                "worst_corner": None if self.worst is None else self.worst.to_dict(), "notes": list(self.notes)}

    def table(self) -> str:
        """Yields, rankings and the worst corner as text."""
        req = self.tolerances.min_yield
        lines = [f"  {self.count} variants ({self.settings.get('method', '')}) of {len(self.tolerances.items)} "
                 f"tolerances" + (f"; required yield >= {100 * req:g} % (lower end of the "
                                  f"{100 * self.overall.confidence:g} % interval)" if req is not None else "")]
        for y in self.yields:
            verdict = "" if y.required is None else ("  ok" if y.met else "  FAIL")
            lines.append(f"  yield {y.name:<22}{y.text()}{verdict}")
            if y.shortfall():
                lines.append(f"        {y.shortfall()}")
        for s in self.sensitivities:
            if s.method == "none":
                lines.append(f"  sensitivity of {s.label}: {s.reason}")
                continue
            fit = f"R^2 {s.r2:.3f}" if np.isfinite(s.r2) else "no regression"
            lines.append(f"  sensitivity of {s.label} ({METHODS.get(s.method, s.method)}, {fit}, "
                         f"shares of its variance with {100 * s.confidence:g} % intervals):")
            if s.method == "src" and not s.r2 >= R2_LINEAR:
                lines.append(f"    caution: {s.reason}")
            inert = [k for k, flag in zip(s.keys, s.inert) if flag]
            for k, v, lo, hi in s.ranking():
                if k not in inert:
                    lines.append(f"    {k:<34}{100 * v:7.3g} %  ({100 * lo:.3g}..{100 * hi:.3g} %)")
            if inert:
                lines.append(f"    does not enter it (0 exactly): {', '.join(inert)}")
        if self.worst is not None:
            w = self.worst
            lines.append(f"  worst corner over {w.basis} ({w.evaluated()}): {w.verdict()} at "
                         f"{self.corner_text()}")
            if w.run_text():
                lines.append(f"    {w.run_text()}")
        lines += [f"  note: {note}" for note in self.notes]
        return "\n".join(lines)

    def shown(self, key: str) -> tuple:
        """``(unit, factor)`` the values of tolerance ``key`` are shown in (:func:`shown_unit`)."""
        units = {t.key: t.unit for t in self.tolerances.items}
        return shown_unit(key, units.get(key, ""), self.display, self.linear)

    def describe(self, tolerance) -> str:
        """A tolerance's distribution in words, in the units shown."""
        return tolerance.describe(*self.shown(tolerance.key))

    def corner_text(self) -> str:
        """The worst corner's values with their units (the scene's ``[display]`` unit for a
        stiffness or an inertia, else SI), e.g. ``motor.resistance = 0.7 ohm``."""
        if self.worst is None:
            return ""
        out = []
        for k, v in self.worst.values.items():
            unit, factor = self.shown(k)
            out.append(f"{k} = {fmt(v * factor, 4)}" + ("" if unit in _NO_UNIT else f" {unit}"))
        return ", ".join(out)

    def plot(self, ax=None, figure: str | None = None):
        """Bar chart of the tolerances' variance shares on ``figure`` (default: the first
        figure with a ranking), with their intervals."""
        import matplotlib.pyplot as plt
        if ax is None:
            _, ax = plt.subplots(figsize=(7, 3.6), layout="constrained")
        ranked = [s for s in self.sensitivities if s.method != "none"]
        if not ranked:
            ax.text(0.5, 0.5, "no figure varies over the variants", ha="center", va="center",
                    transform=ax.transAxes)
            return ax
        s = ranked[0] if figure is None else self.sensitivity(figure)
        order = s.ranking()
        names = [k for k, *_ in order][::-1]
        share = np.array([v for _, v, _, _ in order])[::-1]
        lo = np.array([v for _, _, v, _ in order])[::-1]
        hi = np.array([v for *_, v in order])[::-1]
        err = np.vstack([np.clip(share - lo, 0, None), np.clip(hi - share, 0, None)])
        ax.barh(names, 100 * share, xerr=100 * err, color="C0", ecolor="0.3", capsize=3)
        ax.set_xlabel(f"share of the variance of the {s.label} [%]")
        ax.set_title(f"{self.scene_name}: what drives the {s.label} ({s.method})")
        ax.grid(True, axis="x", alpha=0.3)
        return ax

    def _repr_line(self) -> str:
        y = self.overall
        req = "" if y.required is None else f", required {100 * y.required:g} %: {'met' if y.met else 'NOT met'}"
        return f"{self.scene_name}: {self.count} variants, yield {100 * y.fraction:.4g} % (lower {100 * y.low:.4g} %){req}"

    def _repr_card(self) -> str:
        rows = [(y.name, f"{100 * y.fraction:.4g} %", f"{100 * y.low:.4g}..{100 * y.high:.4g} %",
                 f"{y.passed} / {y.total}", "" if y.required is None else ("met" if y.met else "NOT met"))
                for y in self.yields]
        ranked = [s for s in self.sensitivities if s.method != "none"]
        parts = [facts((("variants", f"{self.count} ({self.settings.get('method', '')})"),
                        ("tolerances", ", ".join(self.tolerances.keys)),
                        ("required yield", "none" if self.tolerances.min_yield is None
                         else f"{100 * self.tolerances.min_yield:g} % (lower end of the interval)"))),
                 table(("requirement", "yield", "interval", "variants", ""), rows)]
        if ranked:
            parts.append(svg(lambda ax: self.plot(ax), size=(7.0, 0.5 + 0.35 * len(self.tolerances.items))))
        notes = [f"{s.label}: {s.reason}" for s in self.sensitivities]
        if self.worst is not None:
            notes.append("worst corner: " + self.corner_text())
        return card(f"Tolerances of {self.scene_name}", status=self.passed if self.tolerances.min_yield is not None
                    else None, parts=parts, notes=notes + list(self.notes))


__all__ = ["ToleranceResult", "WorstCorner", "shown_unit"]
