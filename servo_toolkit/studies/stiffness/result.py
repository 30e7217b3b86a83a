"""The stiffness chain study's result: each compliant stage's stiffness at the output, its
share of the series compliance, the seed-001 neglect criterion, as a table, a card and a
figure (:class:`StiffnessResult`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...core.angles import RAD_PER_DEG
from ...drivetrain.elements import NeglectCriterion
from ...display.cards import RichDisplay
from ...display.legends import legend_beside
from ...display.cards import card, esc, num
from ...display.html import column
from ...display.units import DisplayUnits

#: significant digits of the stiffness table's numbers
DIGITS = 5

def _nulls(values) -> list:
    """List with non-finite entries as None (JSON has no inf or NaN)."""
    return [float(v) if np.isfinite(v) else None for v in np.asarray(values, dtype=float)]


@dataclass(frozen=True, repr=False)
class StiffnessResult(RichDisplay):
    """Stiffness chain at a set of output coordinates.

    Attributes
    ----------
    angles_deg : numpy.ndarray
        Output angles (deg); NaN for a linear output (see ``positions_mm``).
    names : tuple of str
        One per compliant stage, motor side first.
    stage_stiffness : numpy.ndarray
        (n_stages, n_points), reflected to the output: N*m/rad, or N/m for a linear output.
    shares : numpy.ndarray
        Compliance shares (n_stages, n_points).
    total : numpy.ndarray
        Series total, N*m/rad (N/m for a linear output); ``inf`` for a rigid chain.
    ratio : numpy.ndarray
        Motor angle per unit of output N(q): rad/rad, or rad/m for a linear output.
    reflected_inertia : numpy.ndarray
        J(q) at the output, kg*m^2 (a mass in kg for a linear output).
    negligible : numpy.ndarray of bool
        Per stage: compliance share below 1e-3 at every point (share rule).
    output_unit : str
        ``"rad"`` or ``"m"``.
    positions_mm : numpy.ndarray or None
        Output travels (mm) of a linear output, else None.
    criterion : NeglectCriterion or None
        Seed 001's two conditions per stage (None when the chain is rigid).
    native_stiffness : numpy.ndarray
        Each stage's own, unreflected stiffness, in ``native_units``.
    native_units : tuple of str
    native_ratio : numpy.ndarray or None
        |du_i/dq| of each stage's spring coordinate, (n_stages, n_points): rad or m per
        unit of q.
    display : DisplayUnits
        Units :meth:`table` shows a stiffness and an inertia in (the scene's ``[display]``;
        default SI). The arrays and :meth:`to_dict` stay SI.
    """

    angles_deg: np.ndarray
    names: tuple
    stage_stiffness: np.ndarray
    shares: np.ndarray
    total: np.ndarray
    ratio: np.ndarray
    reflected_inertia: np.ndarray
    negligible: np.ndarray
    output_unit: str = "rad"
    positions_mm: np.ndarray | None = None
    criterion: NeglectCriterion | None = None
    native_stiffness: np.ndarray | None = None
    native_units: tuple = ()
    native_ratio: np.ndarray | None = None
    display: DisplayUnits = DisplayUnits()

    @property
    def linear(self) -> bool:
        """True for a linear output (q in m)."""
        return self.output_unit == "m"

    @property
    def stiffness_unit(self) -> str:
        """SI unit of the stiffnesses at the output."""
        return "N/m" if self.linear else "N*m/rad"

    def _stages(self) -> list:
        crit = self.criterion
        out = []
        for i, (n, k, s, neg) in enumerate(zip(self.names, self.stage_stiffness, self.shares, self.negligible)):
            stage = {"name": n, "stiffness_Nm_per_rad": k.tolist(), "share": s.tolist(), "negligible": bool(neg)}
            if self.linear:
                stage["stiffness_N_per_m"] = k.tolist()
            if self.native_stiffness is not None:
                stage["native_stiffness"] = float(self.native_stiffness[i])
                stage["native_unit"] = self.native_units[i]
            if self.native_ratio is not None:
                stage["native_ratio_to_output"] = self.native_ratio[i].tolist()
            if crit is not None:
                stage.update({
                    "own_stiffness": float(crit.own_stiffness[i]),
                    "ratio_to_output": crit.ratio[i].tolist(),
                    "later_ratio": _nulls(crit.later_ratio[i]),
                    "stiffness_to_later": _nulls([crit.stiffness_to_later[i]])[0],
                    "later_ratio_large": bool(np.all(crit.ratio_large[i])),
                    "stiffness_comparable": bool(crit.stiffness_comparable[i]),
                    "seed_negligible": bool(crit.negligible[i]),
                })
            out.append(stage)
        return out

    def to_dict(self) -> dict:
        """JSON-ready dictionary (lists over the points).

        JSON has no infinity: a rigid chain (no stage declares a stiffness) has ``null``
        totals and ``"rigid": true``. Contract keys keep their SI values in the output's
        unit; a linear output also gets unit-correct duplicates (``total_N_per_m``,
        ``ratio_rad_per_m``, ``reflected_mass_kg``, per stage ``stiffness_N_per_m``),
        ``positions_mm``, and ``null`` for ``angles_deg`` and ``total_Nm_per_deg``.
        """
        n = len(self.total)
        data = {
            "angles_deg": [None] * n if self.linear else self.angles_deg.tolist(),
            "output_unit": self.output_unit,
            "stages": self._stages(),
            "total_Nm_per_rad": _nulls(self.total),
            "total_Nm_per_deg": [None] * n if self.linear else _nulls(self.total * RAD_PER_DEG),
            "ratio": self.ratio.tolist(),
            "reflected_inertia_kg_m2": self.reflected_inertia.tolist(),
            "rigid": not self.names,
            "display_units": self.display.to_dict(self.linear),
        }
        if self.criterion is not None:
            data["criterion"] = {"min_ratio": self.criterion.min_ratio, "within": self.criterion.within,
                                 "own_stiffness_unit": self.stiffness_unit}
        if self.linear:
            data.update({"positions_mm": self.positions_mm.tolist(), "total_N_per_m": _nulls(self.total),
                         "total_N_per_mm": _nulls(self.total * 1e-3), "ratio_rad_per_m": self.ratio.tolist(),
                         "reflected_mass_kg": self.reflected_inertia.tolist()})
        return data

    def table(self) -> str:
        """Plain-text table, one block of columns per point, then seed 001's criterion.

        Stiffnesses and the inertia are in :attr:`display`'s units; each block of numbers
        (the stiffnesses with their total, the ratio, the inertia) has one number format
        (:func:`servo_toolkit.display.html.column`).
        """
        show = self.display
        unit, inertia_unit = show.stiffness_unit(self.linear), show.inertia_unit(self.linear)
        if self.linear:
            cols = [f"{p:>+10.2f} mm    share " for p in self.positions_mm]
            ratio_label, inertia_label = "ratio N [rad/m]", f"reflected mass [{inertia_unit}]"
        else:
            cols = [f"{a:>+10.1f} deg   share " for a in self.angles_deg]
            ratio_label, inertia_label = "ratio N [rad/rad]", f"reflected inertia [{inertia_unit}]"
        head = f"{'stage [' + unit + ']':28s}" + "".join(cols)
        lines = [head, "-" * len(head)]
        if not self.names:
            lines.append("no compliant stage: the chain is rigid (give a stage a stiffness, or add a "
                         "compliance stage, to see series stiffness and shares)")
        n_points = len(self.total)
        stiff = np.concatenate([np.asarray(self.stage_stiffness, float).reshape(-1, n_points),
                                np.asarray(self.total, float).reshape(1, -1)]) if self.names else np.empty((0, n_points))
        cells = np.asarray(column(show.show("stiffness", stiff, self.linear).ravel(), DIGITS),
                           dtype=object).reshape(stiff.shape)
        for n, row, s, neg in zip(self.names, cells, self.shares, self.negligible):
            text = f"{n[:28]:28s}" + "".join(f"{ki:>14s} {si:>7.2%}" for ki, si in zip(row, s))
            lines.append(text + ("   (negligible)" if neg else ""))
        lines.append("-" * len(head))
        totals = cells[-1] if self.names else ["rigid"] * n_points
        lines.append(f"{'series total [' + unit + ']':28s}" + "".join(f"{t:>14s}        " for t in totals))
        lines.append(f"{ratio_label:28s}" + "".join(f"{r:>14s}        " for r in column(self.ratio, DIGITS)))
        inertia = column(show.show("inertia", np.asarray(self.reflected_inertia, float), self.linear), DIGITS)
        lines.append(f"{inertia_label:28s}" + "".join(f"{j:>14s}        " for j in inertia))
        if self.criterion is not None and len(self.names) > 1:
            lines += ["", self._criterion_table()]
        return "\n".join(lines)

    def _criterion_table(self) -> str:
        c = self.criterion
        head = (f"{'seed 001 neglect criterion':28s}{'own K [' + self.stiffness_unit + ']':>18s}"
                f"{'ratio to output':>17s}{'later ratio':>13s}{'K / later':>11s}  neglect")
        lines = [head, "-" * len(head)]
        own = column(c.own_stiffness, 4)
        for i, n in enumerate(self.names):
            later = c.later_ratio[i]
            lat = "-" if np.all(np.isnan(later)) else f"{np.nanmin(later):.3g}"
            stiff = "-" if np.isnan(c.stiffness_to_later[i]) else f"{c.stiffness_to_later[i]:.3g}"
            flags = ("ratio " + ("yes" if np.all(c.ratio_large[i]) else "no") + ", K "
                     + ("yes" if c.stiffness_comparable[i] else "no"))
            lines.append(f"{n[:28]:28s}{own[i]:>18s}"
                         f"{f'{c.ratio[i].min():.3g}..{c.ratio[i].max():.3g}':>17s}{lat:>13s}{stiff:>11s}  "
                         f"{'YES' if c.negligible[i] else 'no'} ({flags})")
        lines.append(f"neglect: ratio to every later stage >= {c.min_ratio:g} and own stiffness >= "
                     f"1/{c.within:g} of some later stage's (seed 001);")
        lines.append("own K of a spring on the other kind of coordinate is taken through the mid-stroke ratio "
                     "of the last such spring")
        return "\n".join(lines)

    def plot(self, ax=None):
        """Bar chart of compliance shares per point; returns the Axes."""
        import matplotlib.pyplot as plt
        if ax is None:
            _, ax = plt.subplots(figsize=(7, 3.5), layout="constrained")
        bottom = np.zeros_like(self.total)
        labels = ([f"{p:+.1f} mm" for p in self.positions_mm] if self.linear
                  else [f"{a:+.0f} deg" for a in self.angles_deg])
        for n, s in zip(self.names, self.shares):
            ax.bar(labels, s * 100, bottom=bottom * 100, label=n)
            bottom = bottom + s
        ax.set_ylabel("share of compliance [%]")
        ax.set_title("Series compliance at the output")
        legend_beside(ax)  # the bars fill the axes to 100 %
        return ax

    def _repr_line(self) -> str:
        return _card_line(self)

    def _repr_card(self) -> str:
        return _card_html(self)


def _card_line(s) -> str:
    """The one-line repr of a result of this module."""
    total = num(s.display.show("stiffness", float(np.min(s.total)), s.linear), 4)
    return (f"{len(s.names)} compliant stage(s) at {len(s.total)} point(s); series total {total} "
            f"{s.display.stiffness_unit(s.linear)} at its lowest")


def _card_html(s) -> str:
    """The Jupyter card (HTML) of a result of this module."""
    return card("Stiffness chain", parts=[f"<pre>{esc(s.table())}</pre>"])
