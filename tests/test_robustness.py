"""Robustness over load inertia and stiffness: vectorized figures against python-control."""

from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

import servo_toolkit as st
from servo_toolkit.loop.robustness import reference_margins, robustness


@pytest.fixture(scope="module")
def case():
    scene = st.load_scene()
    return scene, st.design(scene, resonance_filter="none")


def test_nominal_variant_reproduces_the_design(case):
    scene, r = case
    rb = robustness(scene, r, {"load_inertia": [scene.load.inertia], "stiffness": [1.0]}, progress=False)
    assert rb.figures["stable"][0]
    np.testing.assert_allclose(rb.figures["phase_margin_deg"][0], r.margins.phase_margin_deg, atol=0.05)
    np.testing.assert_allclose(rb.figures["gain_margin_db"][0], abs(r.margins.gain_margin_db), atol=0.02)
    np.testing.assert_allclose(rb.figures["bandwidth_hz"][0], r.margins.bandwidth_hz, rtol=2e-3)


@pytest.mark.parametrize("load,k", [(0.0, 0.7), (2.5, 1.3), (4.0, 0.7)])
def test_vectorized_figures_match_python_control(case, load, k):
    scene, r = case
    rb = robustness(scene, r, {"load_inertia": [load], "stiffness": [k]}, progress=False)
    (gm, pm, *_), loop = reference_margins(scene, r, load, k)
    assert rb.figures["stable"][0] == bool(np.all(np.real(__import__("control").poles(
        __import__("control").feedback(loop, 1))) < 0))
    np.testing.assert_allclose(rb.figures["phase_margin_deg"][0], pm, atol=0.05)
    np.testing.assert_allclose(rb.figures["gain_margin_db"][0], abs(20 * np.log10(gm)), atol=0.02)


def test_worst_case_and_executor(case):
    scene, r = case
    a = robustness(scene, r, samples=300, seed=3, progress=False)
    with ThreadPoolExecutor(2) as pool:
        b = robustness(scene, r, samples=300, seed=3, executor=pool, chunk_size=100, progress=False)
    for key in a.figures:
        np.testing.assert_array_equal(a.figures[key], b.figures[key])
    pm = a.requirements[[c.name for c in a.requirements].index("phase_margin")]
    stable = a.figures["stable"]
    assert pm.achieved == pytest.approx(np.min(a.figures["phase_margin_deg"][stable]))
    assert 0 <= a.worst["phase_margin"]["load_inertia"] <= 4
    assert "robustness over 300 variants" in a.table()
    grid = robustness(scene, r, samples=16, grid=True, progress=False)
    assert grid.count == 16 and set(np.round(grid.values["stiffness"], 6)) == {0.7, 0.9, 1.1, 1.3}
