"""Elasto-backlash contact law (Modelica ElastoBacklash) and the current-loop anti-windup.

The contact moment is checked against the law's defining properties (continuous at
engagement for any relative speed, never pulling, spring + damper away from engagement),
inside the compiled right-hand side, and by the energy balance of a damped free swing.
"""

from __future__ import annotations

import math
import tomllib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from servo_toolkit import SimulationError
from servo_toolkit.sim import ModelOptions, Reference, build_model, default_controller, run
from servo_toolkit.sim import layout as lo
from servo_toolkit.sim.kernel import contact, hermite, rhs
from servo_toolkit.sim.reference import fill

from . import rhs_reference
from .conftest import SCENES, build, open_circuit_run, variant

BASE = tomllib.loads((SCENES / "ema_reference.toml").read_text())
SPEEDS = (-50.0, -1.0, -1e-3, 0.0, 1e-3, 1.0, 50.0)


def test_contact_law_is_continuous_at_engagement_and_never_pulls():
    k, beta = 3.4e4, 2e-3
    for dd in SPEEDS:
        for sign in (1.0, -1.0):
            for z in (1e-3, 1e-6, 1e-9, 1e-12):
                f = contact(k * sign * z, beta * k * dd)
                assert f * sign >= 0.0                      # pushes or nothing, never pulls
                assert abs(f) <= 2.0 * k * z * (1 + 1e-12)  # -> 0 with the penetration
            assert contact(0.0, beta * k * dd) == 0.0       # inside the play


def test_contact_law_is_spring_plus_damper_away_from_engagement():
    """|tau_d| <= |tau_c|: the plain Kelvin-Voigt moment k z + beta k z' (both sides)."""
    rng = np.random.default_rng(1)
    k, beta = 3.4e4, 2e-3
    for _ in range(200):
        z = rng.uniform(1e-4, 1e-2) * rng.choice([-1.0, 1.0])
        dd = rng.uniform(-1.0, 1.0) * abs(z) / beta        # |beta dd| <= |z|
        assert contact(k * z, beta * k * dd) == pytest.approx(k * z + beta * k * dd, rel=1e-12)
    # the damper part is capped at the spring part while pushing in fast, and the contact
    # lets go (0) rather than pulling while separating fast
    assert contact(k * 1e-4, beta * k * 10.0) == pytest.approx(2 * k * 1e-4)
    assert contact(-k * 1e-4, -beta * k * 10.0) == pytest.approx(-2 * k * 1e-4)
    assert contact(k * 1e-4, -beta * k * 10.0) == 0.0
    assert contact(-k * 1e-4, beta * k * 10.0) == 0.0


#: magnitudes across the scales the right-hand side meets, and the edge values
MOMENTS = st.one_of(st.floats(-1e6, 1e6, allow_nan=False), st.sampled_from([0.0, -0.0, 1.0, -1.0, 1e-300, -1e-300]))


@settings(max_examples=2000, deadline=None)
@given(tau_c=MOMENTS, tau_d=MOMENTS)
def test_compiled_contact_law_is_its_transcription(tau_c, tau_d):
    """The compiled law compares and adds once (nothing to reassociate): the transcription's
    value (tests/rhs_reference.py) exactly."""
    assert contact(tau_c, tau_d) == rhs_reference.contact(tau_c, tau_d)


@pytest.fixture(scope="module")
def loose():
    """Open loop, 1 deg of play, no hinge load."""
    scene = build(variant(BASE, load__hinge_moment="0 N*m"))
    return build_model(scene, None, ModelOptions(play=math.radians(1.0)))


def _contact_moment(model, P, p, q, pd, qd):
    """The moment on the load side read back from the compiled right-hand side."""
    x = np.zeros(model.nx)
    x[0], x[1], x[2], x[3] = p, pd, q, qd
    dx, aux = np.empty(model.nx), np.empty(lo.NAUX)
    rhs(0.0, x, P, model.T, 0.0, dx, aux)
    m_load = -P[lo.HINGE_M] - P[lo.HINGE_K] * q - P[lo.HINGE_D] * qd
    return dx[3] / P[lo.INV_JL] - m_load


def test_kernel_contact_moment_vanishes_with_penetration_at_any_speed(loose):
    P = fill(loose, Reference.voltage(0.0))
    c = P[lo.HALF_PLAY]
    def k(p):
        return hermite(loose.T, lo.T_K, P, p)[0] * P[lo.KSCALE]

    for dd in SPEEDS:
        for side in (1.0, -1.0):
            prev = None
            for z in (1e-4, 1e-6, 1e-8):
                f = _contact_moment(loose, P, side * (c + z), 0.0, dd, 0.0)
                assert f * side >= 0.0
                assert abs(f) <= 2.0 * k(side * (c + z)) * z * (1 + 1e-9)
                if prev is not None:
                    assert abs(f) <= abs(prev) + 1e-12
                prev = f
            assert _contact_moment(loose, P, side * 0.999 * c, 0.0, dd, 0.0) == 0.0
    # deep in contact and slow: spring plus damper with the model's beta
    z, dd = 1e-3, 1e-3
    f = _contact_moment(loose, P, c + z, 0.0, dd, 0.0)
    assert f == pytest.approx(k(c + z) * (z + P[lo.BETA] * dd), rel=1e-9)


def _energy(model, P, states):
    e = []
    for x in states:
        jd = hermite(model.T, lo.T_J, P, x[0])[0]
        k = hermite(model.T, lo.T_K, P, x[0])[0] * P[lo.KSCALE]
        d, c = x[0] - x[2], P[lo.HALF_PLAY]
        z = d - c if d > c else d + c if d < -c else 0.0
        e.append(0.5 * jd * x[1] ** 2 + 0.5 * P[lo.JL] * x[3] ** 2 + 0.5 * k * z * z)
    return np.array(e)


def test_damped_rattle_never_gains_energy():
    """Open circuit, no friction or hinge load, structural damping on, 0.5 deg of play: the
    two sides rattle through the play; the energy only decreases (to RK4's error) and the
    contacts do dissipate."""
    scene = build(variant(BASE, motor__inductance="0 H",
                          motor__viscous_friction="0 N*m*s/rad", motor__coulomb_friction="0 N*m",
                          load__hinge_moment="0 N*m"))
    model = build_model(scene, None, ModelOptions(damping_ratio=0.2, play=math.radians(0.5)))
    P = fill(model, Reference.voltage(0.0))
    x0 = np.zeros(model.nx)
    x0[1], x0[3] = 1.0, -1.0                       # closing the play from both sides
    states = open_circuit_run(model, P, x0, 1e-5, 20000)
    e = _energy(model, P, states)
    assert np.max(np.diff(e)) <= 1e-9 * e[0], np.max(np.diff(e)) / e[0]
    assert e[-1] < 0.9 * e[0]


def test_reference_integrates_through_voltage_saturation():
    """40 V supply, 20 deg step: the voltage sits at its limit for most of the run. With the
    continuous back-calculation anti-windup the reference solver passes (it stalled with the
    switched conditional integration) and RK4 at the default step agrees."""
    scene = build(variant(BASE, motor__voltage_limit="40 V"))
    model = build_model(scene, default_controller(scene), ModelOptions(controller_mode="continuous"))
    ref = Reference.step(math.radians(20.0), offset=math.radians(-10.0))
    b = run(model, ref, 0.02, "reference", output_dt=1e-4, time_limit_s=60.0)
    a = run(model, ref, 0.02, "rk4", output_dt=1e-4)
    at_limit = np.abs(b.motor_voltage) >= 40.0 * (1 - 1e-9)
    assert at_limit.mean() > 0.8
    scale = np.ptp(b.output_angle)
    assert np.max(np.abs(a.output_angle - b.output_angle)) < 1e-4 * scale
    assert np.max(np.abs(a.motor_current - b.motor_current)) < 1e-3 * np.max(np.abs(b.motor_current))


def test_reference_budget_raises_with_the_time_reached():
    scene = build(BASE)
    model = build_model(scene, default_controller(scene), ModelOptions(controller_mode="continuous"))
    with pytest.raises(SimulationError, match=r"stalled at t = .* after \d+ right-hand-side evaluations"):
        run(model, Reference.sine(math.radians(2.0), 8.0), 0.05, "reference", max_rhs_evals=200)
