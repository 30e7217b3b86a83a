"""Margins over parameter variations (load inertia, drivetrain stiffness), vectorized.

Every variant's open loop is evaluated on one frequency grid as array arithmetic with the
closed-form plant responses (:mod:`.response`) and the designed controller's response,
computed once; closed-loop stability comes from the eigenvalues of the batched closed-loop
matrices (:mod:`.assembly`). :func:`reference_margins` does the same for one variant with
python-control, for checks and for the benchmark.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import control as ct
import numpy as np

from ..errors import SceneError
from ..core.output_units import OutputUnit
from ..core.parallel import chunks, run_cases
from ..plant.linear import DEFAULT_STRUCTURAL_DAMPING, PLANT_OUTPUTS, plant_matrices, sample_delay, spring_damping
from .assembly import _abcd, closed_loop_matrix, controller_matrices
from .closed_loop import DELAY_SAMPLES, open_loop_of
from .margins import frequency_grid
from .metrics import grid_figures
from .requirements import check
from .response import loop_response, plant_responses, state_space_response
from .sampling import sample_variants as _sample
from .vary import PARAMETERS, parse_vary, ranges_text, variant_text
from ..display.cards import RichDisplay
from ..display.cards import card, facts, requirements_table, svg
from ..display.html import fmt
from ..display.units import DisplayUnits

DEFAULT_VARIATIONS = {"load_inertia": (0.0, 4.0), "stiffness": (0.7, 1.3)}


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
    p, J2, K, c = case["p"], case["J2"], case["K"], case["c"]
    w = case["w"]
    response = VariantLoops(p, J2, K, c, case["current_gains"], case["blocks"])
    L = response(np.arange(J2.size)[:, None], w[None, :])
    figs = grid_figures(w, L, phase_freq=case["f_req"], response=response if case["refine"] else None)
    A, B, C, D = batched_plant_matrices(p, J2, K, c)
    acl = closed_loop_matrix(A, B[..., :1], C[..., :3, :], D[..., :3, :1], *case["controller"])
    figs["max_pole_real"] = np.linalg.eigvals(acl).real.max(axis=-1)
    return figs


@dataclass(frozen=True)
class VariantLoops:
    """The open loop of every variant as a function of frequency, closed form (see
    :mod:`.response`): ``self(rows, w)`` is ``L`` of variants ``rows`` at angular
    frequencies ``w`` (arrays broadcasting together)."""

    p: object
    J2: np.ndarray
    K: np.ndarray
    c: np.ndarray
    current_gains: tuple
    blocks: tuple  # (motion A, B [theta, omega_m], C, D), (delay A, B, C, D)

    def __call__(self, rows, w):
        s = 1j * np.asarray(w, float)
        rows = np.asarray(rows)
        P1, P2 = plant_responses(s, self.p, *self.current_gains, J2=self.J2[rows], K=self.K[rows],
                                 c=self.c[rows])
        cy, cw, delay = _controller_response(self.blocks, s)
        return loop_response(s, P1, P2, delay, cy, cw, self.p.N)


def batched_plant_matrices(p, J2, K, c):
    """:func:`plant_matrices` for arrays of J2, K, c (leading batch axis). A two-mass plant
    only changes in its two mechanical rows; a rigid one is built variant by variant."""
    if p.rigid:
        mats = [plant_matrices(replace(p, J2=float(a), K=float(b), c=float(d))) for a, b, d in zip(J2, K, c)]
        return tuple(np.stack([m[k] for m in mats]) for k in range(4))
    A0, B0, C0, D0, _ = plant_matrices(p)
    n = J2.size
    A = np.repeat(A0[None], n, axis=0)
    B = np.repeat(B0[None], n, axis=0)
    electrical = A0[1, 1] + (p.c + p.b1) / p.J1  # back-emf damping without inductance
    A[:, 1, 0], A[:, 1, 1], A[:, 1, 2], A[:, 1, 3] = -K / p.J1, -(c + p.b1) / p.J1 + electrical, K / p.J1, c / p.J1
    A[:, 3, 0], A[:, 3, 1], A[:, 3, 2], A[:, 3, 3] = K / J2, c / J2, -(K + p.kh) / J2, -(c + p.b2) / J2
    B[:, 3, 1] = 1 / J2
    return A, B, np.repeat(C0[None], n, axis=0), np.repeat(D0[None], n, axis=0)


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
            lines.append(f"  worst {c.name:<24}{c.sense} {c.required:g} {c.unit}: {c.achieved:.4g} {c.unit} "
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


#: robust requirement -> (figure, worst is min or max)

    def _repr_line(self) -> str:
        return _card_line(self)

    def _repr_card(self) -> str:
        return _card_html(self)


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
               structural_damping: float = DEFAULT_STRUCTURAL_DAMPING, refine: bool = True) -> RobustnessResult:
    """Margins of ``design_result``'s controller over parameter variations.

    Parameters
    ----------
    scene : Scene
    design_result : DesignResult
    variants : dict, optional
        name -> (lo, hi) range or array of values; names ``load_inertia`` (kg*m^2) and
        ``stiffness`` (factor). Default: ``spec``'s ranges, else load inertia 0..4 kg*m^2,
        stiffness 0.7..1.3.
    samples : int
        Monte Carlo samples (or grid points in total with ``grid=True``) for ranges.
    grid : bool
    seed : int
    spec : Robustness, optional
        A scene's ``[robustness]``: its ranges, sampling and requirements (``variants``,
        ``samples``, ``grid`` and ``seed`` are then taken from it).
    requirements : list of Requirement, optional
        What the variants must achieve; default :func:`robust_requirements` of ``spec``
        (or of the default :class:`~servo_toolkit.scene.loader.Robustness`) and the design's
        nominal requirements.
    executor : concurrent.futures.Executor, optional
        Runs the chunks (e.g. a dask ``Client.get_executor()``).
    chunk_size : int
    progress : bool
    structural_damping : float
    refine : bool
        Solve every crossing, the sensitivity peak and the bandwidth to solver precision
        after the grid brackets them (default); ``False`` interpolates on the grid.

    Returns
    -------
    RobustnessResult
    """
    from ..scene.loader import Robustness
    from .requirements import robust_requirements
    if spec is not None:
        variants = spec.ranges if variants is None else variants
        samples, grid, seed = spec.samples, spec.method == "grid", spec.seed
    values = sample_variants(variants, samples, grid, seed)
    if requirements is None:
        requirements = robust_requirements(spec or Robustness(), design_result.requirements)
    figs = variant_figures(scene, design_result.parameters, design_result.controller, values,
                           _bandwidth_requirement(design_result), executor=executor, chunk_size=chunk_size,
                           progress=progress, structural_damping=structural_damping, refine=refine)
    checks, worst = worst_cases(values, figs, requirements)
    settings = {"method": "grid" if grid else "monte_carlo", "samples": int(samples), "seed": int(seed)}
    return RobustnessResult(scene.name, values, figs, checks, worst, settings, scene.drivetrain.output_unit,
                            scene.display)


def _bandwidth_requirement(design_result) -> float:
    return next(r.required for r in design_result.requirements if r.name == "bandwidth")


def variant_figures(scene, p, ctrl, values: dict, f_req: float, *, executor=None, chunk_size: int = 2500,
                    progress: bool = True, structural_damping: float = DEFAULT_STRUCTURAL_DAMPING,
                    points: int = 600, refine: bool = True) -> dict:
    """Figures of controller ``ctrl`` on every variant of plant parameters ``p`` (see
    :class:`RobustnessResult` ``figures``). The grid of ``points`` frequencies brackets
    every crossing, the sensitivity peak and the bandwidth; with ``refine`` (default) each
    is then solved to solver precision with the closed-form loop response, otherwise it is
    interpolated on the grid."""
    n = next(iter(values.values())).size
    J2 = p.J2 + (values["load_inertia"] - scene.load.inertia if "load_inertia" in values else np.zeros(n))
    if np.any(J2 < 0) if not p.rigid else np.any(p.J1 + J2 <= 0):  # rigid: the load is in J1
        raise SceneError("vary.load_inertia", "gives a negative load-side inertia")
    K = p.K * (values["stiffness"] if "stiffness" in values else np.ones(n))
    c = spring_damping(p.J1, J2, K, structural_damping) * np.ones(n)
    w = frequency_grid(f_min=0.01, f_max=5e3, points=points, extra=[f_req])
    kp_i, ki_i = (ctrl.current_kp, ctrl.current_ki) if p.L > 0 else (0.0, 0.0)
    common = {"p": p, "w": w, "blocks": _controller_blocks(ctrl), "f_req": f_req, "refine": refine,
              "current_gains": (kp_i, ki_i), "controller": controller_matrices(ctrl, scene.motor)}
    idx = np.arange(n)
    cases = [dict(common, J2=J2[i], K=K[i], c=c[i]) for i in chunks(idx, chunk_size)]
    parts = run_cases(_evaluate, cases, executor=executor, progress=progress, description="robustness")
    figs = {k: np.concatenate([part[k] for part in parts]) for k in parts[0]}
    return {"gain_margin_db": np.abs(figs["gain_margin_db"]), "phase_margin_deg": figs["phase_margin_deg"],
            "sensitivity_peak_db": figs["sensitivity_peak_db"], "bandwidth_hz": figs["bandwidth_hz"],
            "phase_lag_deg": -figs["phase_at_freq_deg"], "max_pole_real": figs["max_pole_real"],
            "stable": figs["max_pole_real"] < 0}


def _controller_blocks(ctrl):
    """State-space matrices of the motion controller from [theta, omega_m] to i_ref and of
    the sampling delay (Pade) from i_ref to i_cmd."""
    Am, Bm, Cm, Dm = _abcd(ctrl.motion)
    cols = [ctrl.motion.input_index[name] for name in ("theta", "omega_m")]
    return (Am, Bm[:, cols], Cm, Dm[:, cols]), _abcd(sample_delay(ctrl.sample_time, DELAY_SAMPLES))


def _controller_response(blocks, s):
    """Cy (from -theta), Cw (from -omega_m) and the delay at ``s``."""
    h = state_space_response(*blocks[0], s)
    d = state_space_response(*blocks[1], s)
    return -h[..., 0, 0], -h[..., 0, 1], d[..., 0, 0]


def reference_margins(scene, design_result, load_inertia: float, stiffness: float = 1.0,
                      structural_damping: float = DEFAULT_STRUCTURAL_DAMPING):
    """python-control's ``stability_margins`` (gm, pm, sm, wpc, wgc, wms) of one variant,
    building the plant and the loop as python-control objects (the slow, independent path)."""
    values = {"load_inertia": np.array([load_inertia]), "stiffness": np.array([stiffness])}
    p = varied_parameters(design_result.parameters, scene.load.inertia, values, 0, structural_damping)
    A, B, C, D, states = plant_matrices(p)
    g = ct.ss(A, B, C, D, inputs=["u", "tau_ext"], outputs=list(PLANT_OUTPUTS), states=states)
    loop = open_loop_of(g, design_result.controller, scene.motor)
    return ct.stability_margins(loop), loop


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
