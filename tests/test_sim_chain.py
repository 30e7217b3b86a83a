"""The compiled model takes its two-mass split and its loss placement from the drivetrain's
chain: its Jacobian at rest is the linear plant's for both layouts, a geared ball-screw axis
accelerates as the catalogue says, and a free play in a rigid chain is refused."""

import math

import numpy as np
import pytest

from servo_toolkit.components.ball_screw import BallScrew
from servo_toolkit.components.compliance import Compliance, Load
from servo_toolkit.components.gear import GearTrain
from servo_toolkit.components.motor import DCMotor
from servo_toolkit.errors import SceneError
from servo_toolkit.plant.linear import plant_matrices, plant_parameters
from servo_toolkit.scene.loader import Scene
from servo_toolkit.sim import ModelOptions, Reference, build_model
from servo_toolkit.sim import layout as lo
from servo_toolkit.sim.ivp import make_fun
from servo_toolkit.sim.reference import fill

J_ROTOR, J_PINION, J_WHEEL, J_LOAD, N, K = 2e-4, 1.5e-4, 0.02, 0.6, 20.0, 2.0e4


def scene(stages, load=J_LOAD, rotor=J_ROTOR):
    motor = DCMotor(resistance=0.5, inductance=1e-3, torque_constant=0.2, back_emf_constant=0.2,
                    rotor_inertia=rotor, viscous_friction=1e-4, coulomb_friction=0.0, current_limit=20.0)
    return Scene("chain test", motor=motor, stages=tuple(stages), load=Load(inertia=load, damping=0.3))


LAYOUTS = {
    "mesh": lambda: scene([GearTrain("gear", ratio=N, inertias=(J_PINION, J_WHEEL), torsional_stiffness=K)]),
    "shaft": lambda: scene([GearTrain("gear", ratio=N, inertias=(J_PINION, J_WHEEL)), Compliance("shaft", K)]),
}


def jacobian(model, P, x0, h):
    """Central differences of the compiled right-hand side in the state and in the voltage."""
    n = 5
    jac = np.zeros((n, n + 1))
    for k in range(n + 1):
        plus, minus = x0.copy(), x0.copy()
        Pp, Pm = P.copy(), P.copy()
        if k < n:
            plus[k] += h[k]
            minus[k] -= h[k]
        else:
            Pp[lo.V_OPEN] += h[k]
            Pm[lo.V_OPEN] -= h[k]
        jac[:, k] = (make_fun(model, Pp, [0.0])(0.0, plus)[:n] - make_fun(model, Pm, [0.0])(0.0, minus)[:n]) / (2 * h[k])
    return jac


@pytest.mark.parametrize("layout", sorted(LAYOUTS))
def test_jacobian_at_rest_is_the_linear_plant_for_both_layouts(layout):
    """States (p, p', q, q', i) against the plant's (theta_1, omega_1, theta, omega, i), input
    the voltage; the same structural damping ratio in both."""
    sc = LAYOUTS[layout]()
    zeta = 0.05
    model = build_model(sc, None, ModelOptions(damping_ratio=zeta))
    assert not model.rigid
    P = fill(model, Reference.voltage(0.0))
    x0 = np.zeros(model.nx)
    x0[0] = x0[2] = model.q0
    jac = jacobian(model, P, x0, [1e-7, 1e-5, 1e-7, 1e-5, 1e-4, 1e-3])
    A, B, _, _, states = plant_matrices(plant_parameters(sc, model.q0, structural_damping=zeta))
    assert states == ["theta_1", "omega_1", "theta", "omega", "i"]
    np.testing.assert_allclose(jac[:, :5], A, rtol=1e-5, atol=1e-6 * np.max(np.abs(A)))
    np.testing.assert_allclose(jac[:, 5], B[:, 0], rtol=1e-5, atol=1e-9)


def test_geared_ball_screw_axis_accelerates_as_the_catalogue_says():
    """Rigid gear i (eta_g) and ball screw of lead P (eta_s) moving a mass m at the current
    limit, driving: a = eta N Kt I / (eta N^2 J_r + m), N = 2 pi i / P."""
    i_g, lead, mass, eta_g, eta_s = 3.0, 0.005, 40.0, 0.95, 0.9
    sc = scene([GearTrain("gear", ratio=i_g, efficiency=eta_g), BallScrew("screw", lead=lead, efficiency=eta_s)],
               load=mass, rotor=3e-4)
    sc = Scene(sc.name, motor=sc.motor, stages=sc.stages, load=Load(inertia=mass))
    model = build_model(sc, None, ModelOptions(inductance=False))
    assert model.rigid
    P = fill(model, Reference.voltage(0.0))
    n, eta, kt, current = 2 * math.pi * i_g / lead, eta_g * eta_s, 0.2, 20.0
    speed = 0.05                         # m/s: the motor at ~190 rad/s, the smooth signs saturated
    P[lo.V_OPEN] = 0.5 * current + 0.2 * n * speed
    x = np.zeros(model.nx)
    x[:4] = model.q0, speed, model.q0, speed
    accel = make_fun(model, P, [0.0])(0.0, x)[1]
    friction = 1e-4 * n * speed * n     # the motor's viscous friction, reflected
    expected = eta * (n * kt * current - friction) / (eta * n**2 * 3e-4 + mass)
    assert accel == pytest.approx(expected, rel=1e-6)
    # the old placement (the loss on the rotor's torque too) was 5 % lower here
    assert accel > 1.04 * eta * (n * kt * current - friction) / (n**2 * 3e-4 + mass)


def test_a_backlash_in_a_rigid_chain_is_refused_with_its_key():
    sc = scene([GearTrain("gear", ratio=N, inertias=(J_PINION,), backlash=math.radians(5))])
    with pytest.raises(SceneError) as err:
        build_model(sc, None)
    assert err.value.key == "drivetrain[0].backlash" and "rigid" in err.value.rule and "5 deg" in err.value.rule
    # left out on purpose, it runs
    assert build_model(sc, None, ModelOptions(backlash=False)).rigid


def test_a_backlash_beside_a_compliance_is_kept():
    sc = scene([GearTrain("gear", ratio=N, inertias=(J_PINION, J_WHEEL), backlash=math.radians(1)),
                Compliance("shaft", K)])
    model = build_model(sc, None)
    assert model.P[lo.HALF_PLAY] == pytest.approx(0.5 * math.radians(1))


def test_jacobian_at_rest_is_the_linear_plant_on_the_reference_ema():
    """The shipped EMA (four compliances reduced to its lowest mode), lossless and without
    Coulomb friction or lash so that the state at rest is smooth: the compiled model at q0 is
    the design plant."""
    from dataclasses import replace

    from servo_toolkit import load_scene

    from .conftest import SCENES
    ema = load_scene(SCENES / "ema_reference.toml")
    stages = tuple(replace(s, efficiency=1.0) if hasattr(s, "efficiency") else s for s in ema.stages)
    sc = replace(ema, stages=stages, motor=replace(ema.motor, coulomb_friction=0.0))
    zeta = 0.05
    model = build_model(sc, None, ModelOptions(damping_ratio=zeta, backlash=False))
    P = fill(model, Reference.voltage(0.0))
    x0 = np.zeros(model.nx)
    x0[0] = x0[2] = model.q0
    jac = jacobian(model, P, x0, [1e-7, 1e-5, 1e-7, 1e-5, 1e-4, 1e-3])
    A, B, _, _, _ = plant_matrices(plant_parameters(sc, model.q0, structural_damping=zeta))
    np.testing.assert_allclose(jac[:, :5], A, rtol=1e-5, atol=1e-6 * np.max(np.abs(A)))
    np.testing.assert_allclose(jac[:, 5], B[:, 0], rtol=1e-5, atol=1e-9)
