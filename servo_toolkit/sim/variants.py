"""Parameter rows of model variants (load inertia, series stiffness), from the model code.

A variant is the nominal model with the load's inertia replaced and the series stiffness
scaled, as ``check --vary`` and a scene's ``[robustness]`` describe it. Building every
variant with :func:`~.model.build_model` takes tens of milliseconds each (tables along the
stroke); instead :class:`VariantBuilder` builds the nominal model, one model with the load
inertia raised by 1 kg*m^2 and one with the stiffness doubled, and learns from them which
parameter slots and table rows move:

- the tables and the load-side inertia are linear in the load inertia (J = sum m t^2);
- the slots that follow from the inertias and the stiffness at q0 (damping, end stop) are
  filled by :func:`~.model.drivetrain_slots`, the function :func:`build_model` uses;
- a feedforward that assumes a given load inertia (the nominal one) offsets its inertia from
  the variant's by the difference (``FF_DJ``, linear in the load inertia too).

Every other slot is copied from the nominal model, so slots added to the model later follow
without change here. If any other slot moves with a varied parameter, or the rows built
here differ from :func:`build_model` on the most distant variant (checked once), every
variant is built with :func:`build_model` instead: slower, never different.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..errors import SceneError
from ..core.output_units import OutputUnit
from . import layout as lo
from .model import build_model, drivetrain_slots

#: slots that :func:`drivetrain_slots` fills
DRIVETRAIN_SLOTS = frozenset({lo.JL, lo.INV_JL, lo.INV_JD0, lo.KSCALE, lo.BETA, lo.HALF_PLAY, lo.KSTOP,
                              lo.DSTOP})
#: relative agreement required between the rows built here and :func:`build_model`
SELF_CHECK_RTOL = 1e-12


def with_load_inertia(scene, inertia: float):
    """The scene with its load's inertia replaced (kg*m^2)."""
    return replace(scene, load=replace(scene.load, inertia=float(inertia)))


def _j0_total(model) -> float:
    """Total inertia at q0 as :func:`build_model` interpolates it."""
    P, T = model.P, model.T
    grid = P[lo.TAB_LO] + P[lo.TAB_H] * np.arange(int(P[lo.TAB_N]))
    return float(np.interp(model.q0, grid, T[lo.T_J] + P[lo.JL]))


def _k0(model) -> float:
    P = model.P
    grid = P[lo.TAB_LO] + P[lo.TAB_H] * np.arange(int(P[lo.TAB_N]))
    return float(np.interp(model.q0, grid, model.T[lo.T_K]))


def _moved(a, b) -> set:
    """Slots (or table rows) that differ between two arrays of the same shape by more than
    rounding (1e-13 of the row's largest value)."""
    if a.shape != b.shape:
        return {-1}
    a2, b2 = np.atleast_2d(a.T).T, np.atleast_2d(b.T).T  # rows: slots, or table rows
    a2, b2 = a2.reshape(a2.shape[0], -1), b2.reshape(b2.shape[0], -1)
    same = (a2 == b2) | (np.isnan(a2) & np.isnan(b2))  # equal infinities (an unbounded slot) too
    with np.errstate(invalid="ignore"):
        gap = np.where(same, 0.0, np.abs(a2 - b2))
        finite = np.isfinite(a2) & np.isfinite(b2)
        scale = np.maximum(np.max(np.abs(np.where(finite, a2, 0.0)), axis=1),
                           np.max(np.abs(np.where(finite, b2, 0.0)), axis=1))
    diff = np.max(gap, axis=1) > 1e-13 * scale
    diff |= np.isnan(a2).any(axis=1) != np.isnan(b2).any(axis=1)
    return set(np.flatnonzero(diff).tolist())


@dataclass(frozen=True)
class VariantBuilder:
    """Parameter rows and tables of variants of one scene, controller and model options.

    Attributes
    ----------
    model : Model
        The nominal model.
    fast : bool
        Rows from the nominal model and :func:`drivetrain_slots` (False: :func:`build_model`
        per variant).
    """

    scene: object
    controller: object
    options: object
    model: object
    d_table: np.ndarray | None
    d_jl: float
    d_j0: float
    j0: float
    k0: float
    fast: bool
    d_ff: float = 0.0

    @classmethod
    def create(cls, scene, controller, options, varied=("load_inertia", "stiffness"), model=None):
        """Build the nominal model and learn how the varied parameters move its rows."""
        m0 = model or build_model(scene, controller, options)
        # the full chain's variants are built exactly (its segment block moves with them)
        fast, d_table, d_jl, d_j0, d_ff = m0.P[lo.NMID] == 0.0, None, 0.0, 0.0, 0.0
        if "load_inertia" in varied and fast:
            m1 = build_model(with_load_inertia(scene, scene.load.inertia + 1.0), controller, options)
            fast &= m1.rigid == m0.rigid and _moved(m0.P, m1.P) <= DRIVETRAIN_SLOTS | {lo.FF_DJ}
            if fast:
                d_jl = float(m1.P[lo.JL] - m0.P[lo.JL])
                d_j0 = _j0_total(m1) - _j0_total(m0)
                d_ff = float(m1.P[lo.FF_DJ] - m0.P[lo.FF_DJ])
                d_table = m1.T - m0.T if _moved(m0.T, m1.T) else None
        if "stiffness" in varied and fast:
            m2 = build_model(scene, controller, replace(options, stiffness_scale=2 * options.stiffness_scale))
            fast &= m2.rigid == m0.rigid and _moved(m0.P, m2.P) <= DRIVETRAIN_SLOTS and not _moved(m0.T, m2.T)
        return cls(scene, controller, options, m0, d_table, d_jl, d_j0, _j0_total(m0),
                   0.0 if m0.rigid else _k0(m0), fast, d_ff)

    def _options(self, stiffness):
        return replace(self.options, stiffness_scale=self.options.stiffness_scale * float(stiffness))

    def row(self, P0, load_inertia=None, stiffness=None):
        """Parameters of one variant from the nominal ``P0`` (reference slots filled), and its
        table offset (None: the nominal tables)."""
        m = self.model
        delta = 0.0 if load_inertia is None else float(load_inertia) - self.scene.load.inertia
        jl = 0.0 if m.rigid else float(m.P[lo.JL]) + delta * self.d_jl
        if not m.rigid and not jl > 0:
            raise SceneError("vary.load_inertia", f"{load_inertia:g} {OutputUnit(m.output_unit).inertia} leaves no inertia on the load side "
                                                  "of the compliance")
        P = P0.copy()
        drivetrain_slots(P, rigid=m.rigid, j0_tot=self.j0 + delta * self.d_j0, jl=jl, k0=self.k0,
                         options=self._options(1.0 if stiffness is None else stiffness),
                         play=2.0 * float(m.P[lo.HALF_PLAY]), zeta=m.damping.get("two_mass_ratio"))
        P[lo.FF_DJ] = P0[lo.FF_DJ] + delta * self.d_ff
        return P, (None if self.d_table is None or delta == 0.0 else delta * self.d_table)

    def exact(self, load_inertia=None, stiffness=None):
        """The variant's model from :func:`build_model` (the reference for :meth:`row`)."""
        scene = self.scene if load_inertia is None else with_load_inertia(self.scene, load_inertia)
        return build_model(scene, self.controller, self._options(1.0 if stiffness is None else stiffness))

    def rows(self, P0, values: dict, fill):
        """Parameter matrix, table stack and table index of every variant.

        Parameters
        ----------
        P0 : numpy.ndarray
            Nominal parameters with the reference slots filled.
        values : dict of numpy.ndarray
            ``load_inertia`` and/or ``stiffness`` per variant.
        fill : callable
            ``fill(model) -> P`` with the reference slots set (used on the exact path).

        Returns
        -------
        P : numpy.ndarray
            (n, nP)
        T : numpy.ndarray
            (n_tables, rows, points)
        tix : numpy.ndarray
            (n,) table index per variant.
        """
        n = next(iter(values.values())).size
        load = values.get("load_inertia")
        stiff = values.get("stiffness")
        args = [(None if load is None else load[i], None if stiff is None else stiff[i]) for i in range(n)]
        if not self.fast:
            models = [self.exact(*a) for a in args]
            for m, a in zip(models, args):
                if m.P.size != self.model.P.size or m.T.shape != self.model.T.shape or m.rigid != self.model.rigid:
                    key = "vary.load_inertia" if a[0] is not None else "vary.stiffness"
                    raise SceneError(key, "a variant changes the model's structure (its nodes, compliances or "
                                          f"lost motion) at load_inertia={a[0]}, stiffness={a[1]}: vary within a "
                                          "range where the drivetrain keeps its form")
            return (np.stack([fill(m) for m in models]), np.stack([m.T for m in models]), np.arange(n))
        P = np.empty((n, P0.size))
        tables, tix = [self.model.T], np.zeros(n, dtype=np.int64)
        for i, a in enumerate(args):
            P[i], dT = self.row(P0, *a)
            if dT is not None:
                tables.append(self.model.T + dT)
                tix[i] = len(tables) - 1
        return P, np.stack(tables), tix

    def self_check(self, values: dict) -> bool:
        """Whether :meth:`row` agrees with :func:`build_model` on the variant farthest from the
        nominal one (relative :data:`SELF_CHECK_RTOL`)."""
        if not self.fast:
            return True
        n = next(iter(values.values())).size
        dist = np.zeros(n)
        if "load_inertia" in values:
            dist += np.abs(values["load_inertia"] - self.scene.load.inertia)
        if "stiffness" in values:
            dist += np.abs(np.log(values["stiffness"]))
        i = int(np.argmax(dist))
        a = (values["load_inertia"][i] if "load_inertia" in values else None,
             values["stiffness"][i] if "stiffness" in values else None)
        exact = self.exact(*a)
        P, dT = self.row(self.model.P, *a)
        T = self.model.T + (0.0 if dT is None else dT)
        return (exact.P.shape == P.shape and np.allclose(P, exact.P, rtol=SELF_CHECK_RTOL, atol=0.0)
                and np.allclose(T, exact.T, rtol=SELF_CHECK_RTOL, atol=1e-300))
