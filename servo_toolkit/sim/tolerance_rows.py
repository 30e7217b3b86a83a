"""Parameter rows and stroke tables of model variants of any scene keys (a scene's
``[tolerances]``), for the batched kernel.

The batch reads every parameter slot of a variant from its own row, so a varied motor
resistance, torque constant, friction, voltage or current limit, encoder resolution,
stage stiffness or mass only needs its row (and, where the stroke tables move, its tables).
Building each variant's model with :func:`~.model.build_model` is exact but costs ~0.1-0.2 s;
instead every slot, every table entry and the drivetrain's primary quantities at q0 (total
and load-side inertia, series stiffness, lost motion, driving and back-driven efficiency)
are mapped from the keys by :func:`servo_toolkit.core.separable.fit`, and the slots that
follow from those primaries are then recomputed by the model's own code
(:func:`~.model_slots.drivetrain_slots`: load inertia, damping, end stop; the loss
coefficients, 1/L). The rows are verified against :func:`build_model` on the farthest and on
random variants and on corners of the box the variants span (:func:`box_corners`: every pair
of keys at its four combinations of ends, so the steep ends of a map, such as a light load's
two-mass stiffness, meet the other keys' extremes; the fit refines on them too), relative to
each slot's and each table row's magnitude; above
:data:`~servo_toolkit.core.separable.DEFAULT_RTOL` every variant is built exactly (in the
chunk that runs it).

The controller is the nominal design on every variant: its slots (current-loop gains,
anti-windup, feedforward, its packed matrices and a Kalman filter's gains) keep the nominal
model's values; only the plant and the sensors vary.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, replace

import numpy as np

from ..errors import SceneError
from ..core.separable import DEFAULT_RTOL, GRID_POINTS, fit
from . import layout as lo
from .chain_split import MIN_BACKDRIVE, hold_slots
from .model import build_model
from .model_slots import drivetrain_slots
from .reference import fill

#: header slots of the controller (firmware): every variant keeps the nominal values
CONTROLLER_SLOTS = (lo.KPI, lo.KII, lo.KAW, lo.CMODE, lo.NC, lo.TS, lo.OFF_A, lo.OFF_B, lo.OFF_C, lo.OFF_D,
                    lo.EST, lo.OFF_E, lo.OFF_KF, lo.INV_TS, lo.FF_ON, lo.FF_KV, lo.FF_KA, lo.FF_MODEL,
                    lo.FF_JSCALE, lo.FF_SPEED, lo.FF_LEAD)
#: slots :func:`~.model_slots.drivetrain_slots` fills from the primaries (two-mass and rigid
#: models; the full chain's come from its segment block)
DERIVED_SLOTS = (lo.JL, lo.INV_JL, lo.INV_JD0, lo.KSCALE, lo.BETA, lo.HALF_PLAY, lo.KSTOP, lo.DSTOP)
#: length of a Kalman speed estimator's packed gains (F 3x3 and K 3)
KALMAN_VALUES = 12
#: primary quantities mapped with the slots: total and load-side inertia at q0, series
#: stiffness at q0, total lost motion, driving and back-driven efficiency
PRIMARIES = ("j0_total", "j_load", "k0", "play", "eta", "eta_back")
#: words in a key's name -> the model option that must stay on for it to act
_EFFECTS = (("inductance", "inductance"), ("backlash", "backlash"), ("lash", "backlash"),
            ("friction", "friction"), ("breakaway", "friction"), ("stribeck", "friction"),
            ("efficiency", "efficiency"), ("stiffness", "compliance"))


def keep_effects(options, keys):
    """``options`` with every effect a toleranced key acts through switched on (a reduced
    model may leave out inductance, backlash, friction, efficiency or the compliance for a
    sine's size and frequency; a tolerance on it must act), and the notes saying which."""
    notes, changes = [], {}
    for key in keys:
        name = key.rsplit(".", 1)[-1]
        for word, option in _EFFECTS:
            if word not in name:
                continue
            if option == "friction" and options.friction == "off":
                changes["friction"] = "smooth"
            elif option in ("inductance", "backlash", "efficiency", "compliance") and not getattr(options, option):
                changes[option] = True
            else:
                continue
            notes.append(f"{option} kept in the model: {key} is toleranced")
    return (replace(options, **changes) if changes else options), notes


def _controller_copy(P, P0) -> None:
    """The nominal controller's slots and packed blocks in row ``P`` (in place)."""
    P[list(CONTROLLER_SLOTS)] = P0[list(CONTROLLER_SLOTS)]
    a = int(P0[lo.OFF_A])
    if a:
        P[a:] = P0[a:] if P.size == P0.size else P[a:]
    if int(P0[lo.EST]) == lo.EST_KALMAN:
        k = int(P0[lo.OFF_KF])
        P[k:k + KALMAN_VALUES] = P0[k:k + KALMAN_VALUES]


def box_corners(d: int) -> np.ndarray:
    """Corners of a box of ``d`` keys (rows of 0, a key's lowest value, and 1, its highest) in
    which every pair of keys takes its four combinations: all four corners for two keys, four
    rows up to three keys, five for four, six up to ten, seven up to fifteen.

    Rows ``n`` of a binary covering array of strength 2: the first row all 0, each key's column
    a distinct choice of ``ceil(n/2)`` of the other ``n - 1`` rows set to 1 (two such choices
    differ both ways, and meet, as ``2 ceil(n/2) > n - 1``), with the smallest ``n`` giving
    ``d`` choices.
    """
    if d < 1:
        return np.zeros((1, 0), dtype=np.int64)
    n = 2
    while math.comb(n - 1, (n + 1) // 2) < d:
        n += 1
    out = np.zeros((n, d), dtype=np.int64)
    for k, ones in zip(range(d), itertools.combinations(range(1, n), (n + 1) // 2)):
        out[list(ones), k] = 1
    return out


def _box(X) -> np.ndarray:
    """The :func:`box_corners` of the box the variants ``X`` (n, keys) span, as variants."""
    return np.where(box_corners(X.shape[1]) > 0, X.max(axis=0), X.min(axis=0))


class _Builds:
    """:meth:`ToleranceRows._outputs` of variants, each built once (the fit, its checks and
    the rows' verification share them)."""

    def __init__(self, rows):
        self.rows, self.done = rows, {}

    def __call__(self, X) -> np.ndarray:
        out = []
        for x in np.atleast_2d(np.asarray(X, float)):
            key = x.tobytes()
            if key not in self.done:
                self.done[key] = self.rows._outputs(x[None])[0]
            out.append(self.done[key])
        return np.array(out)

    def buildable(self, C) -> np.ndarray:
        """The variants of ``C`` that make a model of the nominal one's structure (built here)."""
        keep = []
        for x in C:
            try:
                self(x[None])
            except SceneError:
                continue
            keep.append(x)
        return np.array(keep, float).reshape(-1, C.shape[1])


def _primaries(model, scene) -> np.ndarray:
    P, T = model.P, model.T
    grid = P[lo.TAB_LO] + P[lo.TAB_H] * np.arange(int(P[lo.TAB_N]))
    j0 = float(np.interp(model.q0, grid, T[lo.T_J] + P[lo.JL]))
    k0 = 0.0 if model.rigid else float(np.interp(model.q0, grid, T[lo.T_K]))
    drive = scene.drivetrain
    zeta = float(model.damping.get("two_mass_ratio", model.options.damping_ratio))  # the chain's lowest mode's
    return np.array([j0, P[lo.JL], k0, 2.0 * P[lo.HALF_PLAY], drive.efficiency, drive.backdrive_efficiency, zeta])


@dataclass(frozen=True)
class ToleranceRows:
    """Rows of variants of scene keys ``names`` (see the module notes).

    Attributes
    ----------
    model : Model
        The nominal model.
    P0 : numpy.ndarray
        Its parameters with the reference filled.
    names : tuple of str
        Varied keys, in column order (``drivetrain.stiffness_scale`` scales
        ``options.stiffness_scale``).
    fitted : SeparableFit or None
        None: every variant is built exactly.
    error : float
        Largest verified relative error of the fitted rows (0 when exact).
    inert : tuple of str
        Keys that move no slot and no table entry: the model as run does not depend on them.
    table_moves : bool
        Some key moves the stroke tables (each variant then carries its own).
    """

    model: object
    P0: np.ndarray
    names: tuple
    keys: object
    controller: object
    options: object
    reference: object
    fitted: object = None
    error: float = 0.0
    inert: tuple = ()
    table_moves: bool = False
    evaluations: int = 0

    @classmethod
    def create(cls, scene, keys, values: dict, controller, options, reference, *, rtol: float = DEFAULT_RTOL,
               seed: int = 0, points=GRID_POINTS, grade: dict | None = None) -> "ToleranceRows":
        """Build the nominal model, fit the rows over ``values`` (key -> array) and verify
        them; ``keys`` is the scene's :class:`~servo_toolkit.scene.key_paths.SceneKeys`.
        ``points`` and ``grade`` (key -> length) set the exact evaluations along each key
        (:func:`~servo_toolkit.core.separable.fit`)."""
        names = tuple(values)
        model = build_model(scene, controller, options)
        P0 = fill(model, reference)
        base = cls(model, P0, names, keys, controller, options, reference)
        X = np.column_stack([np.asarray(values[k], float) for k in names])
        x0 = np.array([base._nominal(k) for k in names])
        nP, nT = P0.size, model.T.size

        derived = list(CONTROLLER_SLOTS) + ([lo.INV_L, lo.ETA_MEAN, lo.ETA_HALF, lo.HOLD_FWD, lo.HOLD_BACK] +
                                            (list(DERIVED_SLOTS) if P0[lo.NMID] == 0 else []))

        def scale(Y):  # a slot's own magnitude; a table entry's row's; recomputed slots not judged
            mag = np.max(np.abs(np.where(np.isfinite(Y), Y, 0.0)), axis=0)
            t = mag[nP:nP + nT].reshape(model.T.shape)
            mag[nP:nP + nT] = np.repeat(t.max(axis=1), model.T.shape[1])
            mag[derived] = np.inf
            return mag

        integer = np.array([k in keys.known() and keys.resolve(k).integer for k in names])
        log_keys = np.array([np.all(X[:, j] > 0) and X[:, j].max() > 10 * X[:, j].min() for j in range(len(names))])
        grades = np.array([float((grade or {}).get(k, 0.0)) for k in names])
        exact = _Builds(base)
        f = fit(exact, x0, X, integer=integer, log_keys=log_keys, rtol=rtol, seed=seed, scale=scale,
                points=points, grade=grades, checks=exact.buildable(_box(X)))
        moved = f.moved
        inert = tuple(k for j, k in enumerate(names) if not np.any(moved[j]))
        table_moves = bool(np.any(moved[:, nP:nP + nT]))
        rows = replace(base, fitted=f, inert=inert, table_moves=table_moves)
        try:
            error = rows.verify(X, seed=seed + 1, exact=exact)
        except (ValueError, ZeroDivisionError):  # fitted primaries out of their domain (a negative stiffness)
            error = float("inf")
        if not error <= rtol:
            return replace(rows, fitted=None, error=error, evaluations=len(exact.done))
        return replace(rows, error=error, evaluations=len(exact.done))

    def _nominal(self, key: str) -> float:
        from ..scene.tolerances import STIFFNESS_SCALE
        return 1.0 if key == STIFFNESS_SCALE else self.keys.resolve(key).value

    def _split(self, x):
        from ..scene.tolerances import STIFFNESS_SCALE
        values = {k: v for k, v in zip(self.names, x) if k != STIFFNESS_SCALE}
        scale = float(dict(zip(self.names, x)).get(STIFFNESS_SCALE, 1.0))
        return values, replace(self.options, stiffness_scale=self.options.stiffness_scale * scale)

    def exact_model(self, x):
        """The variant ``x`` (one value per key) built by :func:`build_model`, and its row
        with the nominal controller."""
        values, options = self._split(x)
        scene = self.keys.scene(values)
        m = build_model(scene, self.controller, options)
        if m.P.size != self.P0.size or m.T.shape != self.model.T.shape or m.rigid != self.model.rigid:
            raise SceneError("tolerances", "a variant changes the model's structure (its compliances, lost motion "
                                           f"or packed blocks) at {dict(zip(self.names, np.round(x, 6)))}")
        P = fill(m, self.reference)
        _controller_copy(P, self.P0)
        return m, P, scene

    def _outputs(self, X):
        out = []
        for x in np.atleast_2d(X):
            m, P, scene = self.exact_model(x)
            out.append(np.concatenate([P, m.T.ravel(), _primaries(m, scene)]))
        return np.array(out)

    def rows(self, X):
        """``(P, T, tix)`` of the variants ``X`` (n, keys): parameters (n, nP), tables
        (k, rows, points) and each variant's table index."""
        X = np.atleast_2d(np.asarray(X, float))
        n = X.shape[0]
        if self.fitted is None:
            built = [self.exact_model(x) for x in X]
            return np.stack([b[1] for b in built]), np.stack([b[0].T for b in built]), np.arange(n)
        Y = self.fitted(X)
        nP, nT = self.P0.size, self.model.T.size
        P = Y[:, :nP].copy()
        prim = Y[:, nP + nT:]
        for i in range(n):
            self._derived(P[i], prim[i], X[i])
            _controller_copy(P[i], self.P0)
        if self.table_moves:
            return P, Y[:, nP:nP + nT].reshape((n,) + self.model.T.shape), np.arange(n)
        return P, self.model.T[None], np.zeros(n, dtype=np.int64)

    def _derived(self, P, prim, x) -> None:
        """The slots that follow from the primaries, by the model's own code."""
        _, options = self._split(x)
        j0, jl, k0, play, eta, eta_b, zeta = prim
        if P[lo.NMID] == 0:
            drivetrain_slots(P, rigid=self.model.rigid, j0_tot=j0, jl=0.0 if self.model.rigid else jl, k0=k0,
                             options=options, play=play, zeta=zeta)
        P[lo.INV_L] = 1.0 / P[lo.L] if P[lo.L] > 0 else 0.0
        if self.P0[lo.ETA_MEAN] != 0 or self.P0[lo.ETA_HALF] != 0:
            c_drive, c_back = 1.0 - eta, 1.0 / max(eta_b, MIN_BACKDRIVE) - 1.0
            P[lo.ETA_MEAN], P[lo.ETA_HALF] = 0.5 * (c_drive + c_back), 0.5 * (c_drive - c_back)
            hold_slots(P, eta, eta_b)

    def check_variants(self, X, seed: int = 1, random: int = 2) -> np.ndarray:
        """The variants :meth:`verify` builds exactly: of ``X`` (n, keys) the one farthest from
        the nominal one and ``random`` random ones, and the corners of the box ``X`` spans
        (:func:`box_corners`), each once."""
        X = np.atleast_2d(np.asarray(X, float))
        x0 = np.array([self._nominal(k) for k in self.names])
        span = np.ptp(X, axis=0)
        far = int(np.argmax(np.sum(np.abs(X - x0) / np.where(span > 0, span, 1.0), axis=1)))
        picks = sorted({far, *np.random.default_rng(seed).choice(X.shape[0], size=min(random, X.shape[0]),
                                                                  replace=False).tolist()})
        return np.unique(np.vstack([X[picks], _box(X)]), axis=0)

    def verify(self, X, seed: int = 1, random: int = 2, exact=None) -> float:
        """Largest relative difference between :meth:`rows` and :func:`build_model` on
        :meth:`check_variants` (each slot relative to its magnitude, each table entry to its
        row's). A corner that is no variant of ``X`` and makes no model of the nominal one's
        structure (keys whose rules bind each other at their ends, such as a static friction
        below a Coulomb friction) is left out; ``exact``: the exact outputs of variants
        (default :meth:`_outputs`: built here)."""
        X = np.atleast_2d(np.asarray(X, float))
        exact = self._outputs if exact is None else exact
        C = self.check_variants(X, seed, random)
        P, T, tix = self.rows(C)
        nP, shape = self.P0.size, self.model.T.shape
        worst = 0.0
        for r, x in enumerate(C):
            try:
                y = exact(x[None])[0]
            except SceneError:
                if np.any(np.all(X == x, axis=1)):
                    raise
                continue
            Pe, Te = y[:nP], y[nP:nP + int(np.prod(shape))].reshape(shape)
            worst = max(worst, _relative(P[r], Pe), _relative(T[tix[r]], Te, rows=True))
        return worst


def _relative(a, b, rows: bool = False) -> float:
    """Largest |a - b| relative to b's magnitude (per slot, or per table row)."""
    same = (a == b) | (np.isnan(a) & np.isnan(b))
    if np.all(same):
        return 0.0
    with np.errstate(invalid="ignore"):
        gap = np.where(same, 0.0, np.abs(a - b))
        mag = np.abs(np.where(np.isfinite(b), b, 0.0))
        if rows:
            mag = np.broadcast_to(mag.max(axis=-1, keepdims=True), mag.shape)
        rel = gap / np.where(mag > 0, mag, 1.0)
    return float(np.nanmax(np.where(np.isfinite(rel), rel, np.inf)))


__all__ = ["CONTROLLER_SLOTS", "PRIMARIES", "ToleranceRows", "box_corners", "keep_effects"]
