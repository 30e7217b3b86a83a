"""Plant blocks: two-mass resonance, reflected inertia, closed-form responses."""

import math

import control as ct
import numpy as np
import pytest

from servo_toolkit import load_scene
from servo_toolkit.loop.response import plant_responses
from servo_toolkit.plant.current_loop import current_controller, sample_delay
from servo_toolkit.plant.linear import mechanics, plant_parameters, rigid_plant, two_mass_damping, two_mass_plant

from .conftest import SCENES


@pytest.fixture(scope="module")
def ema():
    return load_scene()


def test_split_adds_up_to_reflected_inertia(ema):
    q = np.array([-0.4, 0.0, 0.3])
    split = ema.drivetrain.chain.two_mass(q)
    np.testing.assert_allclose(split.motor_side + split.load_side, ema.drivetrain.inertia(q)[0], rtol=1e-12)
    # the reduction keeps the chain's lowest mode: its stiffness is the series total to within
    # the share of the inertia between the springs (0.2 % here)
    np.testing.assert_allclose(split.stiffness, ema.drivetrain.stiffness(q).total, rtol=2e-3)
    assert split.spring[0] == "link rod and rocker arm"  # the rod has the largest compliance share


@pytest.mark.parametrize("zeta", [0.0, 0.02, 0.1])
def test_two_mass_resonance_matches_closed_form(ema, zeta):
    p = plant_parameters(ema, 0.0, structural_damping=zeta)
    wn = math.sqrt(p.K * (1 / p.J1 + 1 / p.J2))
    mech = mechanics(ema, 0.0, structural_damping=zeta)
    poles = ct.poles(mech)
    osc = poles[np.abs(poles.imag) > 1.0]
    # spring + damper between two free inertias: s^2 + c (1/J1 + 1/J2) s + K (1/J1 + 1/J2)
    np.testing.assert_allclose(np.abs(osc), wn, rtol=1e-6)
    # the two-mass mode has the chain's lowest mode's damping ratio, each compliance damped at
    # zeta in the mode it dominates: the rod dominates the lowest mode (58 % of its strain
    # energy), the dampers of the housing and the screw add 1.2 % of zeta
    want = two_mass_damping(ema.drivetrain.chain, 0.0, zeta)
    assert want == pytest.approx(zeta, rel=0.02)
    # motor viscous friction (b N^2 on the motor side) adds ~2e-4 to the mode's damping ratio
    np.testing.assert_allclose(-osc.real / np.abs(osc), want, atol=5e-4)
    assert 25 < wn / (2 * math.pi) < 40  # "near 30 Hz"


def test_antiresonance_is_a_zero_of_motor_speed(ema):
    p = plant_parameters(ema, 0.0, structural_damping=0.0)
    mech = mechanics(ema, 0.0, structural_damping=0.0)
    z = ct.zeros(mech["omega_m", "tau_m"])
    np.testing.assert_allclose(np.max(np.abs(z)), math.sqrt(p.K / p.J2), rtol=1e-6)


def test_rigid_plant_steady_speed_and_named_signals(ema):
    g = rigid_plant(ema, 0.0, inductance=True)
    assert g.input_labels == ["u", "tau_ext"]
    assert g.output_labels == ["theta", "omega_m", "i", "omega"]
    assert g.state_labels == ["theta", "omega", "i"]
    p = plant_parameters(ema, 0.0, "rigid")
    # constant voltage, no load: R i = u - Ke w_m and the torque balances the viscous friction
    b = p.b1 + p.b2
    w = 1.0 * p.torque_gain / (b * p.R + p.torque_gain * p.Ke * p.N)
    np.testing.assert_allclose(g["omega", "u"](1e-9j).real, w, rtol=1e-6)  # theta integrates


@pytest.mark.parametrize("inductance", [True, False])
def test_closed_form_matches_state_space(ema, inductance):
    p = plant_parameters(ema, 0.0)
    g = two_mass_plant(ema, 0.0, inductance=inductance)
    kp, ki = 3.0, 3000.0
    cur = current_controller(kp, ki)
    if not inductance:  # closed forms assume an ideal current loop without inductance
        p = p.__class__(**{**p.__dict__, "L": 0.0})
        cur = current_controller(0, 0, type("M", (), {"inductance": 0.0, "resistance": p.R,
                                                       "back_emf_constant": p.Ke})())
    sys = ct.interconnect([g, cur], inplist=["i_cmd"], outlist=["omega_m", "theta"], check_unused=False)
    w = np.logspace(0, 3.5, 50)
    r = ct.frequency_response(sys, w)
    p1, p2 = plant_responses(1j * w, p, kp, ki)
    np.testing.assert_allclose(np.asarray(r.complex)[0, 0], p.N * 1j * w * p1, rtol=1e-8)
    np.testing.assert_allclose(np.asarray(r.complex)[1, 0], p2, rtol=1e-8)


def test_cam_plant_is_rigid_and_delay_block(ema):
    cam = load_scene(SCENES / "cam_follower.toml")
    p = plant_parameters(cam)
    assert p.rigid and p.L == 0
    assert rigid_plant(cam).state_labels == ["theta", "omega"]
    d = sample_delay(1e-4)
    w = 2 * np.pi * 50
    np.testing.assert_allclose(np.angle(d(1j * w)), -1.5e-4 * w, rtol=1e-6)
    np.testing.assert_allclose(abs(d(1j * w)), 1.0)
