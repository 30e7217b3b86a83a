"""The result of the robustness study: loop figures over parameter variants and the worst
case against the requirements."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..core.output_units import OutputUnit
from ..display.cards import RichDisplay, card, facts, requirements_table, svg
from ..display.units import DisplayUnits
from .requirements import telling_digits
from .vary import ranges_text, variant_text


@dataclass(frozen=True, repr=False)
class RobustnessResult(RichDisplay):
    """Loop figures over parameter variants and the worst case against the requirements.

    Attributes
    ----------
    scene_name : str
    values : dict of numpy.ndarray
        Parameter values per variant (see ``PARAMETERS``).
    figures : dict of numpy.ndarray
        ``gain_margin_db``, ``phase_margin_deg``, ``sensitivity_peak_db``, ``bandwidth_hz``,
        ``phase_lag_deg`` (closed loop, at the required bandwidth), ``max_pole_real``
        (largest real part of the closed-loop poles, 1/s) and ``stable``.
    requirements : list of Check
        ``stable_fraction`` (stable variants / all) and the worst case over the stable
        variants of each margin requirement (see
        :func:`servo_toolkit.loop.requirements.robust_requirements`).
    worst : dict
        Per requirement, the parameter values of the variant that gives the worst figure
        (for ``stable_fraction``: the variant with the rightmost closed-loop pole).
    settings : dict
        ``method``, ``samples``, ``seed`` of the sampling.
    output_unit : {"rad", "m"}
        The output coordinate: ``load_inertia`` is in kg*m^2 for an angle, kg for a travel.
    display : DisplayUnits
        Unit the text and plot show a load inertia in (the scene's ``[display]``; default
        SI); ``values`` and :meth:`to_dict` stay SI.
    """

    scene_name: str
    values: dict
    figures: dict
    requirements: list
    worst: dict
    settings: dict = field(default_factory=dict)
    output_unit: str = "rad"
    display: DisplayUnits = DisplayUnits()

    @property
    def count(self) -> int:
        """Number of variants."""
        return int(self.figures["stable"].size)

    @property
    def unstable_count(self) -> int:
        """Variants whose closed loop is unstable."""
        return int(np.sum(~self.figures["stable"]))

    @property
    def all_stable(self) -> bool:
        return self.unstable_count == 0

    @property
    def passed(self) -> bool:
        """Every robustness requirement met."""
        return all(c.passed for c in self.requirements)

    @property
    def failures(self) -> list:
        """Checks that are not met."""
        return [c for c in self.requirements if not c.passed]

    def ranges_text(self) -> str:
        """The varied parameters' spans with their units (:func:`.vary.ranges_text`)."""
        return ranges_text(self.values, self.display, OutputUnit(self.output_unit).linear)

    def variant_text(self, values: dict) -> str:
        """One variant's parameters (name -> SI value) with their units (:func:`.vary.variant_text`)."""
        return variant_text(values, self.display, OutputUnit(self.output_unit).linear)

    def worst_variant(self, name: str) -> dict:
        """Parameter values of the variant that gives the worst ``name`` figure."""
        return dict(self.worst.get(name, {}))

    def to_dict(self) -> dict:
        """JSON-ready summary (worst cases and the variant giving each, not every variant)."""
        return {"scene": self.scene_name, "variants": self.count, "unstable_variants": self.unstable_count,
                **self.settings,
                "ranges": {k: [float(v.min()), float(v.max())] for k, v in self.values.items()},
                "worst": {c.name: {**c.to_dict(), "at": self.worst.get(c.name, {})} for c in self.requirements},
                "passed": self.passed}

    def table(self) -> str:
        """Worst cases as text."""
        lines = [f"  robustness over {self.count} variants ({self.ranges_text()}): {self.unstable_count} unstable"]
        for c in self.requirements:
            at = self.variant_text(self.worst.get(c.name, {}))
            short = "" if c.passed else f" short by {c.shortfall:.3g} {c.unit}".rstrip()
            d = telling_digits(c.achieved, c.required, 4)
            lines.append(f"  worst {c.name:<24}{c.sense} {c.required:g} {c.unit}: {c.achieved:.{d}g} {c.unit} "
                         f"{'ok' if c.passed else 'FAIL'}{short}  at {at}")
        return "\n".join(lines)

    def plot(self, ax=None, figure: str = "phase_margin_deg"):
        """Scatter of one figure against load inertia, coloured by stiffness factor."""
        import matplotlib.pyplot as plt
        if ax is None:
            _, ax = plt.subplots(figsize=(7, 4))
        unit = OutputUnit(self.output_unit)
        x = (self.display.show("inertia", self.values["load_inertia"], unit.linear) if "load_inertia" in self.values
             else np.arange(self.count))
        c = self.values.get("stiffness", None)
        y = np.where(self.figures["stable"], self.figures[figure], np.nan)
        sc = ax.scatter(x, y, c=c, s=6, cmap="viridis")
        if c is not None:
            ax.figure.colorbar(sc, ax=ax, label="stiffness factor")
        ax.scatter(x[~self.figures["stable"]], np.zeros(self.unstable_count), marker="x", color="r",
                   label="unstable")
        ax.set_xlabel(f"load {'mass' if unit.linear else 'inertia'} [{self.display.inertia_unit(unit.linear)}]")
        ax.set_ylabel(figure)
        ax.set_title(f"{self.scene_name}: {figure} over {self.count} variants")
        return ax

    def _repr_line(self) -> str:
        return _card_line(self)

    def _repr_card(self) -> str:
        return _card_html(self)



def _card_line(r) -> str:
    """The one-line repr of a result of this module."""
    return (f"{r.scene_name}: {r.count} variants, {r.unstable_count} unstable, "
            f"{'requirements met' if r.passed else 'requirements NOT met'}")


def _card_html(r) -> str:
    """The Jupyter card (HTML) of a result of this module."""
    parts = [facts((("variants", r.count), ("unstable variants", r.unstable_count), ("ranges", r.ranges_text()))),
             requirements_table(r.requirements)]
    if hasattr(r, "plot"):
        parts.append(svg(lambda ax: r.plot(ax), size=(7.0, 3.6)))
    return card(f"Robustness of {r.scene_name}", status=r.passed, parts=parts)
