"""Margins over parameter variations (load inertia, drivetrain stiffness, or any scene key
a ``[tolerances]`` table varies), vectorized.

Every variant's open loop is evaluated on one frequency grid as array arithmetic with the
closed-form plant responses (:mod:`.response`) of its lumped plant (:mod:`.variant_plants`)
and the designed controller's response, computed once (:mod:`.variant_loops`); closed-loop
stability comes from the eigenvalues of the batched closed-loop matrices (:mod:`.assembly`).
:func:`reference_loop` builds one variant's loop as a state-space block by interconnection
instead (what a robust design's worst case is confirmed on), and :func:`reference_margins`
takes python-control's margins of it, for checks and for the benchmark.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ..errors import SceneError
from ..lti.system import ss
from ..core.parallel import chunks, run_cases
from ..plant.linear import DEFAULT_STRUCTURAL_DAMPING, PLANT_OUTPUTS, plant_matrices, spring_damping
from .assembly import closed_loop_matrix, controller_matrices
from .closed_loop import open_loop_block_of
from .margins import frequency_grid
from .metrics import grid_figures
from .requirements import check
from .robustness_result import RobustnessResult
from .sampling import sample_variants as _sample
from .vary import PARAMETERS
from .variant_loops import VariantLoops, controller_blocks as _controller_blocks, variant_grid
from .variant_plants import mode_damping, batched_matrices, variant_plants

#: the ranges :func:`sample_variants` takes without a scene: the reference EMA's defaults (its
#: load of 1 kg*m^2 from none to four times, the series stiffness +-30 %)
DEFAULT_VARIATIONS = {"load_inertia": (0.0, 4.0), "stiffness": (0.7, 1.3)}

#: a scene without ``[robustness]`` varies its load inertia from none to this many times its own
DEFAULT_LOAD_FACTOR = 4.0


def default_variations(scene) -> dict:
    """The ranges a scene without ``[robustness]`` is varied over: its load inertia (mass, at
    an output travel) from 0 to :data:`DEFAULT_LOAD_FACTOR` times its own (the reference EMA's
    1 kg*m^2 gives 0..4 kg*m^2, a 0.2 kg*m^2 flap 0..0.8 kg*m^2) and the series stiffness
    0.7..1.3; a scene without load inertia varies the stiffness alone."""
    load = float(scene.load.inertia)
    out = {"load_inertia": (0.0, DEFAULT_LOAD_FACTOR * load)} if load > 0 else {}
    out["stiffness"] = DEFAULT_VARIATIONS["stiffness"]
    return out


def sample_variants(variants=None, samples: int = 1000, grid: bool = False, seed: int = 0) -> dict:
    """Arrays of parameter values (:func:`.sampling.sample_variants`: log spacing for positive
    ranges over a decade, the corners always in a Monte Carlo sample); default
    :data:`DEFAULT_VARIATIONS`."""
    out = _sample(variants, samples, grid, seed, defaults=DEFAULT_VARIATIONS)
    for k in out:
        if k not in PARAMETERS:
            raise SceneError(f"vary.{k}", f"unknown parameter; known: {sorted(PARAMETERS)}")
    return out


def varied_parameters(p, load, values: dict, i: int, zeta: float):
    """PlantParameters of variant ``i``."""
    delta = values["load_inertia"][i] - load if "load_inertia" in values else 0.0
    factor = values["stiffness"][i] if "stiffness" in values else 1.0
    J2 = p.J2 + delta
    K = p.K * factor
    return replace(p, J2=J2, K=K, c=float(spring_damping(p.J1, J2, K, zeta)))


def _evaluate(case):
    """Figures and stability of one chunk of variants (module level: picklable)."""
    cols, rigid, w = case["cols"], case["rigid"], case["w"]
    response = VariantLoops(cols, case["current_gains"], case["blocks"])
    n = cols["J1"].size
    L = response(np.arange(n)[:, None], w[None, :])
    figs = grid_figures(w, L, phase_freq=case["f_req"], response=response if case["refine"] else None)
    A, B, C, D = batched_matrices(cols, rigid)
    acl = closed_loop_matrix(A, B[..., :1], C[..., :3, :], D[..., :3, :1], *case["controller"])
    figs["max_pole_real"] = np.linalg.eigvals(acl).real.max(axis=-1)
    return figs


def batched_plant_matrices(p, J2, K, c):
    """:func:`plant_matrices` for arrays of J2, K, c (leading batch axis), the other fields
    those of ``p``."""
    n = np.asarray(J2).size
    cols = {k: np.full(n, float(getattr(p, k))) for k in ("J1", "b1", "b2", "kh", "N", "eta", "Kt", "Ke", "R", "L")}
    cols.update(J2=np.asarray(J2, float).ravel(), K=np.asarray(K, float).ravel() * np.ones(n),
                c=np.asarray(c, float).ravel() * np.ones(n))
    return batched_matrices(cols, p.rigid)


#: robust requirement -> (figure, worst is min or max)
_WORST = {"gain_margin": ("gain_margin_db", "min"), "phase_margin": ("phase_margin_deg", "min"),
          "sensitivity_peak": ("sensitivity_peak_db", "max"), "bandwidth": ("bandwidth_hz", "min"),
          "phase_lag_at_bandwidth": ("phase_lag_deg", "max")}


#: a robust requirement's figure when no variant is stable (those of an unstable loop in
#: :func:`.design.evaluate`): the row fails, on a figure rather than on NaN
_UNSTABLE_FIGURE = {"gain_margin": 0.0, "phase_margin": -math.inf, "sensitivity_peak": math.inf, "bandwidth": 0.0,
                   "phase_lag_at_bandwidth": math.inf}


def worst_cases(values: dict, figures: dict, requirements) -> tuple[list, dict]:
    """Checks of ``requirements`` (robust requirements, display units) against the worst
    variant of each, and the parameter values of that variant."""
    stable = figures["stable"]
    achieved, worst = {}, {}
    for r in requirements:
        if r.name == "stable_fraction":
            achieved[r.name] = float(np.mean(stable))
            k = int(np.argmax(figures["max_pole_real"]))
        else:
            key, kind = _WORST[r.name]
            if not np.any(stable):  # no stable variant: the unstable loop's figures, as the design's
                achieved[r.name] = _UNSTABLE_FIGURE[r.name]
                continue
            vals = figures[key]
            k = int(np.argmin(np.where(stable, vals, np.inf)) if kind == "min"
                    else np.argmax(np.where(stable, vals, -np.inf)))
            achieved[r.name] = float(vals[k])
        worst[r.name] = {name: float(v[k]) for name, v in values.items()}
    return check(requirements, achieved), worst


def robustness(scene, design_result, variants=None, *, samples: int = 1000, grid: bool = False, seed: int = 0,
               spec=None, requirements=None, executor=None, chunk_size: int = 2500, progress: bool = True,
               structural_damping: float = DEFAULT_STRUCTURAL_DAMPING, refine: bool = True,
               exact: bool = True) -> RobustnessResult:
    """Margins of ``design_result``'s controller over parameter variations.

    Parameters
    ----------
    scene : Scene
    design_result : DesignResult
    variants : dict, optional
        name -> (lo, hi) range or array of values; names ``load_inertia`` (kg*m^2) and
        ``stiffness`` (factor). Default: ``spec``'s ranges, else :func:`default_variations`
        (load inertia 0 .. 4 times the scene's, stiffness 0.7..1.3).
    samples : int
        Monte Carlo samples (or grid points in total with ``grid=True``) for ranges.
    grid : bool
    seed : int
    spec : Robustness, optional
        A scene's ``[robustness]``: its ranges, sampling and requirements (``variants``,
        ``samples``, ``grid`` and ``seed`` are then taken from it).
    requirements : list of Requirement, optional
        What the variants must achieve; default :func:`robust_requirements` of ``spec``
        (or of the default :class:`~servo_toolkit.scene.tables.Robustness`) and the design's
        nominal requirements.
    executor : concurrent.futures.Executor, optional
        Runs the chunks (e.g. a dask ``Client.get_executor()``).
    chunk_size : int
    progress : bool
    structural_damping : float
    refine : bool
        Solve every crossing, the sensitivity peak and the bandwidth to solver precision
        after the grid brackets them (default); ``False`` interpolates on the grid.
    exact : bool
        Build the variant each row is judged on from the scene (:func:`exact_worst`; default);
        ``False`` keeps every variant's closed-form plant (to test the evaluator against
        python-control on the same plant).

    Returns
    -------
    RobustnessResult
    """
    from ..scene.loader import Robustness
    from .requirements import robust_requirements
    if spec is not None:
        variants = spec.ranges if variants is None else variants
        samples, grid, seed = spec.samples, spec.method == "grid", spec.seed
    elif variants is None:
        variants = default_variations(scene)
    values = sample_variants(variants, samples, grid, seed)
    if requirements is None:
        requirements = robust_requirements(spec or Robustness(), design_result.requirements)
    figs = variant_figures(scene, design_result.parameters, design_result.controller, values,
                           _bandwidth_requirement(design_result), executor=executor, chunk_size=chunk_size,
                           progress=progress, structural_damping=structural_damping, refine=refine)
    if exact:
        figs = exact_worst(scene, design_result, values, figs, requirements, structural_damping, refine)
    checks, worst = worst_cases(values, figs, requirements)
    settings = {"method": "grid" if grid else "monte_carlo", "samples": int(samples), "seed": int(seed)}
    return RobustnessResult(scene.name, values, figs, checks, worst, settings, scene.drivetrain.output_unit,
                            scene.display)


#: rounds of confirming the worst variants exactly (a confirmed variant better than its
#: closed form can hand the worst figure to another variant, confirmed in the next round)
EXACT_ROUNDS = 3


def exact_worst(scene, design_result, values: dict, figs: dict, requirements, structural_damping: float,
                refine: bool = True) -> dict:
    """``figs`` with the variant giving each requirement's worst figure built exactly.

    The variants' plants are the design's two-mass plant with the load's inertia added to J2
    and K scaled (:func:`~.variant_plants.closed_form_plants`), which is fast but leaves the
    chain's reduction as it is at the nominal load. The variant each row is judged on is
    rebuilt from the scene with its load and stiffness (:func:`exact_parameters`, the tolerance
    study's exact corner) and its figures replace the closed form's, so a row never rests on
    an approximation at its worst variant. Only the robustness study's own variations
    (``load_inertia``, ``stiffness``) need it; others are built from the scene already."""
    if not set(values) <= {"load_inertia", "stiffness"} or not requirements:
        return figs
    from .variant_plants import FIELDS, VariantPlants, _plants_of
    from ..scene.loader import scene_keys
    from ..scene.tolerances import STIFFNESS_SCALE
    figs = {k: np.array(v, copy=True) for k, v in figs.items()}
    p0, done, keys = design_result.parameters, set(), scene_keys(scene)
    ratio = mode_damping(scene, p0, structural_damping)
    for _ in range(EXACT_ROUNDS):
        _, worst = worst_cases(values, figs, requirements)
        index = {name: int(np.flatnonzero(np.all([values[key] == v for key, v in at.items()], axis=0))[0])
                 for name, at in worst.items() if name != "stable_fraction"}  # a fraction over all variants
        todo = sorted(set(index.values()) - done)
        if not todo:
            break
        load = values.get("load_inertia", np.full(len(values[next(iter(values))]), scene.load.inertia))
        scale = values.get("stiffness", np.ones_like(load))
        rows = np.array([[getattr(exact_parameters(scene, p0, load[k], 1.0, structural_damping, keys), f)
                          for f in FIELDS] for k in todo], float)
        plants = VariantPlants(_plants_of(rows, {STIFFNESS_SCALE: scale[todo]}, p0, ratio), p0.rigid, "exact")
        exact = variant_figures(scene, p0, design_result.controller, {STIFFNESS_SCALE: scale[todo]},
                                _bandwidth_requirement(design_result), progress=False,
                                structural_damping=structural_damping, refine=refine, plants=plants)
        for key in figs:
            figs[key][todo] = exact[key]
        done.update(todo)
    return figs


def _bandwidth_requirement(design_result) -> float:
    return next(r.required for r in design_result.requirements if r.name == "bandwidth")


def variant_figures(scene, p, ctrl, values: dict, f_req: float, *, executor=None, chunk_size: int = 2500,
                    progress: bool = True, structural_damping: float = DEFAULT_STRUCTURAL_DAMPING,
                    points: int | None = None, refine: bool = True, plants=None) -> dict:
    """Figures of controller ``ctrl`` on every variant of plant parameters ``p`` (see
    :class:`RobustnessResult` ``figures``). The frequency grid brackets every crossing, the
    sensitivity peak and the bandwidth; with ``refine`` (default) each is then solved to
    solver precision with the closed-form loop response, otherwise it is interpolated on
    the grid. The grid is :func:`~.variant_loops.variant_grid` (fine over the variants'
    drivetrain modes and the controller's lightly damped poles and zeros, coarse elsewhere),
    or ``points`` log-spaced frequencies from 0.01 Hz to 5 kHz.

    ``values`` names the variations by the robustness study's names (``load_inertia``,
    ``stiffness``) or by scene key paths (:mod:`.variant_plants`); ``plants`` (a
    :class:`~.variant_plants.VariantPlants`) gives the variants' plants directly."""
    if plants is None:
        plants = variant_plants(scene, p, values, structural_damping)
    cols, n = plants.cols, plants.count
    blocks = _controller_blocks(ctrl)
    w = (variant_grid(cols, plants.rigid, blocks, f_req) if points is None else
         frequency_grid(f_min=0.01, f_max=5e3, points=points, extra=[f_req]))
    kp_i, ki_i = (ctrl.current_kp, ctrl.current_ki) if p.L > 0 else (0.0, 0.0)
    common = {"rigid": plants.rigid, "w": w, "blocks": blocks, "f_req": f_req, "refine": refine,
              "current_gains": (kp_i, ki_i), "controller": controller_matrices(ctrl, scene.motor)}
    cases = [dict(common, cols={k: v[i] for k, v in cols.items()}) for i in chunks(np.arange(n), chunk_size)]
    parts = run_cases(_evaluate, cases, executor=executor, progress=progress, description="robustness")
    figs = {k: np.concatenate([part[k] for part in parts]) for k in parts[0]}
    return {"gain_margin_db": np.abs(figs["gain_margin_db"]), "phase_margin_deg": figs["phase_margin_deg"],
            "sensitivity_peak_db": figs["sensitivity_peak_db"], "bandwidth_hz": figs["bandwidth_hz"],
            "phase_lag_deg": -figs["phase_at_freq_deg"], "max_pole_real": figs["max_pole_real"],
            "stable": figs["max_pole_real"] < 0}


def exact_parameters(scene, p0, load_inertia: float, stiffness: float = 1.0,
                     structural_damping: float = DEFAULT_STRUCTURAL_DAMPING, keys=None):
    """The plant parameters of one variant built from the scene: the design's reduction (at
    ``p0``'s operating point, rigid or two-mass) of the scene with the load's inertia
    ``load_inertia`` and every stiffness times ``stiffness``; the mode keeps the design's
    damping ratio (:func:`~.variant_plants.mode_damping`), as every variant does. ``keys``:
    the scene's key paths (:func:`~servo_toolkit.scene.loader.scene_keys`), read once by a
    caller building several."""
    from ..plant.linear import plant_parameters
    if keys is None:
        from ..scene.loader import scene_keys
        keys = scene_keys(scene)
    q = plant_parameters(keys.scene({"load.inertia": float(load_inertia)}), p0.q0,
                         "rigid" if p0.rigid else "two_mass", structural_damping)
    if q.rigid or not np.isfinite(q.K):
        return q
    K = q.K * stiffness
    return replace(q, K=K, c=float(spring_damping(q.J1, q.J2, K, mode_damping(scene, p0, structural_damping))))


def reference_loop(scene, design_result, load_inertia: float, stiffness: float = 1.0,
                   structural_damping: float = DEFAULT_STRUCTURAL_DAMPING, exact: bool = False):
    """The open loop of one variant as a state-space block (:mod:`servo_toolkit.lti`), built
    from its plant and the design's controller by interconnection, not by the vectorized
    evaluator's closed forms: on the variants' closed-form plant (:func:`varied_parameters`,
    what the vectorized figures use), or with ``exact`` on the plant built from the scene
    (:func:`exact_parameters`, what each row's worst variant is judged on)."""
    p0 = design_result.parameters
    if exact:
        p = exact_parameters(scene, p0, load_inertia, stiffness, structural_damping)
    else:
        values = {"load_inertia": np.array([load_inertia]), "stiffness": np.array([stiffness])}
        p = varied_parameters(p0, scene.load.inertia, values, 0, mode_damping(scene, p0, structural_damping))
    A, B, C, D, states = plant_matrices(p)
    g = ss(A, B, C, D, inputs=["u", "tau_ext"], outputs=list(PLANT_OUTPUTS), states=states)
    return open_loop_block_of(g, design_result.controller, scene.motor)


def reference_margins(scene, design_result, load_inertia: float, stiffness: float = 1.0,
                      structural_damping: float = DEFAULT_STRUCTURAL_DAMPING, exact: bool = False):
    """python-control's ``stability_margins`` (gm, pm, sm, wpc, wgc, wms) of one variant and
    its open loop as a python-control system (the slow, independent path; the loop is
    :func:`reference_loop`'s)."""
    import control as ct
    loop = reference_loop(scene, design_result, load_inertia, stiffness, structural_damping, exact).to_control()
    return ct.stability_margins(loop), loop
