"""The linear plant from the drivetrain's chain: the two-mass split for both layouts, the
catalogue formulas of a geared ball-screw axis, the n-mass plant's modes and signals."""

import math

import control as ct
import numpy as np
import pytest

from servo_toolkit.components.ball_screw import BallScrew
from servo_toolkit.components.compliance import Compliance, Load
from servo_toolkit.components.gear import GearTrain
from servo_toolkit.components.motor import DCMotor
from servo_toolkit.plant.linear import mechanics, plant, plant_parameters
from servo_toolkit.scene.loader import Scene

J_ROTOR, J_PINION, J_WHEEL, J_LOAD, N = 2e-4, 1.5e-4, 0.02, 0.6, 20.0


def motor(rotor=J_ROTOR, ke=0.2, inductance=0.0):
    return DCMotor(resistance=0.5, inductance=inductance, torque_constant=0.2, back_emf_constant=ke,
                   rotor_inertia=rotor, viscous_friction=0.0, coulomb_friction=0.0, current_limit=20.0)


def scene(stages, load=J_LOAD, **kw):
    return Scene("chain test", motor=motor(**kw), stages=tuple(stages), load=Load(inertia=load))


def mesh(k=2.0e4, eta=1.0):
    return scene([GearTrain("gear", ratio=N, inertias=(J_PINION, J_WHEEL), torsional_stiffness=k,
                            efficiency=eta)])


def shaft(k=2.0e4):
    return scene([GearTrain("gear", ratio=N, inertias=(J_PINION, J_WHEEL)), Compliance("shaft", k)])


@pytest.mark.parametrize("make, jm, jl", [
    (mesh, (J_ROTOR + J_PINION) * N**2, J_WHEEL + J_LOAD),
    (shaft, (J_ROTOR + J_PINION) * N**2 + J_WHEEL, J_LOAD),
])
def test_design_plant_resonance_is_right_for_both_layouts(make, jm, jl):
    k = 2.0e4
    p = plant_parameters(make(k), 0.0, structural_damping=0.0)
    assert 2 * math.pi * p.resonance_hz == pytest.approx(math.sqrt(k * (jm + jl) / (jm * jl)), rel=1e-10)
    assert 2 * math.pi * p.antiresonance_hz == pytest.approx(math.sqrt(k / jl), rel=1e-10)
    poles = ct.poles(mechanics(make(k), 0.0, structural_damping=0.0))
    assert np.max(np.abs(poles)) == pytest.approx(math.sqrt(k * (jm + jl) / (jm * jl)), rel=1e-8)


def test_geared_ball_screw_axis_by_catalogue_formulas():
    """Gear i (eta_g) then a ball screw of lead P (eta_s) moving a mass m, rigid: the holding
    torque T = F P / (2 pi eta i), the mass at the screw J = m (P / 2 pi)^2, and under a current
    limit the acceleration a = eta N Kt I / (eta N^2 J_r + m), N = 2 pi i / P (rad/m): the
    loss never acts on the torque that accelerates the rotor."""
    i, lead, mass, eta_g, eta_s, force = 3.0, 0.005, 40.0, 0.95, 0.9, 2000.0
    sc = scene([GearTrain("gear", ratio=i, efficiency=eta_g), BallScrew("screw", lead=lead, efficiency=eta_s)],
               load=mass, rotor=3e-4)
    dt, eta = sc.drivetrain, eta_g * eta_s
    n = 2 * math.pi * i / lead
    assert dt.motor_inertia([0.0])[0] == pytest.approx(3e-4 + mass * (lead / (2 * math.pi)) ** 2 / i**2, rel=1e-12)
    p = plant_parameters(sc, 0.0)
    kt, current = sc.motor.torque_constant, sc.motor.current_limit
    assert force / p.torque_gain * kt == pytest.approx(force * lead / (2 * math.pi * eta * i), rel=1e-12)
    g = mechanics(sc, 0.0)
    accel = (g.B[1, 0] * kt * current)       # d(omega)/dt per tau_m = Kt I at rest
    assert accel == pytest.approx(eta * n * kt * current / (eta * n**2 * 3e-4 + mass), rel=1e-12)
    # lossless, the same formula with eta = 1; the old rule (loss on the rotor's torque too)
    # would give eta N Kt I / (N^2 J_r + m), lower
    assert accel > eta * n * kt * current / (n**2 * 3e-4 + mass) * 1.01


def test_two_mass_loss_placement_on_a_compliant_gear():
    """Driving through a lossy mesh spring: the motor side counts with eta (the rotor and pinion
    before the loss), the wheel and load as they are; the torque gain is eta N Kt."""
    p = plant_parameters(mesh(eta=0.8), 0.0)
    assert p.J1 == pytest.approx(0.8 * (J_ROTOR + J_PINION) * N**2, rel=1e-12)
    assert p.J2 == pytest.approx(J_WHEEL + J_LOAD, rel=1e-12)
    assert p.torque_gain == pytest.approx(0.8 * N * 0.2, rel=1e-12)


def test_chain_plant_has_every_mode_and_named_signals():
    """Three masses (gear mesh k1, shaft k2), no back-emf and no damping: the plant's
    oscillatory poles are the chain's modes, the zeros of omega_m/u its antiresonances."""
    k1, k2 = 5.0e4, 1.2e4
    sc = scene([GearTrain("gear", ratio=N, inertias=(J_PINION, J_WHEEL), torsional_stiffness=k1),
                Compliance("shaft", k2)], ke=0.0)
    g = plant(sc, 0.0, inductance=False, model="chain", structural_damping=0.0)
    assert g.state_labels == ["theta[0]", "theta[1]", "theta[2]", "omega[0]", "omega[1]", "omega[2]"]
    assert g.input_labels == ["u", "tau_ext"]
    assert g.output_labels[:4] == ["theta", "omega_m", "i", "omega"]
    chain = sc.drivetrain.chain
    poles = ct.poles(g)
    osc = np.sort(np.abs(poles[np.abs(poles.imag) > 1.0]))[::2]
    np.testing.assert_allclose(osc, chain.eigenfrequencies(0.0), rtol=1e-8)
    zeros = ct.zeros(g["omega_m", "u"])
    np.testing.assert_allclose(np.sort(np.abs(zeros[np.abs(zeros) > 1.0]))[::2], chain.antiresonances(0.0),
                               rtol=1e-6)


def test_three_mass_modes_match_the_closed_form():
    """Free-free three masses J1 - k1 - J2 - k2 - J3 (rotor and pinion at the output; wheel;
    load): w^2 are the roots of w^4 - w^2 (k1 (1/J1 + 1/J2) + k2 (1/J2 + 1/J3))
    + k1 k2 (J1 + J2 + J3) / (J1 J2 J3) = 0 (textbook, independent of the chain's matrices)."""
    k1, k2 = 5.0e4, 1.2e4
    sc = scene([GearTrain("gear", ratio=N, inertias=(J_PINION, J_WHEEL), torsional_stiffness=k1),
                Compliance("shaft", k2)], ke=0.0)
    j1, j2, j3 = (J_ROTOR + J_PINION) * N**2, J_WHEEL, J_LOAD
    b = k1 * (1 / j1 + 1 / j2) + k2 * (1 / j2 + 1 / j3)
    c = k1 * k2 * (j1 + j2 + j3) / (j1 * j2 * j3)
    expected = np.sqrt([(b - math.sqrt(b * b - 4 * c)) / 2, (b + math.sqrt(b * b - 4 * c)) / 2])
    g = plant(sc, 0.0, inductance=False, model="chain", structural_damping=0.0)
    poles = ct.poles(g)
    np.testing.assert_allclose(np.sort(np.abs(poles[np.abs(poles.imag) > 1.0]))[::2], expected, rtol=1e-8)


def test_chain_plant_of_one_compliance_is_the_two_mass_plant():
    sc = mesh(eta=0.9)
    w = np.logspace(0, 4, 60)
    for out in ("theta", "omega_m", "i"):
        a = plant(sc, 0.0, model="chain")[out, "u"](1j * w)
        b = plant(sc, 0.0)[out, "u"](1j * w)
        np.testing.assert_allclose(a, b, rtol=1e-7)


def test_chain_model_of_a_rigid_chain_is_the_rigid_plant():
    sc = scene([GearTrain("gear", ratio=N, inertias=(J_PINION,))])
    assert plant(sc, 0.0, model="chain").state_labels == ["theta", "omega"]


def test_inverse_dynamics_places_members_and_losses_as_the_plant():
    """Driving a lossy rigid gear (pinion before its loss, wheel beyond it): the Kv inverse
    dynamics' motor torque is the plant's, tau = J1 a / (eta N) with J1 = eta (J_r + J_p) + J_w + J_L,
    i.e. (J_r + J_p) N a + (J_w + J_L) a / (eta N)."""
    from servo_toolkit.studies.mechanisms.inverse_dynamics import inverse_dynamics
    from servo_toolkit.studies.trajectories import SineMotion
    eta = 0.8
    sc = scene([GearTrain("gear", ratio=N, inertias=(J_PINION, J_WHEEL), efficiency=eta)], ke=0.0)
    motion = SineMotion(0.2, 2.0, phase=-math.pi / 2)   # q rises from its lowest point
    t = np.array([0.05, 0.08])                         # qd > 0 and qdd > 0: driving
    q, qd, qdd = motion(t)
    assert np.all(qd > 0) and np.all(qdd > 0)
    r = inverse_dynamics(sc.drivetrain, motion, t, friction=False)
    expected = (J_ROTOR + J_PINION) * N * qdd + (J_WHEEL + J_LOAD) * qdd / (eta * N)
    np.testing.assert_allclose(r.motor_torque, expected, rtol=1e-12)
    p = plant_parameters(sc, 0.0, "rigid")
    np.testing.assert_allclose(r.motor_torque, p.J1 * qdd / (eta * N), rtol=1e-12)
