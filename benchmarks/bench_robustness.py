"""Robustness study timing: 10,000 variants vectorized against python-control per variant.

Run: python3 benchmarks/bench_robustness.py
Prints the time of the vectorized study (frequency responses on one grid with numpy and
batched closed-loop eigenvalues) for 10,000 Monte Carlo variants of load inertia (0..4
kg*m^2) and stiffness (+-30 %), the time per variant of building each loop with
python-control and calling ``stability_margins`` (timed on a subset of the same variants
and extrapolated), and the ratio.
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


def main(n: int = 10_000, subset: int = 40) -> None:
    scene = st.load_scene()
    result = st.design(scene)
    variants = sample_variants(None, n, seed=1)
    t0 = time.perf_counter()
    rb = robustness(scene, result, variants, progress=False)
    t_vec = time.perf_counter() - t0
    idx = np.linspace(0, n - 1, subset).astype(int)
    t0 = time.perf_counter()
    agree = checked = 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for i in idx:
            _, loop = reference_margins(scene, result, variants["load_inertia"][i], variants["stiffness"][i])
            pm = np.min(ct.stability_margins(loop, returnall=True)[1])  # every crossing, smallest
            if rb.figures["stable"][i]:  # unstable loops have no meaningful margin to compare
                checked += 1
                agree += abs(pm - rb.figures["phase_margin_deg"][i]) < 0.1
    t_ref = (time.perf_counter() - t0) / subset * n
    print(f"vectorized robustness, {n} variants: {t_vec:.2f} s ({rb.unstable_count} unstable)")
    print(f"python-control per variant: {t_ref / n * 1e3:.1f} ms/variant, {t_ref:.1f} s extrapolated "
          f"from {subset} of the same variants")
    print(f"ratio: {t_ref / t_vec:.1f}x faster; phase margins agree on {agree}/{checked} stable checked variants")


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:]))
