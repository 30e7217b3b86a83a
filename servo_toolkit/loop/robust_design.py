"""Robust loop design: a cascade that keeps every parameter variant stable with margins.

Why the variations matter (physics)
-----------------------------------
The drivetrain's series compliance K joins the motor side J1 (rotor, gears and screw
reflected to the output, dominated by N^2 J_rotor) to the load side J2 (load and output
shaft). The two-mass mode is at

    f_r = sqrt(K (1/J1 + 1/J2)) / (2 pi)

and, seen from the load angle with the motor side held by a stiff speed loop, at the
anti-resonance f_a = sqrt(K / J2) / (2 pi). Both fall as the load inertia grows and scale
with sqrt(K). On the reference EMA (J1 = 4.4 kg m^2, K = 3.4e4 N m/rad at mid-stroke) a
load of 0..4 kg m^2 moves f_a from about 700 Hz down to 14.7 Hz, and f_r from about 700 Hz
to 20 Hz; a stiffness 30 % low takes them down to 12.3 and 17 Hz. The nominal design's
notch sits on the nominal anti-resonance (29 Hz at 1 kg m^2): for most variants it removes
gain where the mode no longer is, adds its phase lag below it, and leaves the moved,
lightly damped (2 %) mode unfiltered, so about three variants in four are unstable.

What the robust design does instead
-----------------------------------
It does not rely on cancelling the mode. A speed loop on the motor speed is a damper on
the motor side; it adds damping to the two-mass mode whatever J2 is (most when the speed
loop crosses over between f_a and f_r), and the position loop then crosses over below the
lowest anti-resonance of the range. The search scans the cascade (speed-loop crossover,
its integral corner, position gain) with no filter, a low-pass below the lowest mode and a
wide notch over the range of f_a, on a grid of variants that includes the corners of the
ranges, with the vectorized evaluator (:mod:`.response`, :mod:`.assembly`); it refines the
best starts with Nelder-Mead, then checks the chosen loop on the scene's own variants
(:func:`.robustness.robustness`) and adds any worse variant found there to the grid.

Priorities when not everything can be met: (1) the variants' stability
(``stable_fraction``), (2) the margins (worst case over the variants and nominal),
(3) performance (nominal bandwidth and phase lag, worst-case bandwidth if required). The
result always states which requirement fails and by how much.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import replace

import numpy as np
from scipy.optimize import minimize
from ..core.progress import progress_bar

from .controller import CascadeController
from ..lti.convert import ss2tf
from ..plant.current_loop import sample_delay_block
from ..plant.linear import spring_damping
from .assembly import closed_loop_matrix, controller_matrices
from .closed_loop import DELAY_SAMPLES
from .margins import frequency_grid
from .metrics import grid_figures
from .requirements import robust_requirements
from .response import loop_response, plant_responses
from .robustness import batched_plant_matrices, robustness, sample_variants
from .structures import Motion

FV_RATIOS = (0.7, 1.0, 1.4, 2.0, 2.8, 4.0)
"""Speed-loop crossover as multiples of the required bandwidth (coarse scan)."""
WVI_RATIOS = (0.05, 0.12, 0.3)
"""Speed PI integral corner as a fraction of the speed-loop crossover (coarse scan)."""
KP_SCAN = np.geomspace(0.12, 3.0, 18)
"""Position gain kp (1/s) as multiples of 2 pi times the required bandwidth."""
GRID_PER_AXIS = 5
"""Design-grid points per varied parameter (corners included), plus the nominal plant."""
MARGINS = ("gain_margin", "phase_margin", "sensitivity_peak")
PERFORMANCE = ("bandwidth", "phase_lag_at_bandwidth")


def mode_range(p, load_inertia: float, ranges: dict) -> dict:
    """Drivetrain resonance and anti-resonance (Hz) over the varied parameters.

    Parameters
    ----------
    p : PlantParameters
        Nominal plant parameters (two-mass).
    load_inertia : float
        The scene's load inertia (kg*m^2), included in ``p.J2``.
    ranges : dict
        ``load_inertia`` (kg*m^2) and/or ``stiffness`` (factor) as (lo, hi).

    Returns
    -------
    dict
        ``resonance_hz`` and ``antiresonance_hz`` as (lowest, highest) over the corners;
        sqrt(K (1/J1 + 1/J2)) and sqrt(K / J2) are monotonic in J2 and K, so the corners
        bound them.
    """
    if p.rigid:
        return {"resonance_hz": (math.inf, math.inf), "antiresonance_hz": (math.inf, math.inf)}
    loads = ranges.get("load_inertia", (load_inertia, load_inertia))
    factors = ranges.get("stiffness", (1.0, 1.0))
    fr, fa = [], []
    for lo in loads:
        J2 = p.J2 + lo - load_inertia
        for k in factors:
            K = p.K * k
            fr.append(math.sqrt(K * (1 / p.J1 + 1 / J2)) / (2 * math.pi) if J2 > 0 else math.inf)
            fa.append(math.sqrt(K / J2) / (2 * math.pi) if J2 > 0 else math.inf)
    return {"resonance_hz": (min(fr), max(fr)), "antiresonance_hz": (min(fa), max(fa))}


def _norm_slack(name, sense, required, achieved):
    """Normalized slack as in the nominal search (bandwidth: log ratio)."""
    a = np.asarray(achieved, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        if name == "bandwidth":
            sl = np.log(a / required)
        elif name == "stable_fraction":
            sl = a - required
        else:
            sl = (a - required if sense == ">=" else required - a) / max(abs(required), 1.0)
    return np.where(np.isfinite(sl), sl, np.where(sl > 0, 10.0, -10.0))


def _tier(stab, margin, perf):
    """One score from three slacks in priority order: unstable < margins missed <
    performance missed < everything met (then the smallest slack)."""
    stab, margin, perf = (np.asarray(x, float) for x in (stab, margin, perf))
    return np.where(stab < 0, -2.0 + stab / (1.0 - stab) - 1.0,
                    np.where(margin < 0, -1.0 + margin / (1.0 - margin),
                             np.where(perf < 0, perf / (1.0 - perf), np.minimum(margin, perf))))


class _Search:
    """The design grid, its precomputed plant responses, and candidate scoring."""

    def __init__(self, scene, p, nominal, robust, current_gains, sample_time, structural_damping):
        self.scene, self.p, self.nominal, self.robust = scene, p, nominal, robust
        self.current_gains, self.sample_time, self.zeta = current_gains, sample_time, structural_damping
        self.f_req = next(r.value for r in nominal if r.name == "bandwidth")
        self.w = frequency_grid(f_min=0.05, f_max=3e3, points=260, extra=[self.f_req])
        self.s = 1j * self.w
        d = sample_delay_block(sample_time, DELAY_SAMPLES)
        if d.nstates:
            self.delay_polys = tuple(np.ravel(x) for x in ss2tf(d))
        else:
            self.delay_polys = (np.ones(1), np.ones(1))
        self.delay = self.delay_at(self.s)

    def delay_at(self, s):
        """The sampling delay's Pade response at ``s``."""
        return np.polyval(self.delay_polys[0], s) / np.polyval(self.delay_polys[1], s)

    def set_variants(self, values: dict):
        """Variants as arrays, the nominal plant first."""
        p, load = self.p, self.scene.load.inertia
        n = next(iter(values.values())).size
        self.values = values
        self.J2 = p.J2 + (values["load_inertia"] - load if "load_inertia" in values else np.zeros(n))
        self.K = p.K * (values["stiffness"] if "stiffness" in values else np.ones(n))
        self.c = spring_damping(p.J1, self.J2, self.K, self.zeta) * np.ones(n)
        kp, ki = self.current_gains
        self.P1, self.P2 = plant_responses(self.s[None, :], p, kp, ki, J2=self.J2[:, None], K=self.K[:, None],
                                           c=self.c[:, None])
        self.plant = batched_plant_matrices(p, self.J2, self.K, self.c)

    def motion(self, kp, fv, wvi_ratio, filt="none", fparams=None) -> Motion:
        """Cascade with the speed loop crossing over at ``fv`` Hz on the nominal plant."""
        wv = 2 * math.pi * fv
        sv = np.array([1j * wv])
        P1v, _ = plant_responses(sv, self.p, *self.current_gains)
        dv = self.delay_at(sv)
        kv = float(1.0 / np.abs(dv * (1 + wvi_ratio * wv / sv) * sv * P1v)[0])
        return Motion("cascade", {"kp": float(kp), "kv": kv, "wvi": wvi_ratio * wv}, filt, dict(fparams or {}),
                      self.p.N)

    def loops(self, motion: Motion, kps) -> np.ndarray:
        """Open loops (len(kps), variants, frequencies): kp only scales the loop."""
        unit = replace(motion, gains=dict(motion.gains, kp=1.0))
        cy, cw = unit.responses(self.s)
        L0 = loop_response(self.s[None, :], self.P1, self.P2, self.delay, cy, cw, self.p.N)
        return np.asarray(kps, float)[:, None, None] * L0[None]

    def max_pole_real(self, motion: Motion) -> np.ndarray:
        """Largest real part of the closed-loop poles of each variant (1/s)."""
        ctrl = CascadeController(motion.state_space(), *self.current_gains, self.sample_time, "")
        A, B, C, D = self.plant
        acl = closed_loop_matrix(A, B[..., :1], C[..., :3, :], D[..., :3, :1],
                                 *controller_matrices(ctrl, self.scene.motor))
        return np.linalg.eigvals(acl).real.max(axis=-1)

    def score(self, L, max_real=None):
        """Tiered score of loops ``L`` (k, variants, w); ``max_real`` (k, variants) or None
        (frequency-domain screening: stability assumed)."""
        figs = grid_figures(self.w, L)
        nom = grid_figures(self.w, L[:, 0, :], phase_freq=self.f_req)
        stable = np.ones(L.shape[:2], bool) if max_real is None else max_real < 0
        achieved_n = {"bandwidth": nom["bandwidth_hz"], "phase_lag_at_bandwidth": -nom["phase_at_freq_deg"],
                      "gain_margin": np.abs(nom["gain_margin_db"]), "phase_margin": nom["phase_margin_deg"],
                      "sensitivity_peak": nom["sensitivity_peak_db"]}
        gm = np.where(stable, np.abs(figs["gain_margin_db"]), np.inf).min(axis=1)
        worst = {"gain_margin": gm, "phase_margin": np.where(stable, figs["phase_margin_deg"], np.inf).min(axis=1),
                 "sensitivity_peak": np.where(stable, figs["sensitivity_peak_db"], -np.inf).max(axis=1),
                 "bandwidth": np.where(stable, figs["bandwidth_hz"], np.inf).min(axis=1),
                 "stable_fraction": stable.mean(axis=1)}
        return self.tiered(achieved_n, worst, stable[:, 0],
                           None if max_real is None else np.max(max_real, axis=1))

    def tiered(self, achieved_n, worst, nominal_stable, max_real=None):
        """Score from nominal figures and worst-case figures (display units)."""
        margin, perf, stab = [], [], []
        for r in self.nominal:
            sl = _norm_slack(r.name, r.sense, r.value, achieved_n[r.name])
            (margin if r.name in MARGINS else perf).append(sl)
        for r in self.robust:
            sl = _norm_slack(r.name, r.sense, r.value, worst[r.name])
            (stab if r.name == "stable_fraction" else margin if r.name in MARGINS else perf).append(sl)
        stab = np.min(stab, axis=0) if stab else np.zeros_like(margin[0])
        stab = np.where(np.asarray(nominal_stable), stab, np.minimum(stab, -0.5))
        if max_real is not None:  # how far from stable, so that the refinement can climb out
            stab = np.where(stab < 0, stab - 0.05 * np.tanh(np.maximum(max_real, 0) / (2 * math.pi * self.f_req)),
                            stab)
        return _tier(stab, np.min(margin, axis=0), np.min(perf, axis=0))

    def filters(self):
        """Resonance-filter candidates for the range of the drivetrain mode."""
        if self.p.rigid:
            return [("none", {})]
        ranges = {k: (float(v.min()), float(v.max())) for k, v in self.values.items()}
        fa_lo, fa_hi = mode_range(self.p, self.scene.load.inertia, ranges)["antiresonance_hz"]
        fa_hi = min(fa_hi, 3 * fa_lo)
        wc = 2 * math.pi * math.sqrt(fa_lo * fa_hi)
        zp = float(np.clip((fa_hi - fa_lo) / (2 * math.sqrt(fa_lo * fa_hi)), 0.5, 2.0))
        return [("none", {}), ("lowpass", {"wn": 1.5 * 2 * math.pi * fa_lo, "zeta": 0.7}),
                ("notch", {"wn": wc, "zeta_zero": 0.3 * zp, "zeta_pole": zp})]


def _coarse(search: _Search, progress: bool):
    """Frequency-domain scan; returns rows (score, filter, fparams, fv, wvi_ratio, kp), best first."""
    rows = []
    combos = [(f, fp, r, q) for f, fp in search.filters() for r in FV_RATIOS for q in WVI_RATIOS]
    kps = KP_SCAN * 2 * math.pi * search.f_req
    for filt, fp, r, q in progress_bar(combos, show=progress, desc="robust design: scan", leave=False):
        m = search.motion(1.0, r * search.f_req, q, filt, fp)
        sc = search.score(search.loops(m, kps))
        rows += [(float(sc[i]), filt, fp, r * search.f_req, q, float(kps[i])) for i in range(len(kps))]
    rows.sort(key=lambda row: -row[0])
    return rows


def _starts(search: _Search, rows, count: int = 2, tries: int = 60):
    """The best-ranked candidates that are stable on the design grid, distinct in structure."""
    starts, seen = [], set()
    for row in rows[:tries]:
        key = (row[1], row[3], row[4])
        if key in seen:
            continue
        m = search.motion(row[5], row[3], row[4], row[1], row[2])
        mr = search.max_pole_real(m)
        if np.all(mr < 0):
            seen.add(key)
            starts.append(row)
            if len(starts) == count:
                break
    return starts or rows[:1]


def _refine(search: _Search, row, maxfev: int = 90):
    """Nelder-Mead on log(kp), log(fv), log(wvi ratio) (and log of the filter frequency)
    from a candidate row; returns (Motion, score, row of the refined candidate)."""
    _, filt, fp, fv, q, kp = row
    has_filter = filt != "none"
    x0 = np.log([kp, fv, q] + ([fp["wn"]] if has_filter else []))

    def unpack(x):
        kp_, fv_, q_ = np.exp(x[:3])
        fp_ = dict(fp, wn=float(np.exp(x[3]))) if has_filter else fp
        return (filt, fp_, float(fv_), float(min(q_, 1.0)), float(kp_))

    def objective(x):
        filt_, fp_, fv_, q_, kp_ = unpack(x)
        m = search.motion(kp_, fv_, q_, filt_, fp_)
        mr = search.max_pole_real(m)
        return -float(search.score(search.loops(m, [kp_]), mr[None, :])[0])

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        f0 = objective(x0)
        res = minimize(objective, x0, method="Nelder-Mead", bounds=_bounds(search, fp if has_filter else None),
                       options={"maxfev": maxfev, "xatol": 1e-3, "fatol": 1e-5})
    x, f = (res.x, res.fun) if res.fun <= f0 else (x0, f0)
    filt_, fp_, fv_, q_, kp_ = unpack(x)
    return search.motion(kp_, fv_, q_, filt_, fp_), -f, (-f, filt_, fp_, fv_, q_, kp_)


def _bounds(search: _Search, fp):
    """The search box in log units: kp and the speed crossover within a decade or so of the
    required bandwidth (a loop on a rigid, delay-free plant would otherwise climb forever)."""
    wb = 2 * math.pi * search.f_req
    box = [(0.5 * KP_SCAN[0] * wb, 2 * KP_SCAN[-1] * wb), (0.25 * search.f_req, 3 * FV_RATIOS[-1] * search.f_req),
           (0.01, 1.0)]
    if fp is not None:
        box.append((0.25 * fp["wn"], 4 * fp["wn"]))
    return [(math.log(lo), math.log(hi)) for lo, hi in box]


def design_grid(spec, load_inertia: float, per_axis: int = GRID_PER_AXIS) -> dict:
    """Nominal plant first, then a grid over ``spec``'s ranges (corners included)."""
    ranges = spec.ranges
    grid = sample_variants(dict(ranges), per_axis ** len(ranges), grid=True)
    nominal = {"load_inertia": load_inertia, "stiffness": 1.0}
    return {k: np.concatenate([[nominal[k]], v]) for k, v in grid.items()}


def robust_search(scene, p, spec, nominal, current_gains, sample_time, structural_damping, *,
                  evaluate_design, progress: bool = True, rounds: int = 2, executor=None):
    """Search the cascade over ``spec``'s variations (see module docstring).

    ``evaluate_design(controller, motion)`` turns a controller into a nominal DesignResult
    (python-control figures). Returns ``(result, search)``: the best DesignResult found, with
    ``robustness`` checked on ``spec``'s own variants, and the search state (its design grid
    in ``search.values``). When the scene's variants reveal a worse variant than the grid,
    it is added to the grid and the refinement runs again (at most ``rounds`` times).
    ``executor`` runs the chunks of that check over the scene's variants.
    """
    robust = robust_requirements(spec, nominal)
    search = _Search(scene, p, nominal, robust, current_gains, sample_time, structural_damping)
    search.set_variants(design_grid(spec, scene.load.inertia))
    rows = _coarse(search, progress)
    bar = progress_bar(total=rounds + 1, show=progress, desc="robust design: refine", leave=False)
    best = None
    for start in _starts(search, rows):
        cand = _refine(search, start)
        if best is None or cand[1] > best[1]:
            best = cand
    bar.update()
    results = []
    for round_ in range(rounds + 1):
        motion = best[0]
        ctrl = CascadeController(motion.state_space(), *current_gains, sample_time,
                                 motion.describe(scene.drivetrain.output_unit))
        nominal_result = evaluate_design(ctrl, motion)
        rb = robustness(scene, nominal_result, spec=spec, requirements=robust, progress=False,
                        structural_damping=structural_damping, executor=executor)
        result = replace(nominal_result, robustness=rb)
        achieved_n = {c.name: c.achieved for c in nominal_result.requirements}
        worst = {c.name: c.achieved for c in rb.requirements}
        results.append((float(search.tiered(achieved_n, worst, nominal_result.margins.closed_loop_stable)),
                        round_, result))
        if rb.passed or round_ == rounds:  # nothing the design grid missed
            break
        # the scene's variants found something the grid missed: add those variants, refine again
        extra = {k: np.array([rb.worst[c.name][k] for c in rb.requirements if c.name in rb.worst])
                 for k in search.values}
        search.set_variants({k: np.concatenate([search.values[k], extra[k]]) for k in search.values})
        best = _refine(search, best[2])
        bar.update()
    bar.close()
    return max(results, key=lambda r: (r[0], r[1]))[2], search


def confirm_worst_case(scene, result, structural_damping) -> str:
    """Rebuild the worst phase-margin variant from the scene as a state-space loop
    (interconnection, python-control's ``stability_margins`` arithmetic, closed-loop poles)
    and compare it with the vectorized figures; returns a note (a disagreement is stated,
    not hidden)."""
    from ..lti.analysis import stability_margins
    from ..lti.connect import feedback
    from .robustness import reference_loop
    rb = result.robustness
    name = "phase_margin" if "phase_margin" in rb.worst else "stable_fraction"
    at = rb.worst.get(name)
    if not at:
        return "no stable variant to confirm with a state-space loop"
    values = {k: np.array([v]) for k, v in at.items()}
    load = float(values.get("load_inertia", [scene.load.inertia])[0])
    factor = float(values.get("stiffness", [1.0])[0])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        loop = reference_loop(scene, result, load, factor, structural_damping, exact=True)
        pms = np.atleast_1d(stability_margins(loop, returnall=True)[1])
        stable = bool(np.all(feedback(loop, 1.0).poles().real < 0))
    where = rb.variant_text(at)
    k = int(np.flatnonzero(np.all([rb.values[key] == v for key, v in at.items()], axis=0))[0])
    vec_stable = bool(rb.figures["stable"][k])
    pm_vec = float(rb.figures["phase_margin_deg"][k])
    pm_ss = float(np.min(pms)) if pms.size else math.inf
    agree = stable == vec_stable and (not stable or abs(pm_ss - pm_vec) < 0.5)
    return (f"worst case ({where}) rebuilt as a state-space loop from the scene: closed loop "
            f"{'stable' if stable else 'UNSTABLE'}, phase margin {pm_ss:.4g} deg (vectorized {pm_vec:.4g} deg)"
            + ("" if agree else "; the vectorized evaluator DISAGREES on this variant"))
