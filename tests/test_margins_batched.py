"""The margins' crossing search and the design search cost a few batched evaluations, and
give what the scalar computations give.

The truth for the batched root finder is scipy's own ``brentq`` with the same tolerances:
the same roots to the last bit and the same failures; for the disk margins python-control's
``disk_margins``, for the phase unwrapping numpy's ``unwrap``. The cost is counted in
evaluations of the loop (never in seconds): a crossing search refines every bracket at once,
the design search never holds more than one group of candidates, the plants along the
stroke are computed once per design, and a plant's parameters compose the drivetrain's
kinematics at their point once.
"""

from __future__ import annotations

import importlib
import math

import control as ct
import numpy as np
import pytest
from scipy.optimize import brentq as scipy_brentq

import servo_toolkit as st
from servo_toolkit.loop import crossings as crossings_module
from servo_toolkit.loop.brent import brentq
from servo_toolkit.loop.margins import disk_margins, frequency_grid, loop_margins
from servo_toolkit.loop.metrics import grid_closed_loop, grid_figures, grid_margins, unwrap

from .conftest import SCENES

design_module = importlib.import_module("servo_toolkit.loop.design")  # the module, not the function
search_module = importlib.import_module("servo_toolkit.loop.nominal_search")


@pytest.fixture(scope="module")
def ema():
    return st.load_scene(SCENES / "ema_reference.toml")


@pytest.fixture(scope="module")
def ema_design(ema):
    return ema, design_module.design(ema)


FUNCTIONS = {
    "cos": (lambda x: np.cos(x) - x, -2.0, 2.0),
    "cubic": (lambda x: x**3 - 2 * x - 5, 0.0, 4.0),
    "flat_root": (lambda x: (x - 0.3)**3, -1.0, 2.0),  # converges slowly: bisection steps
    "steep": (lambda x: np.tanh(50 * (x - 0.1)), -1.0, 3.0),
    "tiny": (lambda x: 1e-200 * (1 - 2 * x), 0.0, 1.0),  # the product of the ends underflows
    "root_at_end": (lambda x: x - 1.0, 1.0, 3.0),
    "no_sign_change": (lambda x: x**2 + 1.0, -1.0, 1.0),
    "nan_inside": (lambda x: np.where(np.abs(x - 0.5) < 0.2, np.nan, x - 0.5), 0.0, 1.0),
}


def _scipy(fun, a, b, **tol):
    try:
        return scipy_brentq(lambda x: float(fun(np.array([x]))[0]), a, b, **tol)
    except (ValueError, RuntimeError):
        return None


@pytest.mark.parametrize("maxiter", [100, 8])
def test_batched_brent_gives_scipys_roots_to_the_last_bit(maxiter):
    rng = np.random.default_rng(7)
    for name, (fun, lo, hi) in FUNCTIONS.items():
        a = np.concatenate([[lo], lo - rng.uniform(0, 0.5, 20)])
        b = np.concatenate([[hi], hi + rng.uniform(0, 0.5, 20)])
        xtol = 1e-12 * (1 + np.abs(a))
        roots, ok = brentq(fun, a, b, xtol, 4e-15, maxiter)
        for k in range(a.size):
            ref = _scipy(fun, a[k], b[k], xtol=xtol[k], rtol=4e-15, maxiter=maxiter)
            assert ok[k] == (ref is not None), (name, k)
            if ref is not None:
                assert roots[k] == ref, (name, k, roots[k], ref)


def _modes_loop():
    """A loop with an integrator, a Pade delay and four lightly damped modes (1 % damping)
    from 30 Hz to 2 kHz: phase crossings beside the modes."""
    s = ct.tf("s")
    L = 50 * (1 - 1e-3 * s / 2) / (1 + 1e-3 * s / 2) / (s * (s / 20 + 1))
    for f in (30.0, 180.0, 700.0, 2000.0):
        w = 2 * math.pi * f
        L = L * w**2 / (s**2 + 2 * 0.01 * w * s + w**2)
    return ct.ss(L)


def test_a_crossing_search_evaluates_the_loop_in_a_few_batched_calls(ema_design, monkeypatch):
    """The reference design on the n-mass plant: far above its modes ``|L|`` is ~1e-24 and
    the sign of ``Im L`` is rounding, some 500 brackets that a scalar search refined with one
    call of the loop per Brent step (some 16000 calls)."""
    from servo_toolkit.loop.closed_loop import open_loop
    from servo_toolkit.plant.linear import DEFAULT_STRUCTURAL_DAMPING
    ema, r = ema_design
    loop = open_loop(ema, r.controller, r.q0, "chain", DEFAULT_STRUCTURAL_DAMPING)
    calls, points = [], []
    real = crossings_module.solved_response

    def counted(A, B, C, D, s):
        calls.append(1)
        points.append(np.size(s))
        return real(A, B, C, D, s)

    monkeypatch.setattr(crossings_module, "solved_response", counted)
    wpc, gm, wgc, pm = crossings_module.crossings(loop)
    assert sum(points) > 10000 and len(calls) < 200
    # what it finds is a crossing of the loop itself
    lp = loop(1j * wpc)
    assert wpc.size >= 1 and np.all(np.abs(lp.imag) <= 1e-6 * np.abs(lp)) and np.all(lp.real < 0)
    assert wgc.size >= 1 and np.all(np.abs(np.abs(loop(1j * wgc)) - 1) <= 1e-6)


def test_the_margins_of_a_lightly_damped_loop_are_its_closed_loop_poles():
    """The gain margins the batched search reports put closed-loop poles on the axis."""
    loop = _modes_loop()
    m = loop_margins(loop, ct.feedback(loop, 1))
    assert len(m.gain_margins_db) >= 2
    for g_db, f in zip(m.gain_margins_db, m.phase_crossover_hz):
        poles = ct.poles(ct.feedback(10 ** (g_db / 20) * loop, 1))
        assert np.min(np.abs(poles - 2j * math.pi * f)) < 1e-6 * 2 * math.pi * f


def test_disk_margins_are_python_controls(ema_design):
    from servo_toolkit.loop.closed_loop import open_loop
    ema, r = ema_design
    s = ct.tf("s")
    loops = [r.loop, open_loop(ema, r.controller, r.q0, "chain", 0.02), _modes_loop(), ct.ss(2 / (s + 1) ** 3),
             ct.ss(3 * (10 + s) / (2 + s)), ct.ss(((s - 0.1) ** 2 + 1) / ((s + 0.1) * ((s - 0.2) ** 2 + 4)))]
    omega = frequency_grid(extra=[8.0])
    for loop in loops:
        ours, theirs = disk_margins(loop, omega), ct.disk_margins(loop, omega)
        assert all(a == b for a, b in zip(ours, theirs)), (ours, theirs)


def test_phase_unwrapping_is_numpys():
    rng = np.random.default_rng(5)
    steps = np.cumsum(rng.uniform(-4, 4, (30, 400)), axis=-1)
    steps[3, 17] = np.nan
    exact = np.array([[0.0, np.pi, 0.0, -np.pi, 0.0, 2 * np.pi], [0.0, -np.pi, -2 * np.pi, np.pi, 3 * np.pi, 0.0]])
    for p in (steps, exact, np.angle(_modes_loop()(1j * np.geomspace(1, 1e5, 3000)))):
        assert np.array_equal(unwrap(p), np.unwrap(p, axis=-1), equal_nan=True)


def test_grid_figures_are_row_by_row():
    """The design search takes the margins of a group of candidates and the closed-loop
    figures of their q0 rows only: each figure of a row depends on that row alone."""
    rng = np.random.default_rng(3)
    w = 2 * np.pi * np.geomspace(0.01, 5e3, 401)
    L = (rng.standard_normal((6, 3, w.size)) + 1j * rng.standard_normal((6, 3, w.size))) * 30 / (1j * w)
    whole = grid_figures(w, L, phase_freq=8.0)
    for key, value in grid_margins(w, L[2:4]).items():
        assert np.array_equal(value, whole[key][2:4])
    for key, value in grid_closed_loop(w, L[:, 0], phase_freq=8.0).items():
        assert np.array_equal(value, whole[key][:, 0])


def test_the_design_search_holds_one_group_of_candidates_at_a_time(ema, monkeypatch):
    rows = []
    real = search_module.grid_margins

    def recorded(w, L):
        rows.append(int(np.prod(np.shape(L)[:-1])))
        return real(w, L)

    monkeypatch.setattr(search_module, "grid_margins", recorded)
    r = design_module.design(ema)
    points = next(n for n in r.notes if n.startswith("designed on")).split()[2]
    assert len(rows) > 10 and max(rows) <= len(search_module.GAIN_SCAN) * int(points)


def test_the_plants_along_the_stroke_are_computed_once_per_design(ema, monkeypatch):
    """The design's scan of the stroke and its stroke check read the same plants."""
    from servo_toolkit.loop import stroke_design, stroke_plants
    from servo_toolkit.plant.linear import plant_parameters
    seen = []

    def counted(scene, q0=None, *args, **kwargs):
        seen.append(float(q0))
        return plant_parameters(scene, q0, *args, **kwargs)

    monkeypatch.setattr(stroke_plants, "plant_parameters", counted)
    monkeypatch.setattr(stroke_design, "plant_parameters", counted)
    r = design_module.design(ema)
    assert r.stroke is not None and len(seen) == len(set(seen)) == r.stroke.q.size


def test_a_plants_parameters_compose_the_kinematics_at_their_point_once(ema, monkeypatch):
    """The chain's inertias, springs, modes and damping at q0 all read one composition of the
    stages (and the ratio and the chain's layout their own): the same parameters."""
    from servo_toolkit.drivetrain.reflected import Drivetrain
    from servo_toolkit.plant.linear import plant_parameters
    before = [plant_parameters(ema, q) for q in (-0.4, 0.1)]
    real, points = Drivetrain.kinematics, []

    def counted(self, q):
        points.append(np.size(q))
        return real(self, q)

    monkeypatch.setattr(Drivetrain, "kinematics", counted)
    for q, expected in zip((-0.4, 0.1), before):
        points.clear()
        assert plant_parameters(ema, q) == expected
        assert len(points) <= 3
