"""The result of :func:`servo_toolkit.studies.reduce.run.reduce`: what a study's reduced model
leaves out, the a-priori bound, the measured difference and each effect's own cost."""

from __future__ import annotations

import math
import textwrap
from dataclasses import dataclass, field

import numpy as np

from ...core.json_text import nulls
from ...core.output_units import OutputUnit
from ...display.cards import RichDisplay, card, facts, num, svg, table
from .choice import _db, _deg
from .estimates import ReductionPlan

#: characters per line of the plot's title (a long list of effects left out wraps)
TITLE_CHARS = 80


@dataclass(frozen=True)
class EffectCost:
    """What leaving out one effect alone costs the study.

    Attributes
    ----------
    effect : str
    estimate : float
        Its a-priori estimate.
    measured : float
        Largest relative difference full / full without it over the points within the limits
        (NaN: no such point).
    measured_saturated : float
        The same over the points that reached a limit (NaN: none).
    failed : int
        Points whose run failed on either model (not compared).
    """

    effect: str
    estimate: float
    measured: float
    measured_saturated: float
    failed: int = 0

    def to_dict(self) -> dict:
        """JSON-ready (strict: a figure that does not exist is None)."""
        return nulls({"effect": self.effect, "estimate_relative": self.estimate, "measured_relative": self.measured,
                      "measured_saturated_relative": self.measured_saturated, "failed_points": self.failed})


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
        (n_a, n_f) measured relative difference full/reduced (NaN: a run failed, see
        ``failures``).
    saturated : numpy.ndarray
        (n_a, n_f) bool: a limit was reached in either run (outside the linear statement);
        False at a failed point.
    full_options, reduced_options : dict
    notes : tuple of str
    output_unit : {"rad", "m"}
        Unit of the output coordinate; amplitudes are shown in deg or mm after it.
    per_effect : tuple of EffectCost
        Each effect left out and the chain's modes above the first, measured on their own
        (empty with ``per_effect=False``).
    failures : tuple
        (n_a * n_f) row-major: None, or why the point's run failed (on which model); a
        failed point is neither compared nor counted as saturated.
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
    per_effect: tuple = ()
    failures: tuple = ()

    @property
    def failed(self) -> np.ndarray:
        """(n_a, n_f) bool: the point's run failed on either model (see ``failures``)."""
        if not self.failures:
            return np.isnan(self.difference)
        return np.array([f is not None for f in self.failures], dtype=bool).reshape(self.difference.shape)

    @property
    def compared(self) -> np.ndarray:
        """(n_a, n_f) bool: the point ran on both models and stayed within the limits (what
        :attr:`measured` is over)."""
        return ~self.saturated & ~self.failed & ~np.isnan(self.difference)

    @property
    def same_model(self) -> bool:
        """True when the reduction left nothing out: the reduced model is the full model
        (friction that holds included), run once, and there is no difference to measure."""
        return self.full_options == self.reduced_options

    @property
    def bound(self) -> float:
        """The a-priori bound on the relative difference (the tolerance)."""
        return self.plan.tolerance

    @property
    def measured(self) -> float:
        """Largest measured relative difference over the points within the limits that ran on
        both models (NaN: no such point)."""
        ok = self.compared
        return float(np.max(self.difference[ok])) if ok.any() else math.nan

    @property
    def measured_saturated(self) -> float:
        """Largest measured relative difference over the points that reached a limit."""
        sat = self.saturated & ~self.failed & ~np.isnan(self.difference)
        return float(np.max(self.difference[sat])) if sat.any() else math.nan

    @property
    def bound_applies(self) -> bool:
        """True when at least one point stayed within the current and voltage limits and ran
        on both models: the a-priori bound is a statement about the linear range only."""
        return bool(np.any(self.compared))

    @property
    def within_bound(self) -> bool | None:
        """Measured difference (within the limits) <= the a-priori bound; None (not
        applicable) when no point stayed within the limits and ran on both models."""
        if not self.bound_applies:
            return None
        return bool(self.measured <= self.bound)

    @property
    def verdict(self) -> str:
        """``"within"``, ``"NOT within"`` or ``"not applicable"`` (no point within the limits
        that ran on both models)."""
        return {True: "within", False: "NOT within", None: "not applicable"}[self.within_bound]

    def to_dict(self) -> dict:
        """JSON-ready (strict: a figure that does not exist is None)."""
        def db(e):
            return 20 * math.log10(1 + e) if math.isfinite(e) else e

        def deg(e):
            return math.degrees(math.asin(min(e, 1.0))) if math.isfinite(e) else e
        u = OutputUnit(self.output_unit)
        return nulls({"scene": self.scene, "study": self.study, "measure": self.measure,
                **self.plan.to_dict(),
                "bound_relative": self.bound, "measured_relative": self.measured,
                "measured_dB": db(self.measured), "measured_deg": deg(self.measured),
                "measured_saturated_relative": self.measured_saturated,
                "within_bound": self.within_bound, "bound_applies": self.bound_applies,
                "same_model": self.same_model,
                "points_total": int(self.difference.size), "points_compared": int(self.compared.sum()),
                "points_saturated": int(self.saturated.sum()), "points_failed": int(self.failed.sum()),
                "points": [{"frequency_hz": float(f), u.key("amplitude"): float(u.show(a)),
                            "difference_relative": float(self.difference[i, k]),
                            "saturated": bool(self.saturated[i, k]), "failed": bool(self.failed[i, k]),
                            "error": self._failure(i, k)}
                           for i, a in enumerate(self.amplitudes_rad) for k, f in enumerate(self.frequencies_hz)],
                "full_options": self.full_options, "reduced_options": self.reduced_options,
                "per_effect": [c.to_dict() for c in self.per_effect],
                "notes": list(self.notes)})

    def _failure(self, i: int, k: int):
        """Why point (amplitude i, frequency k) failed, or None."""
        if self.failures:
            return self.failures[i * self.frequencies_hz.size + k]
        return "no difference (a run failed)" if np.isnan(self.difference[i, k]) else None

    def counts(self) -> str:
        """What the measured difference is over: ``"2 of 3 points (1 failed)"``."""
        n, sat, fail = self.difference.size, int(self.saturated.sum()), int(self.failed.sum())
        rest = [f"{sat} reached a limit"] * bool(sat) + [f"{fail} failed"] * bool(fail)
        return f"{int(self.compared.sum())} of {n} point(s)" + (f" ({', '.join(rest)})" if rest else "")

    def failed_text(self) -> str:
        """The failed points with their reasons, ``"8 Hz, 3 deg: reduced model: ..."``, joined by ``"; "``."""
        u = OutputUnit(self.output_unit)
        return "; ".join(f"{f:.4g} Hz, {u.text(a, 3)}: {self._failure(i, k)}"
                         for i, a in enumerate(self.amplitudes_rad) for k, f in enumerate(self.frequencies_hz)
                         if self.failed[i, k])

    def table(self) -> str:
        """Plain-text report: effects, estimates, choice, bound and measured difference."""
        p = self.plan
        f = self.frequencies_hz
        freqs = (f"frequency {f[0]:.4g} Hz" if f.size == 1 else f"{f.size} frequencies {f[0]:.3g}..{f[-1]:.3g} Hz")
        lines = [f"Reduction of {self.scene} for study {self.study or '(default sweep)'}: {freqs}, "
                 f"amplitudes {', '.join(OutputUnit(self.output_unit).text(a, 3) for a in self.amplitudes_rad)}",
                 f"{'effect':34s} {'estimate':>9} {'[dB]':>7} {'[deg]':>6}  decision",
                 "-" * 96]
        for e in p.effects:
            lines.append(f"{e.effect[:34]:34s} {e.estimate:9.2e} {_db(e.estimate):7.3f} {_deg(e.estimate):6.2f}  "
                         f"{e.reason or ('left out' if e.omitted else 'kept')}")
            lines.extend(e.details(" " * 37))
        lines.append("-" * 96)
        left = [e.effect for e in p.omitted]
        lines.append("left out: " + (", ".join(left) if left else "nothing"))
        lines.append(f"a-priori: sum of estimates of the omissions {p.predicted:.2e}; bound (tolerance) "
                     f"{self.bound:.2e} = {_db(self.bound):.3f} dB / {_deg(self.bound):.2f} deg")
        what = "sine-dwell response" if self.measure == "sweep" else "output-angle RMS"
        if self.same_model:
            lines.append(f"measured ({what}): nothing to compare, the reduced model is the full model (every "
                         "effect kept, friction that holds included)")
        elif self.bound_applies:
            lines.append(f"measured ({what}, full vs reduced, over {self.counts()}): {self.measured:.2e} = "
                         f"{_db(self.measured):.3f} dB / {_deg(self.measured):.2f} deg -> {self.verdict} the bound")
        elif np.any(self.saturated):
            sat = self.measured_saturated
            lines.append(f"measured ({what}, full vs reduced, {self.counts()} compared): no point stayed within "
                         f"the current and voltage limits and ran on both models, so the linear bound does not "
                         f"apply (not applicable); difference at the saturated points {sat:.2e} = "
                         f"{_db(sat):.3f} dB / {_deg(sat):.2f} deg")
        else:
            lines.append(f"measured ({what}, full vs reduced): every point's run failed, nothing was compared "
                         f"(not applicable)")
        u = OutputUnit(self.output_unit)
        for i, a in enumerate(self.amplitudes_rad):
            for k, f in enumerate(self.frequencies_hz):
                if self.failed[i, k]:
                    lines.append(f"FAILED at {f:.4g} Hz, {u.text(a, 3)} (not compared): {self._failure(i, k)}")
        if np.any(self.saturated) and self.bound_applies:
            lines.append(f"points that reached a limit (outside the linear statement): largest difference "
                         f"{self.measured_saturated:.2e}")
        if self.per_effect:
            lines.append("each effect on its own (full model vs the full model without it):")
            for c in self.per_effect:
                sat = (f"; {c.measured_saturated:.2e} where a limit was reached"
                       if math.isfinite(c.measured_saturated) else "")
                got = (f"{c.measured:9.2e} = {_db(c.measured):.3f} dB / {_deg(c.measured):.2f} deg"
                       if not math.isnan(c.measured) else "n/a (no point within the limits)")
                fail = f"; {c.failed} point(s) failed, not compared" if c.failed else ""
                lines.append(f"  {c.effect[:32]:32s} estimate {c.estimate:9.2e}  measured {got}{sat}{fail}")
        lines += [f"note: {n}" for n in p.notes + self.notes]
        return "\n".join(lines)

    def plot(self, ax=None):
        """Measured relative difference per point, with the bound and the a-priori sum."""
        import matplotlib.pyplot as plt
        if ax is None:
            _, ax = plt.subplots(figsize=(7, 3.5), layout="constrained")
        for i, a in enumerate(self.amplitudes_rad):
            d = np.where(np.isnan(self.difference[i]), np.nan, np.maximum(self.difference[i], 1e-12))
            line, = ax.loglog(self.frequencies_hz, d, "o-", ms=4, label=f"measured, {OutputUnit(self.output_unit).text(a, 3)}")
            sat = self.saturated[i]
            if sat.any():
                ax.loglog(self.frequencies_hz[sat], d[sat], "o", mfc="none", ms=8, color=line.get_color(),
                          label="reached a limit")
            fail = self.failed[i]
            if fail.any():  # no difference: marked along the top of the axes
                ax.plot(self.frequencies_hz[fail], np.full(int(fail.sum()), 0.95), "x", ms=8,
                        color=line.get_color(), transform=ax.get_xaxis_transform(), label="run failed (not compared)")
        ax.axhline(self.bound, color="r", lw=1, label="a-priori bound")
        if self.plan.predicted > 0:
            ax.axhline(self.plan.predicted, color="k", ls="--", lw=1, label="sum of estimates")
        ax.set_xlabel("frequency [Hz]")
        ax.set_ylabel("|reduced / full - 1|")
        left_out = ", ".join(e.effect for e in self.plan.omitted) or "nothing"  # several lines when long
        ax.set_title(textwrap.fill(f"{self.scene}: reduced model left out {left_out}", TITLE_CHARS), fontsize="small")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize="small")
        return ax

    def _repr_line(self) -> str:
        return _card_line(self)

    def _repr_card(self) -> str:
        return _card_html(self)


def _card_line(r) -> str:
    """The one-line repr of a result of this module."""
    left = ", ".join(e.effect for e in r.plan.omitted) or "nothing"
    fail = f", {int(r.failed.sum())} point(s) failed" if r.failed.any() else ""
    return (f"{r.scene}: left out {left}; measured {num(r.measured, 3)} vs bound {num(r.bound, 3)} "
            f"({r.verdict}){fail}")


def _card_html(r) -> str:
    """The Jupyter card (HTML) of a result of this module."""
    alone = {c.effect: c.measured for c in r.per_effect}
    rows = [(e.effect, num(e.estimate, 3), num(alone[e.effect], 3) if e.effect in alone else "",
             "left out" if e.omitted else "kept", e.reason) for e in r.plan.effects]
    parts = [table(("effect", "estimate (relative)", "measured alone", "decision", "why"), rows),
             facts((("a-priori bound", num(r.bound, 3)), ("measured difference", num(r.measured, 3)),
                    ("measured over", r.counts()), ("verdict", r.verdict))),
             svg(lambda ax: r.plot(ax), size=(7.0, 3.4))]
    return card(f"Reduction of {r.scene}", status=r.within_bound if r.within_bound is not None else None,
                parts=parts, notes=r.notes)


__all__ = ["EffectCost", "ReductionResult"]
