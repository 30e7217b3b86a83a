"""Robustness study timing and accuracy: N variants vectorized against python-control per variant.

Run: python3 benchmarks/bench_robustness.py [N [SUBSET]]    (default 10000 variants, 40 checked)

Prints, for N Monte Carlo variants of load inertia (0..4 kg*m^2) and stiffness (+-30 %) of
the reference EMA's designed loop:

- the time of the vectorized study with the crossings, the sensitivity peak and the
  bandwidth only interpolated on the frequency grid (``refine=False``) and refined to solver
  precision (the default), run one after the other under the same conditions (best of
  ``REPEATS``);
- the time per variant of building each loop with python-control and calling
  ``stability_margins`` (timed on SUBSET of the same variants and extrapolated), and the ratio;
- the agreement on those SUBSET variants, stable or not (margins are figures of the open
  loop): max |dPM| (smallest phase margin over every gain crossing, deg), max |dGM|
  (smallest |gain margin| over every phase crossing above 1e-3 rad/s, dB) and max |dMs|
  (against 1 / python-control's smallest |1 + L| over its stationary points, dB), for the
  grid-only and the refined figures.
"""

from __future__ import annotations

import sys
import time
import warnings

from pathlib import Path

import control as ct
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout

import servo_toolkit as st  # noqa: E402
from servo_toolkit.loop.robustness import reference_margins, robustness, sample_variants  # noqa: E402

REPEATS = 2


def _timed(scene, result, variants, refine):
    best, rb = np.inf, None
    for _ in range(REPEATS):
        t0 = time.perf_counter()
        rb = robustness(scene, result, variants, progress=False, refine=refine)
        best = min(best, time.perf_counter() - t0)
    return best, rb


def main(n: int = 10_000, subset: int = 40) -> None:
    scene = st.load_scene()
    result = st.design(scene)
    variants = sample_variants(None, n, seed=1)
    robustness(scene, result, sample_variants(None, 10, seed=2), progress=False)  # warm caches
    t_grid, grid = _timed(scene, result, variants, refine=False)
    t_vec, rb = _timed(scene, result, variants, refine=True)
    idx = np.linspace(0, n - 1, subset).astype(int)
    ref = {"pm": [], "gm": [], "ms": []}
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for i in idx:
            _, loop = reference_margins(scene, result, variants["load_inertia"][i], variants["stiffness"][i])
            gm, pm, sm, wpc, _, _ = ct.stability_margins(loop, returnall=True)  # every crossing
            ref["pm"].append(np.min(pm) if pm.size else np.inf)
            gm_db = np.abs(20 * np.log10(gm[wpc > 1e-3]))
            ref["gm"].append(np.min(gm_db) if gm_db.size else np.inf)
            ref["ms"].append(-20 * np.log10(np.min(sm)))
    t_ref = (time.perf_counter() - t0) / subset * n
    keys = {"pm": "phase_margin_deg", "gm": "gain_margin_db", "ms": "sensitivity_peak_db"}

    def worst(figs, k):
        d = np.abs(figs[keys[k]][idx] - np.asarray(ref[k]))
        d = np.where(np.isinf(figs[keys[k]][idx]) & np.isinf(ref[k]), 0.0, d)  # no crossing on either side
        return float(np.max(d))

    print(f"variants: {n} ({rb.unstable_count} unstable), python-control checked on {subset} of them")
    print(f"vectorized, grid only:  {t_grid:.2f} s   max |dPM| {worst(grid.figures, 'pm'):.2e} deg, "
          f"|dGM| {worst(grid.figures, 'gm'):.2e} dB, |dMs| {worst(grid.figures, 'ms'):.2e} dB")
    print(f"vectorized, refined:    {t_vec:.2f} s   max |dPM| {worst(rb.figures, 'pm'):.2e} deg, "
          f"|dGM| {worst(rb.figures, 'gm'):.2e} dB, |dMs| {worst(rb.figures, 'ms'):.2e} dB")
    print(f"refinement cost: {t_vec / t_grid:.2f}x the grid-only time")
    print(f"python-control per variant: {t_ref / n * 1e3:.1f} ms/variant, {t_ref:.1f} s extrapolated")
    print(f"ratio: {t_ref / t_vec:.1f}x faster than python-control per variant")


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:]))
