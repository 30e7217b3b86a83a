"""The result of a nonlinear Monte Carlo run (:func:`servo_toolkit.studies.montecarlo.run.montecarlo`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...core.output_units import OutputUnit
from ...display.cards import RichDisplay, card, facts, svg
from ...display.html import fmt
from ...display.units import DisplayUnits


@dataclass(frozen=True, repr=False)
class MonteCarloResult(RichDisplay):
    """Figures of every variant's closed-loop time run.

    Attributes
    ----------
    scene_name : str
    values : dict of numpy.ndarray
        Varied parameters per variant (``load_inertia`` kg*m^2, or the load's mass in kg for
        an output travel; ``stiffness`` factor).
    tracking_error : numpy.ndarray
        Largest |output - command| over the run (rad; m for an output travel).
    peak_current : numpy.ndarray
        Largest |motor current| (A).
    saturated : numpy.ndarray of bool
        The current reference or the armature voltage reached its limit.
    failed : numpy.ndarray of bool
        Non-finite state, stroke end, or a step outside the RK4 stability region at the
        variant's own parameters (``reasons`` says which); its figures are not trusted.
    reasons : tuple of str
        Why each variant failed ("" when it did not).
    abs_lambda_dt : numpy.ndarray
        Largest |lambda dt| found by the variant's step check.
    wall_s : float
        Integration time (model building and step checks excluded), summed
        over chunks.
    dt_s : float
    steps_per_variant : int
    duration_s : float
    linear_output : bool
        The output is a travel (figures in mm) rather than an angle (deg).
    settings : dict
    notes : tuple of str
    display : DisplayUnits
        Unit the text, card and plot show a load inertia in (the scene's ``[display]``;
        default SI); ``values`` and :meth:`to_dict` stay SI.
    """

    scene_name: str
    values: dict
    tracking_error: np.ndarray
    peak_current: np.ndarray
    saturated: np.ndarray
    failed: np.ndarray
    reasons: tuple
    abs_lambda_dt: np.ndarray
    wall_s: float
    dt_s: float
    steps_per_variant: int
    duration_s: float
    linear_output: bool = False
    settings: dict = field(default_factory=dict)
    notes: tuple = ()
    display: DisplayUnits = DisplayUnits()
    runner: tuple = field(default=(), repr=False, compare=False)

    @property
    def count(self) -> int:
        """Number of variants."""
        return int(self.tracking_error.size)

    @property
    def unit(self) -> OutputUnit:
        """Units of the output coordinate (an angle, or a travel)."""
        return OutputUnit("m" if self.linear_output else "rad")

    def shown_values(self) -> dict:
        """:attr:`values` as shown: ``load_inertia`` in :attr:`display`'s unit."""
        return {k: self.display.show("inertia", v, self.unit.linear) if k == "load_inertia" else v
                for k, v in self.values.items()}

    def ranges_text(self) -> str:
        """The varied parameters' spans with units, e.g. ``load_inertia 0.01..3.99 kg*m^2,
        stiffness 0.7..1.3 x nominal`` (:func:`servo_toolkit.loop.vary.ranges_text`)."""
        from ...loop.vary import ranges_text
        return ranges_text(self.values, self.display, self.unit.linear)

    def variant_text(self, i: int) -> str:
        """Variant ``i``'s parameters with their units (:func:`servo_toolkit.loop.vary.variant_text`)."""
        from ...loop.vary import variant_text
        return variant_text(self.values, self.display, self.unit.linear, index=int(i))

    @property
    def error_unit(self) -> str:
        """``"mm"`` for an output travel, else ``"deg"``."""
        return self.unit.shown

    @property
    def error_display(self) -> np.ndarray:
        """Tracking errors in :attr:`error_unit`."""
        return self.unit.show(self.tracking_error)

    def worst_index(self, figure: str = "tracking_error") -> int | None:
        """Index of the variant with the largest ``figure`` (``"tracking_error"`` or
        ``"peak_current"``) among those that did not fail; None if every variant failed."""
        vals = getattr(self, figure)
        if np.all(self.failed):
            return None
        return int(np.argmax(np.where(self.failed, -np.inf, vals)))

    def worst_indices(self, n: int = 3, figure: str = "tracking_error") -> np.ndarray:
        """Indices of the ``n`` worst variants (largest ``figure``, failed ones left out)."""
        vals = np.where(self.failed, -np.inf, getattr(self, figure))
        order = np.argsort(vals)[::-1]
        return order[:min(n, int(np.sum(~self.failed)))]

    def variant(self, i: int) -> dict:
        """Parameters and figures of variant ``i`` (the JSON entry)."""
        key = f"max_abs_tracking_error_{self.error_unit}"
        return {**{k: float(v[i]) for k, v in self.values.items()}, key: float(self.error_display[i]),
                "peak_current_A": float(self.peak_current[i]), "saturated": bool(self.saturated[i]),
                "failed": bool(self.failed[i]), **({"reason": self.reasons[i]} if self.failed[i] else {})}

    def worst(self) -> dict:
        """The worst variant per figure: its index and entry."""
        out = {}
        for figure in ("tracking_error", "peak_current"):
            i = self.worst_index(figure)
            out[figure] = None if i is None else {"index": i, **self.variant(i)}
        return out

    def trace(self, i: int):
        """Variant ``i`` run again by :func:`servo_toolkit.sim.run` with every step recorded
        (a :class:`~servo_toolkit.sim.SimulationResult`: traces to plot, and the single
        run's loop as a check of the batched figures).

        Raises
        ------
        SimulationError
            For a variant that failed.
        """
        from dataclasses import replace

        from ...sim import run
        builder, P0, reference, *fitted = self.runner
        load = self.values["load_inertia"][i] if "load_inertia" in self.values else None
        stiff = self.values["stiffness"][i] if "stiffness" in self.values else None
        rows = fitted[0] if fitted else None
        if rows is not None:  # the fitted row the batch ran
            P, T, tix = rows.rows(np.array([[self.values[k][i] for k in self.values]]))
            model = replace(rows.model, P=P[0], T=T[tix[0]])
        elif builder.fast:
            P, dT = builder.row(P0, load, stiff)
            model = replace(builder.model, P=P, T=builder.model.T if dT is None else builder.model.T + dT)
        else:
            model = builder.exact(load, stiff)
        return run(model, reference, self.duration_s, "rk4", self.dt_s, output_dt=self.dt_s)

    def to_dict(self) -> dict:
        """JSON-ready: settings, every variant and the worst ones."""
        return {"scene": self.scene_name, "samples": self.count, "wall_s": float(self.wall_s),
                "steps_per_variant": int(self.steps_per_variant), "dt_s": self.dt_s,
                "duration_s": self.duration_s, "failed_variants": int(np.sum(self.failed)),
                "saturated_variants": int(np.sum(self.saturated)), **self.settings,
                "ranges": {k: [float(v.min()), float(v.max())] for k, v in self.values.items()},
                "variants": [self.variant(i) for i in range(self.count)], "worst": self.worst(),
                "notes": list(self.notes)}

    def summary(self) -> str:
        """One line."""
        i = self.worst_index()
        worst = "no variant ran" if i is None else (
            f"worst tracking error {self.error_display[i]:.4g} {self.error_unit}, peak current "
            f"{np.max(np.where(self.failed, -np.inf, self.peak_current)):.4g} A")
        return (f"{self.scene_name}: {self.count} variants x {self.steps_per_variant} steps, {worst}, "
                f"{int(np.sum(self.saturated))} saturated, {int(np.sum(self.failed))} failed, "
                f"integration {self.wall_s:.3g} s")

    def _repr_line(self) -> str:
        return self.summary()

    def _repr_card(self) -> str:
        """The notebook card: the figures, the plot of every variant and the notes."""
        rows = (("variants", self.count), ("steps per variant", self.steps_per_variant),
                ("ranges", self.ranges_text()),
                ("worst tracking error", self._worst_text("tracking_error")),
                ("worst peak current", self._worst_text("peak_current")),
                ("saturated / failed", f"{int(np.sum(self.saturated))} / {int(np.sum(self.failed))}"),
                ("integration", f"{self.wall_s:.3g} s"))
        return card(f"Monte Carlo of {self.scene_name}", parts=[facts(rows), svg(self.plot, size=(11.0, 4.0), cols=2)],
                    notes=self.notes)

    def _worst_text(self, figure) -> str:
        i = self.worst_index(figure)
        if i is None:
            return "every variant failed"
        at = self.variant_text(i)
        value = (f"{fmt(self.error_display[i])} {self.error_unit}" if figure == "tracking_error"
                 else f"{fmt(self.peak_current[i])} A")
        return f"{value} at {at}"

    def table(self) -> str:
        """Text summary."""
        rng = self.ranges_text()
        lines = [f"  {self.count} variants ({rng}), {self.steps_per_variant} steps of {self.dt_s:.4g} s each, "
                 f"integration {self.wall_s:.3g} s",
                 f"  worst tracking error {self._worst_text('tracking_error')}",
                 f"  worst peak current   {self._worst_text('peak_current')}",
                 f"  {int(np.sum(self.saturated))} variants reached a current or voltage limit, "
                 f"{int(np.sum(self.failed))} failed"]
        for i in np.flatnonzero(self.failed)[:5]:
            lines.append(f"    variant {i}: {self.reasons[i]}")
        lines += [f"  note: {n}" for n in self.notes]
        return "\n".join(lines)

    def plot(self, axes=None):
        """Tracking error and peak current against load inertia (coloured by stiffness
        factor); failed variants marked with x."""
        import matplotlib.pyplot as plt
        if axes is None:
            _, axes = plt.subplots(1, 2, figsize=(11, 4))
        x = self.shown_values().get("load_inertia", np.arange(self.count))
        c = self.values.get("stiffness")
        ok = ~self.failed
        for ax, y, label in ((axes[0], self.error_display, f"max |tracking error| [{self.error_unit}]"),
                             (axes[1], self.peak_current, "peak |current| [A]")):
            sc = ax.scatter(x[ok], y[ok], c=None if c is None else c[ok], s=6, cmap="viridis")
            if np.any(self.failed):
                ax.scatter(x[self.failed], np.zeros(int(np.sum(self.failed))), marker="x", color="r", label="failed")
                ax.legend()
            ax.set_xlabel(f"load {'mass' if self.unit.linear else 'inertia'} [{self.display.inertia_unit(self.unit.linear)}]"
                          if "load_inertia" in self.values else "variant")
            ax.set_ylabel(label)
        if c is not None:
            axes[1].figure.colorbar(sc, ax=axes[1], label="stiffness factor")
        axes[0].set_title(f"{self.scene_name}: {self.count} variants")
        return axes


