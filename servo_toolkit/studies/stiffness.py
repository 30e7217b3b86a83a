"""Stiffness chain study (seed 001): each stage's stiffness at the output and its share.

The output coordinate q is an angle for a rotary output (the cam angle for a cam chain) and
a travel for a linear one (a chain ending in a screw, :attr:`Drivetrain.output_is_linear`).
Angles are given in deg, travels in mm; both must be finite and inside the drivetrain's
stroke (a cam chain is periodic: any finite cam angle).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import SceneError
from ..core.angles import RAD_PER_DEG
from ..drivetrain.elements import NeglectCriterion
from ..display.cards import RichDisplay
from ..display.cards import card, esc, num
from ..display.html import column
from ..display.units import DisplayUnits

#: significant digits of the stiffness table's numbers
DIGITS = 5

DEFAULT_ANGLES_DEG = (-30.0, 0.0, 10.0, 30.0)


def default_angles_deg(drivetrain) -> tuple:
    """The default output angles (deg): :data:`DEFAULT_ANGLES_DEG` when they lie in the
    stroke (the reference EMA's), else the stroke's ends and middle (a cam: its turn's
    quarters)."""
    lo, hi = (math.degrees(x) for x in drivetrain.stroke)
    if drivetrain.ends_in_cam:
        return (0.0, 90.0, 180.0, 270.0)
    if lo - 1e-9 <= min(DEFAULT_ANGLES_DEG) and max(DEFAULT_ANGLES_DEG) <= hi + 1e-9:
        return DEFAULT_ANGLES_DEG
    return (lo, 0.5 * (lo + hi), hi)


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
            _, ax = plt.subplots(figsize=(7, 3.5))
        bottom = np.zeros_like(self.total)
        labels = ([f"{p:+.1f} mm" for p in self.positions_mm] if self.linear
                  else [f"{a:+.0f} deg" for a in self.angles_deg])
        for n, s in zip(self.names, self.shares):
            ax.bar(labels, s * 100, bottom=bottom * 100, label=n)
            bottom = bottom + s
        ax.set_ylabel("share of compliance [%]")
        ax.set_title("Series compliance at the output")
        ax.legend(fontsize="small")
        return ax

    def _repr_line(self) -> str:
        return _card_line(self)

    def _repr_card(self) -> str:
        return _card_html(self)


def output_points(drive, angles_deg=None, positions_mm=None) -> tuple[np.ndarray, np.ndarray]:
    """Validated output coordinates: q (rad, or m for a linear output) and the values given.

    Parameters
    ----------
    drive : Drivetrain
    angles_deg : sequence of float, optional
        Output angles (deg) of a rotary output; default -30, 0, 10, 30.
    positions_mm : sequence of float, optional
        Output travels (mm) of a linear output; default mid-stroke.

    Returns
    -------
    q, values : numpy.ndarray
        SI coordinates and the same points in deg or mm.

    Raises
    ------
    SceneError
        Key ``angle`` or ``position``: the wrong kind of coordinate for this output, a
        non-finite value, or a value outside :attr:`Drivetrain.stroke`.
    """
    lo, hi = drive.stroke
    if drive.output_is_linear:
        if angles_deg is not None:
            raise SceneError("angle", "the output of this drivetrain is a travel (m), not an angle: "
                             "give positions in mm (--position MM)")
        key, unit, scale = "position", "mm", 1e-3
        values = [drive.mid_stroke / scale] if positions_mm is None else positions_mm
    else:
        if positions_mm is not None:
            raise SceneError("position", "the output of this drivetrain is an angle: give angles "
                             "in deg (--angle DEG)")
        key, unit, scale = "angle", "deg", RAD_PER_DEG
        values = (default_angles_deg(drive) if angles_deg is None else angles_deg)
    values = np.atleast_1d(np.asarray(values, dtype=float))
    if values.size == 0:
        raise SceneError(key, "give at least one value")
    bad = values[~np.isfinite(values)]
    if bad.size:
        raise SceneError(key, f"must be a finite number (got {bad[0]:g} {unit})")
    q = values * scale
    if not drive.ends_in_cam:  # a cam law is periodic: any finite cam angle is fine
        tol = 1e-9 * max(1.0, hi - lo)
        out = values[(q < lo - tol) | (q > hi + tol)]
        if out.size:
            raise SceneError(key, f"must lie within the drivetrain stroke [{lo / scale:.6g}, "
                             f"{hi / scale:.6g}] {unit} (got {out[0]:g} {unit})")
    return q, values


def stiffness_study(scene, angles_deg=None, positions_mm=None, *, min_ratio: float = 10.0,
                    within: float = 10.0) -> StiffnessResult:
    """Reflect each stage's stiffness to the output at the given points.

    Parameters
    ----------
    scene : Scene
    angles_deg : sequence of float, optional
        Output angles (deg) of a rotary output (q for a cam chain); default -30, 0, 10, 30.
    positions_mm : sequence of float, optional
        Output travels (mm) of a linear output; default mid-stroke.
    min_ratio, within : float
        Thresholds of seed 001's neglect criterion (see :class:`NeglectCriterion`).

    Returns
    -------
    StiffnessResult

    Raises
    ------
    SceneError
        See :func:`output_points`.
    """
    drive = scene.drivetrain
    q, values = output_points(drive, angles_deg, positions_mm)
    chain = drive.stiffness(q)
    n, _ = drive.ratio(q)
    j, _ = drive.inertia(q)
    linear = drive.output_is_linear
    crit = chain.criterion(min_ratio, within) if chain.names else None
    return StiffnessResult(
        angles_deg=np.full(q.size, np.nan) if linear else values, names=chain.names,
        stage_stiffness=chain.stage_stiffness, shares=chain.shares, total=chain.total, ratio=n,
        reflected_inertia=j, negligible=chain.negligible(), output_unit=drive.output_unit,
        positions_mm=values if linear else None, criterion=crit, native_stiffness=chain.native_stiffness,
        native_units=chain.native_units, native_ratio=chain.ratio_to_output, display=scene.display)


def _card_line(s) -> str:
    """The one-line repr of a result of this module."""
    total = num(s.display.show("stiffness", float(np.min(s.total)), s.linear), 4)
    return (f"{len(s.names)} compliant stage(s) at {len(s.total)} point(s); series total {total} "
            f"{s.display.stiffness_unit(s.linear)} at its lowest")


def _card_html(s) -> str:
    """The Jupyter card (HTML) of a result of this module."""
    return card("Stiffness chain", parts=[f"<pre>{esc(s.table())}</pre>"])
