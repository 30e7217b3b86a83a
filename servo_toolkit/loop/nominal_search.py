"""The nominal design's search: the candidate controllers and how they are ranked.

Each structure's candidates (:data:`GAIN_SCAN` times the bandwidth, the cascade's speed loops
at :data:`SPEED_RATIOS` times it, each resonance filter tried) are evaluated on a frequency
grid with the closed-form plant responses (:mod:`.response`) at the design points along the
stroke, ranked by their smallest normalized slack against the requirements (margins at their
worst over the points, bandwidth and phase lag at q0), and the best one stable at every point
is kept; when none reaches the required bandwidth the search aims lower
(:data:`TARGET_FALLBACK`). :mod:`.design` evaluates the chosen controller.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from .controller import CascadeController
from ..plant.linear import plant_matrices
from .assembly import closed_loop_matrix, controller_matrices
from .closed_loop import DELAY_SAMPLES
from .margins import frequency_grid
from .metrics import grid_closed_loop, grid_margins
from .response import loop_response, plant_responses
from .stroke_design import StrokePlants, speed_references, stroke_filters
from .structures import Motion


SPEED_RATIOS = (2.0, 3.0, 4.0, 6.0, 8.0, 12.0, 16.0)
"""Speed-loop crossover as multiples of the required bandwidth (cascade search)."""
TARGET_FALLBACK = tuple(3.0 ** -k for k in range(12))
"""When no stable design reaches the required bandwidth, aim lower by these factors (down to
a bandwidth of :data:`LOWEST_TARGET_HZ`): the best stable design is returned with the unmet
requirements failing, never an unstable controller while a stable one exists."""
LOWEST_TARGET_HZ = 0.05
GAIN_SCAN = np.logspace(-0.8, 0.5, 27)
"""Position gain (cascade) or crossover (other structures) as multiples of the bandwidth."""


@functools.lru_cache(maxsize=16)
def _delay_polys(sample_time: float):
    """Numerator and denominator of :func:`plant.sample_delay` (None without a delay)."""
    from ..lti.convert import ss2tf
    from ..plant.current_loop import sample_delay_block
    d = sample_delay_block(sample_time, DELAY_SAMPLES)
    if d.nstates == 0:
        return None
    num, den = ss2tf(d)
    return np.ravel(num), np.ravel(den)


def _delay_response(s, sample_time):
    """Pade(2) of the sampling delay at ``s`` (what :func:`plant.sample_delay` builds)."""
    polys = _delay_polys(float(sample_time))
    s = np.asarray(s, complex)
    if polys is None:
        return np.ones_like(s)
    return np.polyval(polys[0], s) / np.polyval(polys[1], s)


MARGINS = ("gain_margin", "phase_margin", "sensitivity_peak")
"""Requirements judged at their worst over the design points (the others at q0)."""


def _slack(figs, reqs):
    """Smallest normalized slack over the requirements (negative: some requirement missed).

    ``figs`` holds the margins per candidate and design point (candidates x points, q0
    first), which count at their worst over the points, and the bandwidth and phase lag per
    candidate, at q0."""
    achieved = _achieved(figs)
    cols = []
    for r in reqs:
        a = np.asarray(achieved[r.name], float)
        if r.name == "bandwidth":
            with np.errstate(divide="ignore", invalid="ignore"):
                sl = np.log(a / r.value)
        else:
            sl = (a - r.value if r.sense == ">=" else r.value - a) / max(abs(r.value), 1.0)
        sl = np.where(np.isfinite(sl), sl, np.where(sl > 0, 10.0, -10.0))
        cols.append(sl.min(axis=1) if r.name in MARGINS else sl)
    return np.min(cols, axis=0)


def _achieved(figs) -> dict:
    return {"bandwidth": figs["bandwidth_hz"], "phase_lag_at_bandwidth": -figs["phase_at_freq_deg"],
            "gain_margin": np.abs(figs["gain_margin_db"]), "phase_margin": figs["phase_margin_deg"],
            "sensitivity_peak": figs["sensitivity_peak_db"]}


def _filters(p, names, zeta, stroke_params):
    """(name, parameters) of the resonance filters tried: the notch on the anti-resonance at
    q0 and the low-pass at half of it, and, when the mode walks along the stroke, the
    stroke-wide ones (:func:`.stroke_design.stroke_filters`)."""
    wa = 2 * math.pi * p.antiresonance_hz
    base = {"none": {}, "notch": {"wn": wa, "zeta_zero": max(zeta, 0.05), "zeta_pole": 0.7},
            "lowpass": {"wn": 0.5 * wa, "zeta": 0.5}}
    out = [(n, base[n]) for n in names]
    out += [(n, fp) for n, fp in stroke_filters(stroke_params) if n in names]
    return out


def _speed_gains(p, refs, wb, sample_time, current_gains, kv_cap):
    """(kv, wvi) of the cascade's speed loops: crossover at each of :data:`SPEED_RATIOS`
    times the bandwidth on each speed reference's plant; a gain above ``kv_cap`` (A per
    output rad/s) is lowered to it, its crossover and integral corner with it (the motor
    side's response falls as 1/w there), and the repeats dropped."""
    out = []
    for r, ref in ((r, ref) for ref in refs for r in SPEED_RATIOS):
        wv = r * wb
        sv = np.array([1j * wv])
        P1v, _ = plant_responses(sv, ref, *current_gains)
        dv = _delay_response(sv, sample_time)
        kv = float(p.N / ref.N / np.abs(dv * (1 + (wv / 4) / sv) * sv * P1v)[0])
        if kv > kv_cap:
            wv *= kv_cap / kv
            kv = kv_cap
        if all(abs(kv - k) > 1e-9 * kv or abs(wv / 4 - w) > 1e-9 * wv for k, w in out):
            out.append((kv, wv / 4))
    return out


def _candidates(structure, p, s, delay, wb, filters, sample_time, current_gains, plants, kv_cap=math.inf):
    """Yield the scan of one structure in groups, one per filter and speed-loop gains: (the
    Motions, L of each at every design point on the grid, shape (motions, points, grid))."""
    n = p.N
    P1, P2, nq = plants.P1, plants.P2, plants.N
    refs = speed_references(p, plants.params)
    for filt, fparams in filters:
        if structure == "cascade":
            for kv, wvi in _speed_gains(p, refs, wb, sample_time, current_gains, kv_cap):
                group = [Motion("cascade", {"kp": k * wb, "kv": kv, "wvi": wvi}, filt, fparams, n)
                         for k in GAIN_SCAN]
                yield group, _group_loops(group, s, P1, P2, delay, nq)
        else:
            group = []
            for k in GAIN_SCAN:
                wc = k * wb
                gains = {"pid": {"kc": 1.0, "wi": wc / 5, "wz": wc / 3, "wp": 3 * wc},
                         "lead_lag": {"kc": 1.0, "wz": wc / 3, "wp": 3 * wc},
                         "pi": {"kc": 1.0, "wi": wc / 5}}[structure]
                unit = Motion(structure, gains, filt, fparams, n)
                sc = np.array([1j * wc])
                cy1, _ = unit.responses(sc)
                P1c, P2c = plant_responses(sc, p, *current_gains)
                lc = _delay_response(sc, sample_time) * cy1 * P2c
                group.append(Motion(structure, dict(gains, kc=float(1.0 / abs(lc[0]))), filt, fparams, n))
            yield group, _group_loops(group, s, P1, P2, delay, nq)


def _group_loops(group, s, P1, P2, delay, nq):
    """L of every Motion of ``group`` at every design point: (motions, points, grid)."""
    cy, cw = (np.array(r)[:, None, :] for r in zip(*(m.responses(s) for m in group)))
    return loop_response(s, P1, P2, delay, cy, cw, nq)


def _search(scene, p, reqs, structure, filters, f_req, f_target, phase_hz, sample_time, current_gains,
            stroke_params, stable_only=True, kv_cap=math.inf):
    """Best-ranked candidate aiming at ``f_target``, stable at every design point:
    (Motion, CascadeController) or None. ``stroke_params``: the plants at the design points,
    q0 first (:func:`.stroke_design.design_points`). The figures are taken one group of
    candidates at a time (arrays that stay in cache), the margins at every point, the
    bandwidth and the phase lag at q0 only (where they are judged)."""
    w = frequency_grid(f_min=0.01, f_max=5e3, points=700, extra=[f_req, phase_hz])
    s = 1j * w
    delay = _delay_response(s, sample_time)
    plants = StrokePlants(stroke_params, s, current_gains)
    motions, parts = [], []
    for group, L in _candidates(structure, p, s, delay, 2 * math.pi * f_target, filters, sample_time,
                                current_gains, plants, kv_cap):
        motions += group
        parts.append({**grid_margins(w, L), **grid_closed_loop(w, L[:, 0], phase_freq=f_req)})
    if not parts:
        return None
    figs = {key: np.concatenate([part[key] for part in parts]) for key in parts[0]}
    order = np.argsort(-_slack(figs, reqs), kind="stable")
    mats = [plant_matrices(q, inductance=True) for q in stroke_params]
    for idx in order:
        ctrl = CascadeController(motions[idx].state_space(), *current_gains, sample_time,
                                 motions[idx].describe(scene.drivetrain.output_unit))
        if not stable_only:
            return motions[idx], ctrl
        kc = controller_matrices(ctrl, scene.motor)
        if all(np.all(np.linalg.eigvals(closed_loop_matrix(A, B[:, :1], C[:3], D[:3, :1], *kc)).real < 0)
               for A, B, C, D, _ in mats):
            return motions[idx], ctrl
    return None

def _best(scene, p, reqs, structure, filters, f_req, phase_hz, sample_time, current_gains, stroke_params,
          kv_cap=math.inf):
    """The search with its fallbacks: (Motion, CascadeController, notes)."""
    for target in TARGET_FALLBACK:
        if target < 1 and f_req * target < LOWEST_TARGET_HZ:
            break
        chosen = _search(scene, p, reqs, structure, filters, f_req, f_req * target, phase_hz,
                         sample_time, current_gains, stroke_params, kv_cap=kv_cap)
        if chosen is not None:
            return chosen + ([] if target == 1 else
                             [f"no stable {structure} design reaches {f_req:g} Hz; the best stable one found "
                              f"aiming at {f_req * target:.3g} Hz is shown"],)
    chosen = _search(scene, p, reqs, structure, filters, f_req, f_req, phase_hz, sample_time,
                     current_gains, stroke_params, stable_only=False, kv_cap=kv_cap)
    return chosen + ([f"no stable {structure} design was found in the search (aiming as low as "
                      f"{max(LOWEST_TARGET_HZ, f_req * TARGET_FALLBACK[-1]):.3g} Hz); the best-ranked one is shown "
                      "and its closed loop is UNSTABLE"],)
