"""A sampled position command (Reference.table): the cubic spline through the samples and its
exact derivatives inside the kernel; a table of a sine runs as the sine does, to the spline's
interpolation accuracy (closed form 5/384 h^4 max|r''''|), with the feedforward too and
through the reference solver; bad tables are one line."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from servo_toolkit.errors import SceneError
from servo_toolkit.loop.controller import Feedforward
from servo_toolkit.scene.loader import load_scene
from servo_toolkit.sim import Reference, build_model, controller_for, run
from servo_toolkit.sim import layout as lo
from servo_toolkit._physics._kernels import table_rates
from servo_toolkit.sim.kernel import reference
from servo_toolkit.sim.reference import fill, initial_state

from .conftest import SCENES

A = math.radians(2.0)
F = 8.0
W = 2 * math.pi * F
#: table spacing, not a divisor of the 1 kHz controller sample: the samples fall between knots
H = 0.7e-3
#: the cubic spline's interpolation error bound for a sine of amplitude A (h^4 5/384 A w^4),
#: and of its first and second derivatives (h^3 A w^4 / 24, h^2 3/8 A w^4: de Boor's bounds)
BOUND = (5 / 384 * H ** 4 * A * W ** 4, H ** 3 / 24 * A * W ** 4, 3 / 8 * H ** 2 * A * W ** 4)


@pytest.fixture(scope="module")
def ema():
    scene = load_scene(SCENES / "ema_reference.toml")
    controller, _ = controller_for(scene)
    return scene, controller


def sine_table(duration=0.5, phase=0.0):
    t = np.arange(-0.01, duration + 0.01, H)
    return Reference.table(t, A * np.sin(W * t + phase))


def test_the_table_of_a_sine_runs_as_the_sine(ema):
    scene, controller = ema
    model = build_model(scene, controller)
    sine = run(model, Reference.sine(A, F), 0.3, "rk4", output_dt=1e-3)
    table = run(model, sine_table(0.3), 0.3, "rk4", dt=sine.dt_s, output_dt=1e-3)
    assert np.max(np.abs(table.reference_angle - sine.reference_angle)) < BOUND[0]
    # the loop's gain from command to output is below 2 at 8 Hz: the output follows within it
    assert np.max(np.abs(table.output_angle - sine.output_angle)) < 2 * BOUND[0]
    assert table.reference["kind"] == "table" and table.reference["samples"] > 400


def test_the_kernel_gives_the_spline_and_its_exact_derivatives(ema):
    scene, controller = ema
    model = build_model(scene, controller)
    P = fill(model, sine_table())
    assert P[lo.SHAPE_A0] == 0.0  # no command shaper: the reference is the table's spline
    t = np.linspace(0.0, 0.5, 997)  # between and on knots
    got = np.array([table_rates(x, P) for x in t])
    np.testing.assert_array_equal(got[:, 0], [reference(x, P) for x in t])
    q0 = model.q0
    exact = np.column_stack([q0 + A * np.sin(W * t), A * W * np.cos(W * t), -A * W * W * np.sin(W * t)])
    err = np.max(np.abs(got - exact), axis=0)
    assert (err < BOUND).all(), (err, BOUND)
    assert err[2] > 1e-3 * BOUND[2]  # the bound is not loose by orders of magnitude
    # before the first sample and after the last the end value is held, at rest
    r, rd, rdd = table_rates(-1.0, P)
    assert r == pytest.approx(q0 + A * math.sin(W * -0.01), abs=1e-15) and rd == 0.0 and rdd == 0.0


def test_a_periodic_table_wraps_smoothly(ema):
    scene, controller = ema
    model = build_model(scene, controller)
    n = 250  # one period of a two-line multisine, 1 ms samples: 0.25 s
    t = np.arange(n) * 1e-3
    v = A * (np.sin(2 * np.pi * 4 * t) + 0.5 * np.cos(2 * np.pi * 12 * t))
    P = fill(model, Reference.table(t, v, offset=0.0, periodic=True))
    assert P[lo.REF_TAB_WRAP] == 1.0 and P[lo.REF_TAB_N] == n + 1
    for x in (0.0, 0.1234, 0.2499):
        one, later = table_rates(x, P), table_rates(x + 3 * 0.25, P)
        np.testing.assert_allclose(later, one, rtol=1e-9, atol=1e-9 * A * 1e4)
    # across the wrap the value, slope and curvature are continuous (a periodic spline)
    before, after = table_rates(0.25 - 1e-9, P), table_rates(0.25 + 1e-9, P)
    np.testing.assert_allclose(after, before, rtol=1e-5, atol=1e-5 * A * 1e4)
    # the start is in equilibrium at the command's value at t = 0
    assert initial_state(model, P)[2] == pytest.approx(v[0] + 0.0)


def test_the_feedforward_follows_a_table_as_it_follows_the_sine(ema):
    scene, controller = ema
    model = build_model(scene, replace(controller, feedforward=Feedforward(model=True)))
    sine = run(model, Reference.sine(A, F), 0.2, "rk4", output_dt=1e-3)
    table = run(model, sine_table(0.2), 0.2, "rk4", dt=sine.dt_s, output_dt=1e-3)
    err = table.output_angle - sine.output_angle
    # the feedforward's current follows r'' (bound H^2 ...): a far larger difference would be
    # a table the feedforward did not see (without it the 8 Hz error is 5 times larger)
    assert np.max(np.abs(err)) < 1e-3 * A
    assert np.max(np.abs(table.current_reference - sine.current_reference)) < 1e-3 * np.max(
        np.abs(sine.current_reference))


def test_the_reference_solver_follows_a_table(ema):
    scene, controller = ema
    model = build_model(scene, controller)
    ref = sine_table(0.05, phase=0.3)
    fixed = run(model, ref, 0.05, "rk4", output_dt=1e-3)
    exact = run(model, ref, 0.05, "reference", output_dt=1e-3, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(exact.output_angle, fixed.output_angle, atol=1e-6 * A)
    # it starts in equilibrium at the command's value at t = 0
    assert exact.output_angle[0] == exact.reference_angle[0]
    assert exact.reference_angle[0] == pytest.approx(model.q0 + A * math.sin(0.3), abs=BOUND[0])


def test_variants_of_sampled_commands_run_in_the_batch_as_alone(ema):
    """Variants with the same table and a table 1e-9 rad out of phase: the batch on one and two
    threads gives each its single run to the bit; the table out of phase moves the run, the
    same table does not, and the table's run ends where the sine's does."""
    from .test_batch import assert_as_single_runs, batch
    scene, controller = ema
    model = build_model(scene, controller)
    P = np.array([fill(model, r) for r in (sine_table(), sine_table(), sine_table(phase=1e-9))])
    X0 = np.array([initial_state(model, p) for p in P])
    dt, one = model.sample_time / 10, np.zeros(1, dtype=np.int64)
    X = assert_as_single_runs(P, model.T[None], np.zeros(len(P), dtype=np.int64), X0, 10, 2000, dt,
                              threads=(1, 2))[0]
    assert np.array_equal(X[1], X[0]) and not np.array_equal(X[2], X[0])
    sine = fill(model, Reference.sine(A, F))
    x = batch(sine[None], model.T[None], one, initial_state(model, sine)[None], 10, 2000, dt=dt)[0]
    assert np.max(np.abs(x[0, [0, 2]] - X[0, [0, 2]])) < 2 * BOUND[0]


@pytest.mark.parametrize("times, values, key, words", [
    ([0, 1, 2], [0, 1, 2], "time_s", "needs 4"),
    ([0, 1, 3, 4], [0, 1, 2, 3], "time_s", "equally spaced"),
    ([0, 2, 1, 3], [0, 1, 2, 3], "time_s", "increase strictly"),
    ([0, 1, 2, 3], [0, float("nan"), 2, 3], "values", "not a finite number"),
    ([0, 1, 2, float("inf")], [0, 1, 2, 3], "time_s", "not a finite number"),
    ([0, 1, 2, 3], [0, 1, 2], "values", "one value per time"),
])
def test_bad_tables_are_one_line(times, values, key, words):
    with pytest.raises(SceneError) as info:
        Reference.table(times, values)
    assert info.value.key == key and words in str(info.value) and "\n" not in str(info.value)


def test_every_reference_field_has_a_plain_default():
    """No field of a reference is shadowed by a constructor of the same name (a field
    ``step`` once took the classmethod ``Reference.step`` as its default)."""
    import dataclasses
    from servo_toolkit.sim.reference import Reference
    for f in dataclasses.fields(Reference):
        assert not callable(f.default), f.name
    assert "method" not in repr(Reference.sine(1.0, 2.0))
