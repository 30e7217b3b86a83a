"""The run's stability scan (sim/stability.py): the Jacobians of every sampled state taken in
one compiled call, their eigenvalues stacked and every mode's step limit at once, against
the definition state by state.

The definition is written out here: each state and its contact variant, its Jacobian by
central differences through the right-hand side Python calls (:mod:`.jacobian_reference`), its
eigenvalues, the smallest stable step of each (:func:`stability.max_stable_dt`), and the
fastest eigenvalue, the first of the largest in order.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from servo_toolkit import load_scene
from servo_toolkit.sim import ModelOptions, Reference, build_model, controller_for
from servo_toolkit.sim.batch import jacobians
from servo_toolkit.sim.reference import fill, initial_state
from servo_toolkit.sim.stability import (IMAG_LIMIT, REAL_LIMIT, contact_states, fastest, jacobian, max_stable_dt,
                                         smooth_parameters)

from .jacobian_reference import central_differences


def jacobian_by_definition(model, P, x, t, iref):
    """The definition (:func:`.jacobian_reference.central_differences`) at one state, friction
    that holds left out (a quotient across its jump is no eigenvalue)."""
    P = np.ascontiguousarray(smooth_parameters(P))[None]
    J, _ = central_differences(np.asarray(x, float)[None], np.array([t], float), np.array([iref], float), P,
                               model.T[None], np.zeros(1, np.int64), np.zeros(1, np.int64))
    return J[0]


def scan_by_state(model, P, states, times, irefs):
    """The definition: every state and its contact variant, one at a time."""
    worst = {"max_abs_lambda": 0.0, "lambda": [0.0, 0.0], "t_s": 0.0, "dt_limit_s": np.inf}
    for x, t, ir in zip(states, times, irefs):
        for y in (x, contact_states(model, np.asarray(P)[None], x[None])[0]):
            eigs = np.linalg.eigvals(jacobian_by_definition(model, P, y, t, ir))
            if not np.all(np.isfinite(eigs)):
                continue
            k = int(np.argmax(np.abs(eigs)))
            if abs(eigs[k]) > worst["max_abs_lambda"]:
                worst.update(max_abs_lambda=float(abs(eigs[k])), t_s=float(t),
                             **{"lambda": [float(eigs[k].real), float(eigs[k].imag)]})
            worst["dt_limit_s"] = min(worst["dt_limit_s"], max_stable_dt(eigs))
    return worst


@pytest.fixture(scope="module", params=["sampled", "continuous", "stick"])
def case(request):
    scene = load_scene()
    controller, _ = controller_for(scene)
    options = {"sampled": ModelOptions(), "continuous": ModelOptions(controller_mode="continuous"),
               "stick": ModelOptions(friction="stick")}[request.param]
    model = build_model(scene, controller, options)
    P = fill(model, Reference.sine(math.radians(2.0), 8.0))
    return model, P, initial_state(model, P)


def test_the_compiled_jacobians_are_the_definitions_quotients_to_the_bit(case):
    model, P, x0 = case
    rng = np.random.default_rng(7)
    X = x0 + rng.normal(scale=0.02, size=(40, x0.size))
    times, irefs = np.linspace(0.0, 1.0, 40), rng.normal(scale=5.0, size=40)
    J = np.empty((40, x0.size, x0.size))
    jacobians(X, times, irefs, smooth_parameters(P)[None], model.T[None], np.zeros(1, np.int64),
              np.zeros(40, np.int64), J)
    for m in range(40):
        assert np.array_equal(J[m], jacobian_by_definition(model, P, X[m], times[m], irefs[m])), m
        assert np.array_equal(jacobian(model, P, X[m], times[m], irefs[m]), J[m]), m  # the one-state face


def test_the_scan_finds_what_the_state_by_state_definition_finds(case):
    model, P, x0 = case
    rng = np.random.default_rng(11)
    states = x0 + rng.normal(scale=0.05, size=(25, x0.size))
    states[3] = states[2]  # a tie: the first of the largest keeps its time
    times, irefs = np.linspace(0.0, 0.5, 25), rng.normal(scale=5.0, size=25)
    assert fastest(model, P, states, times, irefs) == scan_by_state(model, P, states, times, irefs)
    assert fastest(model, P, [x0], [0.0]) == scan_by_state(model, P, [x0], [0.0], [0.0])


def test_an_empty_scan_bounds_nothing(case):
    model, P, x0 = case
    assert fastest(model, P, np.empty((0, x0.size)), []) == {
        "max_abs_lambda": 0.0, "lambda": [0.0, 0.0], "t_s": 0.0, "dt_limit_s": np.inf}



@settings(max_examples=60, deadline=None)
@given(st.lists(st.complex_numbers(max_magnitude=1e6, allow_nan=False, allow_infinity=False), min_size=1,
                max_size=12))
def test_the_limit_of_many_modes_is_the_smallest_of_each_alone(eigs):
    """Bisecting only the modes that can hold the smallest limit finds that limit exactly."""
    lam = np.array(eigs, complex)
    assert max_stable_dt(lam) == min(max_stable_dt(np.array([value])) for value in lam)


def test_the_limits_on_the_axes_are_rk4s_closed_forms():
    assert max_stable_dt(np.array([-1000.0 + 0j])) == pytest.approx(REAL_LIMIT / 1000, rel=1e-9)
    assert max_stable_dt(np.array([100j])) == pytest.approx(IMAG_LIMIT / 100, rel=1e-9)
    assert max_stable_dt(np.array([0j])) == np.inf
    assert max_stable_dt(np.array([5.0 + 0j])) == IMAG_LIMIT / 5.0
