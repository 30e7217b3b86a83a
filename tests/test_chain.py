"""The lumped drivetrain chain checked against closed forms computed here by hand: every
inertia at its node, two-mass resonance and antiresonance for both layouts, three-mass modes."""

import math

import numpy as np
import pytest

from servo_toolkit import load_scene
from servo_toolkit.components.ball_screw import BallScrew
from servo_toolkit.components.compliance import Compliance, Load
from servo_toolkit.components.gear import GearTrain
from servo_toolkit.components.motor import DCMotor
from servo_toolkit.drivetrain.reflected import Drivetrain

from .conftest import SCENES

J_ROTOR, J_PINION, J_WHEEL, J_LOAD, N = 2e-4, 1.5e-4, 0.02, 0.6, 20.0


def motor(rotor=J_ROTOR):
    return DCMotor(resistance=0.5, inductance=0.0, torque_constant=0.2, back_emf_constant=0.2,
                   rotor_inertia=rotor, viscous_friction=0.0, coulomb_friction=0.0)


def mesh_layout(k=2.0e4):
    """A gear stage with its own mesh stiffness (at its output shaft), then the load."""
    gear = GearTrain("gear", ratio=N, inertias=(J_PINION, J_WHEEL), torsional_stiffness=k)
    return Drivetrain(motor(), (gear,), Load(inertia=J_LOAD))


def shaft_layout(k=2.0e4):
    """A rigid gear stage, then a compliant output shaft, then the load."""
    gear = GearTrain("gear", ratio=N, inertias=(J_PINION, J_WHEEL))
    return Drivetrain(motor(), (gear, Compliance("shaft", k)), Load(inertia=J_LOAD))


def two_mass_forms(jm, jl, k):
    return math.sqrt(k * (jm + jl) / (jm * jl)), math.sqrt(k / jl)


@pytest.mark.parametrize("layout, jm, jl", [
    # the pinion turns with the motor: motor side of its mesh spring; the wheel beyond it
    (mesh_layout, (J_ROTOR + J_PINION) * N**2, J_WHEEL + J_LOAD),
    # a rigid gear's wheel turns with the motor side of the compliant shaft that follows it
    (shaft_layout, (J_ROTOR + J_PINION) * N**2 + J_WHEEL, J_LOAD),
])
def test_two_mass_resonance_and_antiresonance_for_both_layouts(layout, jm, jl):
    k = 2.0e4
    chain = layout(k).chain
    w_r, w_a = two_mass_forms(jm, jl, k)
    np.testing.assert_allclose(chain.eigenfrequencies(0.0), [w_r], rtol=1e-10)
    np.testing.assert_allclose(chain.antiresonances(0.0), [w_a], rtol=1e-10)
    for split, rtol in ((chain.node_split([0.0, 0.1]), 1e-12), (chain.two_mass([0.0, 0.1]), 1e-9)):
        np.testing.assert_allclose(split.motor_side, jm, rtol=rtol)
        np.testing.assert_allclose(split.load_side, jl, rtol=rtol)
        np.testing.assert_allclose(split.stiffness, k, rtol=rtol)
    np.testing.assert_allclose(chain.modal_two_mass(0.0), (jm, jl, k), rtol=1e-9)


def test_mass_and_stiffness_matrices_of_the_mesh_layout():
    chain = mesh_layout(3.0e4).chain
    np.testing.assert_allclose(chain.mass_matrix(0.0),
                               np.diag([(J_ROTOR + J_PINION) * N**2, J_WHEEL + J_LOAD]), rtol=1e-12)
    np.testing.assert_allclose(chain.stiffness_matrix(0.0), [[3e4, -3e4], [-3e4, 3e4]], rtol=1e-12)


def test_three_mass_chain_solves_its_characteristic_equation():
    """Gear mesh k1 between rotor+pinion and wheel, shaft k2 between wheel and load:
    det(K - lam M) = -lam (A lam^2 - B lam + C) with A = m0 m1 m2,
    B = k1 m1 m2 + (k1 + k2) m0 m2 + k2 m0 m1, C = k1 k2 (m0 + m1 + m2)."""
    k1, k2 = 5.0e4, 1.2e4
    gear = GearTrain("gear", ratio=N, inertias=(J_PINION, J_WHEEL), torsional_stiffness=k1)
    chain = Drivetrain(motor(), (gear, Compliance("shaft", k2)), Load(inertia=J_LOAD)).chain
    m0, m1, m2 = (J_ROTOR + J_PINION) * N**2, J_WHEEL, J_LOAD
    a, b, c = m0 * m1 * m2, k1 * m1 * m2 + (k1 + k2) * m0 * m2 + k2 * m0 * m1, k1 * k2 * (m0 + m1 + m2)
    lam = np.sort([(b - math.sqrt(b * b - 4 * a * c)) / (2 * a), (b + math.sqrt(b * b - 4 * a * c)) / (2 * a)])
    np.testing.assert_allclose(chain.eigenfrequencies(0.0), np.sqrt(lam), rtol=1e-9)
    # motor held: the wheel and the load on k1 + k2 and k2
    a2, b2, c2 = m1 * m2, (k1 + k2) * m2 + k2 * m1, k1 * k2
    lam2 = np.sort([(b2 - math.sqrt(b2 * b2 - 4 * a2 * c2)) / (2 * a2),
                    (b2 + math.sqrt(b2 * b2 - 4 * a2 * c2)) / (2 * a2)])
    np.testing.assert_allclose(chain.antiresonances(0.0), np.sqrt(lam2), rtol=1e-9)
    # the node split is at the more compliant spring (the shaft, at the output)
    split = chain.node_split([0.0])
    assert split.spring == ("shaft",)
    np.testing.assert_allclose([split.motor_side[0], split.load_side[0], split.stiffness[0]],
                               [m0 + m1, m2, k1 * k2 / (k1 + k2)], rtol=1e-12)
    # the two-mass reduction keeps the lowest mode and antiresonance and the total inertia
    two = chain.two_mass([0.0])
    j1, j2, k = two.motor_side[0], two.load_side[0], two.stiffness[0]
    assert j1 + j2 == pytest.approx(m0 + m1 + m2, rel=1e-12)
    w_r, w_a = two_mass_forms(j1, j2, k)
    assert w_r == pytest.approx(math.sqrt(lam[0]), rel=1e-9)
    assert w_a == pytest.approx(math.sqrt(lam2[0]), rel=1e-9)


def test_a_massless_node_is_condensed_statically():
    """Two springs in series with nothing between them act as one, k1 k2 / (k1 + k2)."""
    k1, k2 = 4.0e4, 1.0e4
    gear = GearTrain("gear", ratio=N, inertias=(J_PINION,), torsional_stiffness=k1)
    chain = Drivetrain(motor(), (gear, Compliance("shaft", k2)), Load(inertia=J_LOAD)).chain
    w_r, w_a = two_mass_forms((J_ROTOR + J_PINION) * N**2, J_LOAD, k1 * k2 / (k1 + k2))
    np.testing.assert_allclose(chain.eigenfrequencies(0.0), [w_r], rtol=1e-9)
    np.testing.assert_allclose(chain.antiresonances(0.0), [w_a], rtol=1e-9)


def test_the_screw_sits_before_its_spring_and_loss_the_nut_beyond():
    screw = BallScrew("screw", lead=0.005, screw_inertia=1e-5, nut_mass=0.5, efficiency=0.9,
                      axial_stiffness=1e8)
    gear = GearTrain("gear", ratio=3.0, inertias=(1e-5, 3e-5), efficiency=0.95)
    chain = Drivetrain(motor(), (gear, screw), Load(inertia=20.0)).chain
    where = {e.label: (e.node, e.loss) for e in chain.elements}
    assert where["motor rotor"] == (0, 1.0)
    assert where["gear: gear 1"] == (0, 1.0)
    assert where["gear: gear 2"] == (0, pytest.approx(0.95))
    assert where["screw: screw"] == (0, pytest.approx(0.95))
    assert where["screw: nut"] == (1, pytest.approx(0.855))
    assert where["load"] == (1, pytest.approx(0.855))
    assert [s.nodes for s in chain.springs] == [(0, 1)] and chain.springs[0].unit == "N/m"


def test_loss_inertia_is_the_inertia_before_a_single_loss():
    """One lossy stage: J_w is what turns before its loss (rotor and pinion), reflected."""
    gear = GearTrain("gear", ratio=N, inertias=(J_PINION, J_WHEEL), efficiency=0.8)
    chain = Drivetrain(motor(), (gear,), Load(inertia=J_LOAD)).chain
    np.testing.assert_allclose(chain.loss_inertia([0.0]), (J_ROTOR + J_PINION) * N**2, rtol=1e-12)
    lossless = Drivetrain(motor(), (GearTrain("gear", ratio=N, inertias=(J_PINION,)),), Load(J_LOAD))
    assert np.all(lossless.chain.loss_inertia([0.0, 0.1]) == 0.0)


def test_reference_ema_places_each_member_at_its_node():
    chain = load_scene(SCENES / "ema_reference.toml").drivetrain.chain
    node = {e.label: e.node for e in chain.elements}
    assert node["motor rotor"] == node["spur gear train: gear 1"] == 0
    assert node["spur gear train: gear 2"] == node["spur gear train: gear 3"] == node["ball screw: screw"] == 1
    assert node["ball screw: nut"] == node["link rod and rocker arm: rod end at nut"] == 2
    assert node["link rod and rocker arm: output shaft"] == node["link rod and rocker arm: rod end at arm"] == 3
    assert node["load"] == 4 and chain.n_nodes == 5
    assert [s.label for s in chain.springs] == ["spur gear train", "ball screw", "link rod and rocker arm",
                                                "housing"]
    assert [b.spring for b in chain.lashes] == [0, 1]
    # four compliances, four modes; the node split's series stiffness is within 0.1 % of the
    # lowest, the two-mass reduction keeps it
    w = chain.eigenfrequencies(0.0)
    assert w.size == 4
    for split, rel in ((chain.node_split([0.0]), 1e-3), (chain.two_mass([0.0]), 1e-9)):
        w2 = math.sqrt(split.stiffness[0] * (1 / split.motor_side[0] + 1 / split.load_side[0]))
        assert w2 == pytest.approx(w[0], rel=rel)


def test_a_lash_in_a_rigid_stage_is_known_as_such():
    gear = GearTrain("gear", ratio=N, inertias=(J_PINION,), backlash=math.radians(5))
    chain = Drivetrain(motor(), (gear,), Load(inertia=J_LOAD)).chain
    assert chain.rigid and [b.key for b in chain.rigid_lashes] == ["drivetrain[0].backlash"]
