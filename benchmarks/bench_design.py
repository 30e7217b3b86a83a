"""Loop-design figures of the reference EMA, best of several repeats in this process (after a
first call that loads python-control, scipy and the compiled code):

- ``design(scene)``: the cascade with its resonance filter, margins at every crossing and the
  check along the stroke (target: under 5 s on 2 cores);
- ``stroke_check`` at 37 points of the stroke (target: under 1.5 s).

Run it on an idle machine: ``python benchmarks/bench_design.py``. The test suite asserts no
wall time; these figures live here.
"""

from __future__ import annotations

import time

import servo_toolkit as st
from servo_toolkit.loop.stroke import stroke_check

TARGET_DESIGN_S = 5.0
TARGET_STROKE_S = 1.5


def best(function, repeats: int = 5) -> float:
    """Best wall time (s) of ``repeats`` calls."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return min(times)


def main() -> None:
    scene = st.load_scene()
    result = st.design(scene)  # loads the libraries and the compiled code
    t_design = best(lambda: st.design(scene), repeats=3)
    t_stroke = best(lambda: stroke_check(scene, result.controller, result.q0, points=37))
    print(f"design(reference EMA)      {t_design:7.3f} s   target < {TARGET_DESIGN_S:g} s   "
          f"{'ok' if t_design < TARGET_DESIGN_S else 'OVER'}")
    print(f"stroke_check(37 points)    {t_stroke:7.3f} s   target < {TARGET_STROKE_S:g} s   "
          f"{'ok' if t_stroke < TARGET_STROKE_S else 'OVER'}")


if __name__ == "__main__":
    main()
