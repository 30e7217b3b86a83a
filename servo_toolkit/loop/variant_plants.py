"""The lumped linear plant of every parameter variant, as arrays (its open loop:
:mod:`.variant_loops`).

Variants are named two ways:

- the robustness study's names (``check --vary``, ``[robustness]``): ``load_inertia``
  replaces the load's inertia (added to the load side, J2) and ``stiffness`` multiplies the
  two-mass model's stiffness K, in closed form;
- scene key paths (``motor.resistance``, ``drivetrain[3].stiffness``, ``load.inertia``, the
  virtual ``drivetrain.stiffness_scale``: a factor on K), as a scene's ``[tolerances]`` draws
  them. Motor keys enter the plant directly; drivetrain and load keys move the inertias,
  stiffness, ratio and efficiency through the whole drivetrain. Building and reducing the
  scene costs ~15 ms a variant, so every :class:`~servo_toolkit.plant.linear.PlantParameters`
  field is mapped from the keys by :func:`servo_toolkit.core.separable.fit` (one-key exact
  maps in the field's natural coordinate, pair terms where needed), verified against exact
  builds of the farthest and of random variants; above :data:`SEPARABLE_RTOL` every variant
  is built exactly instead. A key that moves no field (Coulomb friction, a voltage limit,
  a backlash, an encoder) leaves every margin exactly as it is: it is listed as such, not
  estimated.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import SceneError
from ..core.separable import DEFAULT_RTOL
from ..plant.linear import plant_matrices, plant_parameters, spring_damping, two_mass_damping

#: the mapped fields of :class:`~servo_toolkit.plant.linear.PlantParameters` (c follows from
#: J1, J2, K and the structural damping)
FIELDS = ("J1", "J2", "K", "b1", "b2", "kh", "N", "eta", "Kt", "Ke", "R", "L")
#: largest relative error of the separable maps, verified against exact builds, for which
#: they replace building every variant: a relative error e in K moves the drivetrain mode by
#: e/2, i.e. 5e-5 at this bound, far below the two-mass reduction's own approximation of the
#: chain and the resolution of any figure the margins report
SEPARABLE_RTOL = DEFAULT_RTOL
#: the robustness study's variation names
LEGACY = ("load_inertia", "stiffness")


@dataclass(frozen=True)
class VariantPlants:
    """Plant parameters of ``n`` variants: one array per field.

    Attributes
    ----------
    cols : dict of numpy.ndarray
        :data:`FIELDS` and ``c``, each (n,).
    rigid : bool
    method : str
        ``"closed form"``, ``"separable"`` (maps verified against exact builds) or
        ``"exact"`` (every variant built).
    error : float
        Largest relative error of the maps on the verification variants (0 closed form or
        exact).
    inert : tuple of str
        Keys that move no field: the linear loop does not depend on them.
    evaluations : int
        Exact scene builds spent.
    mapper : callable or None
        ``mapper(values)`` -> the VariantPlants of other variants of the same keys (by the
        same verified maps; None when every variant was built exactly).
    """

    cols: dict
    rigid: bool
    method: str = "closed form"
    error: float = 0.0
    inert: tuple = ()
    evaluations: int = 0
    mapper: object = field(default=None, repr=False, compare=False)

    @property
    def count(self) -> int:
        return int(self.cols["J1"].size)

    def rows(self, rows) -> dict:
        """The fields of variants ``rows`` (any index array)."""
        return {k: v[rows] for k, v in self.cols.items()}


def mode_damping(scene, p, zeta: float) -> float:
    """The damping ratio of the two-mass mode of ``p`` when each compliance whose stage gives
    none has ``zeta``: the chain's lowest mode's (:func:`~servo_toolkit.plant.linear.two_mass_damping`,
    as :func:`~servo_toolkit.plant.linear.plant_parameters` gives the design's plant); a
    variant keeps it."""
    return 0.0 if p.rigid or not np.isfinite(p.K) else two_mass_damping(scene.drivetrain.chain, p.q0, zeta)


def _with_damping(cols: dict, zeta: float) -> dict:
    cols["c"] = np.broadcast_to(spring_damping(cols["J1"], cols["J2"], cols["K"], zeta), cols["J1"].shape).copy()
    return cols


def _nominal(p, n: int) -> dict:
    return {k: np.full(n, float(getattr(p, k))) for k in FIELDS}


def closed_form_plants(p, load_inertia: float, values: dict, zeta: float) -> VariantPlants:
    """Variants by the robustness study's names: ``load_inertia`` (the load's inertia,
    replacing ``load_inertia``) and ``stiffness`` (a factor on K)."""
    n = next(iter(values.values())).size
    cols = _nominal(p, n)
    if "load_inertia" in values:
        delta = values["load_inertia"] - load_inertia
        cols["J1" if p.rigid else "J2"] = cols["J1" if p.rigid else "J2"] + delta
        if np.any(cols["J2"] < 0) if not p.rigid else np.any(cols["J1"] <= 0):
            raise SceneError("vary.load_inertia", "gives a negative load-side inertia")
    if "stiffness" in values:
        cols["K"] = cols["K"] * values["stiffness"]
    return VariantPlants(_with_damping(cols, zeta), p.rigid)


def _exact_rows(keys, names, p, zeta):
    """``evaluate(X)`` of the fields from built scenes (``names`` are the scene keys)."""
    model = "rigid" if p.rigid else "two_mass"

    def evaluate(X):
        out = np.empty((X.shape[0], len(FIELDS)))
        for r, x in enumerate(np.atleast_2d(X)):
            scene = keys.scene(dict(zip(names, x)))
            q = plant_parameters(scene, p.q0, model, zeta)
            out[r] = [getattr(q, k) for k in FIELDS]
        return out
    return evaluate


def keyed_plants(scene, p, values: dict, zeta: float, keys=None, rtol: float = SEPARABLE_RTOL,
                 progress: bool = False, exact: bool = False) -> VariantPlants:
    """Variants by scene key paths (see the module notes).

    Parameters
    ----------
    scene : Scene
    p : PlantParameters
        The design's plant (its operating point and reduction).
    values : dict
        Key path -> values (n,), SI; ``drivetrain.stiffness_scale`` multiplies K.
    zeta : float
        Structural damping ratio.
    keys : SceneKeys, optional
        Default: the scene's tolerances' (or its file's).
    rtol : float
        Largest verified relative error of the maps (else every variant is built).
    progress : bool
    exact : bool
        Build every variant exactly, without fitting maps (a few variants, e.g. the corners
        of a study whose maps did not verify).
    """
    from ..core.separable import fit
    from ..scene.tolerances import STIFFNESS_SCALE
    n = next(iter(values.values())).size
    names = [k for k in values if k != STIFFNESS_SCALE]
    method, error, inert, spent, f = "closed form", 0.0, (), 0, None
    if STIFFNESS_SCALE in values and p.rigid:
        inert = (STIFFNESS_SCALE,)
    Y = np.array([[getattr(p, k) for k in FIELDS]] * n, float)
    if names:
        if keys is None:
            from ..scene.loader import scene_keys
            keys = scene_keys(scene)
        _refuse_inductance(p, names)
        X = np.column_stack([np.asarray(values[k], float) for k in names])
        x0 = np.array([keys.resolve(k).value for k in names])
        evaluate = _exact_rows(keys, names, p, zeta)
        log_keys = np.array([np.all(X[:, j] > 0) and X[:, j].max() > 10 * X[:, j].min() for j in range(len(names))])
        integer = np.array([keys.resolve(k).integer for k in names])
        if not exact:
            f = fit(evaluate, x0, X, integer=integer, log_keys=log_keys, rtol=rtol)
            spent, error = f.evaluations, f.error
            inert += tuple(k for j, k in enumerate(names) if not np.any(f.moved[j]))
        if f is not None and error <= rtol:
            Y, method = f(X), "separable"
        else:
            from ..core.progress import progress_bar
            Y, f = np.empty((n, len(FIELDS))), None
            with progress_bar(total=n, desc="plants", show=progress) as bar:
                for i in range(n):
                    Y[i] = evaluate(X[i:i + 1])[0]
                    bar.update(1)
            method, spent = "exact", spent + n
    from dataclasses import replace
    ratio = mode_damping(scene, p, zeta)
    result = VariantPlants(_plants_of(Y, values, p, ratio), p.rigid, method, float(error), inert, spent)
    if f is None and names:
        return result

    box = (X.min(axis=0), X.max(axis=0)) if names else None

    def mapper(other, _f=f, _names=tuple(names)):
        m = next(iter(other.values())).size
        if not _names:
            return replace(result, cols=_plants_of(np.array([[getattr(p, k) for k in FIELDS]] * m, float),
                                                   other, p, ratio))
        Xo = np.column_stack([np.asarray(other[k], float) for k in _names])
        Yo = _f(Xo)
        # the maps are verified over the sampled box only: a point beyond it (a range's end that
        # no sample reached, a corner) or one the maps cannot place is built exactly
        beyond = np.any((Xo < box[0]) | (Xo > box[1]), axis=1) | ~np.all(np.isfinite(Yo), axis=1)
        if np.any(beyond):
            Yo[beyond] = evaluate(Xo[beyond])
        return replace(result, cols=_plants_of(Yo, other, p, ratio))
    return replace(result, mapper=mapper)


def _plants_of(Y, values, p, zeta) -> dict:
    """The field columns of mapped rows ``Y`` (K scaled by a stiffness factor, c derived)."""
    from ..scene.tolerances import STIFFNESS_SCALE
    cols = {k: Y[:, j].copy() for j, k in enumerate(FIELDS)}
    if np.any(np.isfinite(cols["K"]) != np.isfinite(p.K)):
        raise SceneError("tolerances", "some variants change whether the drivetrain is compliant")
    if STIFFNESS_SCALE in values:
        cols["K"] = cols["K"] * np.asarray(values[STIFFNESS_SCALE], float)
    return _with_damping(cols, zeta)


def _refuse_inductance(p, names) -> None:
    if p.L <= 0 and "motor.inductance" in names:
        raise SceneError("tolerances.motor.inductance", "the design's current loop is ideal (the motor has no "
                         "inductance): give the motor an inductance to tolerance it")


def variant_plants(scene, p, values: dict, zeta: float, **kw) -> VariantPlants:
    """:func:`closed_form_plants` for the robustness study's names, :func:`keyed_plants`
    for scene key paths (not both at once)."""
    legacy = [k for k in values if k in LEGACY]
    if legacy and len(legacy) != len(values):
        other = next(k for k in values if k not in LEGACY)
        raise SceneError(f"vary.{other}", f"use either {list(LEGACY)} or scene key paths, not both")
    if legacy:
        return closed_form_plants(p, scene.load.inertia, values, mode_damping(scene, p, zeta))
    return keyed_plants(scene, p, values, zeta, **kw)


def batched_matrices(cols: dict, rigid: bool, inductance: bool = True):
    """:func:`~servo_toolkit.plant.linear.plant_matrices` of every variant: (A, B, C, D)
    with a leading batch axis, built from the field arrays."""
    J1, J2, K, c, b1, b2, kh, N, eta, Kt, Ke, R, L = (np.asarray(cols[k], float) for k in
                                                    ("J1", "J2", "K", "c", "b1", "b2", "kh", "N", "eta", "Kt",
                                                     "Ke", "R", "L"))
    n = J1.size
    kt = eta * N * Kt
    ind = inductance and bool(np.all(L > 0))
    if rigid:
        J = J1 + J2
        nm, w1 = 2, 1
        A = np.zeros((n, 2, 2))
        A[:, 0, 1] = 1.0
        A[:, 1, 0], A[:, 1, 1] = -kh / J, -(b1 + b2) / J
        B = np.zeros((n, 2, 2))
        B[:, 1, 1] = 1 / J
        C = np.zeros((n, 4, 2))
        C[:, 0, 0], C[:, 1, 1], C[:, 3, 1] = 1.0, N, 1.0
        jm = J
    else:
        nm, w1 = 4, 1
        A = np.zeros((n, 4, 4))
        A[:, 0, 1] = A[:, 2, 3] = 1.0
        A[:, 1, 0], A[:, 1, 1], A[:, 1, 2], A[:, 1, 3] = -K / J1, -(c + b1) / J1, K / J1, c / J1
        A[:, 3, 0], A[:, 3, 1], A[:, 3, 2], A[:, 3, 3] = K / J2, c / J2, -(K + kh) / J2, -(c + b2) / J2
        B = np.zeros((n, 4, 2))
        B[:, 3, 1] = 1 / J2
        C = np.zeros((n, 4, 4))
        C[:, 0, 2], C[:, 1, 1], C[:, 3, 3] = 1.0, N, 1.0
        jm = J1
    D = np.zeros((n, 4, 2))
    if ind:
        A = np.pad(A, ((0, 0), (0, 1), (0, 1)))
        B = np.pad(B, ((0, 0), (0, 1), (0, 0)))
        C = np.pad(C, ((0, 0), (0, 0), (0, 1)))
        A[:, w1, nm] = kt / jm
        A[:, nm, w1] = -Ke * N / L
        A[:, nm, nm] = -R / L
        B[:, nm, 0] = 1 / L
        C[:, 2, nm] = 1.0
    else:
        A[:, w1, w1] -= kt * Ke * N / (R * jm)
        B[:, w1, 0] += kt / (R * jm)
        C[:, 2, w1] = -Ke * N / R
        D[:, 2, 0] = 1 / R
    return A, B, C, D


def reference_plant(cols: dict, i: int, q0: float = 0.0):
    """PlantParameters of variant ``i`` (for python-control checks)."""
    from ..plant.linear import PlantParameters
    return PlantParameters(**{k: float(cols[k][i]) for k in FIELDS}, c=float(cols["c"][i]), q0=q0)


def check_matrices(cols, rigid, i: int = 0) -> float:
    """Largest difference between :func:`batched_matrices` and ``plant_matrices`` of
    variant ``i`` (a self-check used by the tests)."""
    batched = batched_matrices(cols, rigid)
    single = plant_matrices(reference_plant(cols, i))
    return max(float(np.max(np.abs(b[i] - s_))) if b[i].shape == s_.shape else math.inf
               for b, s_ in zip(batched, single[:4]))


__all__ = ["FIELDS", "LEGACY", "SEPARABLE_RTOL", "VariantPlants", "batched_matrices", "closed_form_plants",
           "keyed_plants", "reference_plant", "variant_plants"]
