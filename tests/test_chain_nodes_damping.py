"""The full chain's nodes along the stroke and the damper of each compliance.

Every node's inertia varies with the motor-side position in the compiled model as the chain
has it: the Jacobian at either stroke end is the chain plant at that end, its modes the
chain's there, and the undamped lossless chain conserves T + V along a motion across the
stroke (energy from the drivetrain's own inertias and springs). Each compliance has its own
damper: a symmetric three-mass chain (proportional damping, closed form) and one with two
separated modes (each dominated by one compliance) have the stated damping ratios as the
eigenvalues of the compiled model's Jacobian say.
"""

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy import linalg

from servo_toolkit import SceneError, load_scene
from servo_toolkit.components.compliance import Compliance, Load
from servo_toolkit.components.gear import GearTrain
from servo_toolkit.components.motor import DCMotor
from servo_toolkit.drivetrain.chain_damping import chain_damping
from servo_toolkit.plant.chain_plant import chain_plant
from servo_toolkit.plant.linear import plant_parameters, spring_damping
from servo_toolkit.scene.loader import Scene
from servo_toolkit.sim import ModelOptions, Reference, build_model
from servo_toolkit.sim import layout as lo
from servo_toolkit.sim.chain_model import segment_stiffness, segments
from servo_toolkit.sim.integrators import integrate
from servo_toolkit.sim.reference import fill, initial_state

from .conftest import SCENES, build, variant
from .test_sim_full_chain import lossless, node_order, numeric_jacobian


def open_circuit(model):
    """Parameters of an open-loop model with the armature open (no back-EMF braking)."""
    P = fill(model, Reference.voltage(0.0))
    P[lo.R] = 1e12
    return P


def frictionless(scene):
    return replace(lossless(scene), motor=replace(scene.motor, viscous_friction=0.0, coulomb_friction=0.0),
                   load=replace(scene.load, hinge_moment=0.0, damping=0.0))


@pytest.fixture(scope="module")
def ema_undamped():
    sc = frictionless(load_scene(SCENES / "ema_reference.toml"))
    return sc, build_model(sc, None, ModelOptions(chain="full", damping_ratio=0.0, backlash=False,
                                                  inductance=False))


@pytest.mark.parametrize("end", [0, 1])
def test_modes_at_the_stroke_ends_are_the_chain_s_there(ema_undamped, end):
    """At either stroke end (nodes 1 and 2 of the reference EMA carry a third less or more
    than at mid-stroke) the compiled full model's Jacobian at rest is the chain plant at that
    end, and its modes are the chain's eigenfrequencies there."""
    sc, model = ema_undamped
    q_end = sc.drivetrain.stroke[end]
    chain = sc.drivetrain.chain
    j_end, j_mid = chain.node_inertias([q_end, model.q0]).T
    assert abs(j_end[1] / j_mid[1] - 1) > 0.15  # the case the nodes' tables are for
    P = open_circuit(model)
    x = initial_state(model, P, at_rest=True)
    theta, omega = node_order(model)
    x[theta] = q_end
    jac = numeric_jacobian(model, P, x, theta + omega)
    osc = np.linalg.eigvals(jac)
    osc = np.sort(np.abs(osc.imag[osc.imag > 1.0]))
    np.testing.assert_allclose(osc, chain.eigenfrequencies(q_end, driving=True), rtol=1e-6)
    P[lo.R] = sc.motor.resistance  # the armature closed: the plant's electrical coupling too
    jac = numeric_jacobian(model, P, x, theta + omega)
    A = chain_plant(sc, q_end, inductance=False, structural_damping=0.0).A
    np.testing.assert_allclose(jac, A, rtol=1e-6, atol=1e-6 * np.max(np.abs(A)))


def test_the_undamped_lossless_chain_conserves_energy_across_the_stroke(ema_undamped):
    """Open circuit, no friction, no damping, no loss: the reference EMA coasting from -25 deg
    across the stroke while its springs ring keeps T + V, with T = sum_j J_j(p) y_j'^2 / 2
    and V = sum_s k_s(p) z_s^2 / 2 from the drivetrain's own elements and springs (not the
    model's tables), to 1e-7 of T; nodes 1 and 2 change their inertia by a third on the
    way, so a node held at its q0 inertia, or a velocity term left out, breaks the balance
    by far more."""
    sc, model = ema_undamped
    chain = sc.drivetrain.chain
    P = open_circuit(model)
    x = initial_state(model, P, at_rest=True)
    theta, omega = node_order(model)
    start = math.radians(-25.0)
    x[theta] = start + np.array([3e-4, 2e-4, 1e-4, 0.0, 0.0])  # the springs wound up
    x[omega] = 20.0  # rad/s at the output: -25 deg to about +30 deg in 47 ms
    n, dt = 23500, 2e-6
    out_t, out_x, aux = np.zeros(n // 50 + 2), np.zeros((n // 50 + 2, model.nx)), np.zeros((n // 50 + 2, lo.NAUX))
    status, _, k, _, _ = integrate(x, P, model.T, 0.0, dt, n, 0, 0.0, False, 50, out_t, out_x, aux)
    assert status == lo.OK
    rows = out_x[:k]
    p = rows[:, 0]
    assert p.max() - p.min() > math.radians(50.0)  # a motion across the stroke
    keep = [0] + [b for _, b in segments(chain, model.q0)]
    nodes = chain.node_inertias(p)[keep]  # (n_nodes, n_t) at the motor-side position
    kinetic = 0.5 * np.sum(nodes * rows[:, omega].T ** 2, axis=0)
    k = segment_stiffness(chain, p, segments(chain, model.q0))
    z = rows[:, theta[:-1]].T - rows[:, theta[1:]].T
    energy = kinetic + 0.5 * np.sum(k * z**2, axis=0)
    assert np.ptp(energy) < 1e-7 * kinetic[0]
    assert np.ptp(rows[:, 1]) > 0.05 * rows[0, 1]  # coasting, the chain's speed follows J(p)


def three_mass(j, k, zeta):
    """Rotor, a 1:1 gear's wheel beyond its mesh spring k1 (ratio zeta1), a shaft k2 (zeta2)
    to the load: the free three-mass chain, no electrical or viscous damping."""
    motor = DCMotor(resistance=1.0, inductance=0.0, torque_constant=0.1, back_emf_constant=0.1,
                    rotor_inertia=j[0], viscous_friction=0.0, coulomb_friction=0.0, current_limit=50.0,
                    voltage_limit=100.0)
    stages = (GearTrain("gear", ratio=1.0, inertias=(0.0, j[1]), torsional_stiffness=k[0], damping_ratio=zeta[0]),
              Compliance("shaft", k[1], damping_ratio=zeta[1]))
    return Scene("three mass", motor=motor, stages=stages, load=Load(inertia=j[2]))


def jacobian_modes(scene):
    """(w_k, zeta_k) of the compiled full model's Jacobian at rest, armature open."""
    model = build_model(scene, None, ModelOptions(chain="full", inductance=False, backlash=False))
    P = open_circuit(model)
    x = initial_state(model, P, at_rest=True)
    theta, omega = node_order(model)
    lam = np.linalg.eigvals(numeric_jacobian(model, P, x, theta + omega))
    lam = lam[lam.imag > 1.0]
    lam = lam[np.argsort(np.abs(lam))]
    return np.abs(lam), -lam.real / np.abs(lam)


def test_a_symmetric_three_mass_chain_has_proportional_damping():
    """J1 = J3, k1 = k2, one ratio zeta: each mode strains both springs alike, so both are
    set by the lowest mode, beta = 2 zeta / w1, C = beta K: the damping is proportional and the
    modes' ratios are zeta and zeta w2 / w1 exactly, with w1^2 = k / J1 and
    w2^2 = k (1 / J1 + 2 / J2) (the antisymmetric and the symmetric mode)."""
    j1, j2, k, zeta = 1e-3, 4e-3, 3e3, 0.05
    w, z = jacobian_modes(three_mass((j1, j2, j1), (k, k), (zeta, zeta)))
    w1, w2 = math.sqrt(k / j1), math.sqrt(k * (1 / j1 + 2 / j2))
    np.testing.assert_allclose(w, [w1, w2], rtol=1e-6)
    np.testing.assert_allclose(z, [zeta, zeta * w2 / w1], rtol=1e-5)


def test_each_compliance_gives_the_mode_it_dominates_its_ratio():
    """A soft mesh (zeta 0.02) and a stiff shaft (zeta 0.06) with their modes a decade apart:
    each mode's strain energy lies 99 % in one compliance. From the undamped chain's modes
    (solved here), beta_i = 2 zeta_i / (w_k e_ik) for the mode k compliance i dominates, and
    each mode's ratio is (w_k / 2) sum_i beta_i e_ik: the stated ratio, plus (on the upper mode)
    what the soft compliance's damper adds, 0.002. The eigenvalues of the compiled model's
    Jacobian give those ratios."""
    j, k, zeta = (1e-3, 1e-3, 1e-2), (1e3, 1e5), (0.02, 0.06)
    sc = three_mass(j, k, zeta)
    K = np.array([[k[0], -k[0], 0], [-k[0], k[0] + k[1], -k[1]], [0, -k[1], k[1]]])
    w2, phi = linalg.eigh(K, np.diag(j))
    w, phi = np.sqrt(w2[1:]), phi[:, 1:]
    e = np.array([[k[i] * (phi[i, m] - phi[i + 1, m]) ** 2 for i in range(2)] for m in range(2)])
    e /= e.sum(axis=1, keepdims=True)
    assert e[0, 0] > 0.99 and e[1, 1] > 0.99
    beta = [2 * zeta[0] / (w[0] * e[0, 0]), 2 * zeta[1] / (w[1] * e[1, 1])]
    want = [0.5 * w[m] * (beta[0] * e[m, 0] + beta[1] * e[m, 1]) for m in range(2)]
    assert want[0] == pytest.approx(zeta[0], rel=0.01) and want[1] == pytest.approx(zeta[1], abs=0.003)
    got_w, got_z = jacobian_modes(sc)
    np.testing.assert_allclose(got_w, w, rtol=1e-3)
    np.testing.assert_allclose(got_z, want, rtol=1e-3)
    d = chain_damping(sc.drivetrain.chain, 0.0, 0.05)
    np.testing.assert_allclose(d.modal_ratios, want, rtol=1e-9)
    # the two-mass reduction keeps the lowest mode's ratio
    p = plant_parameters(sc, 0.0, "two_mass")
    assert p.c == pytest.approx(spring_damping(p.J1, p.J2, p.K, want[0]), rel=1e-9)


def test_a_single_compliance_keeps_its_stated_ratio():
    """One compliance: its damper gives the two-mass mode the stage's ratio, whatever the
    default structural damping."""
    sc = three_mass((1e-3, 0.0, 2e-3), (math.inf, 4e3), (None, 0.07))
    sc = replace(sc, stages=(replace(sc.stages[0], torsional_stiffness=math.inf, damping_ratio=None),
                             sc.stages[1]))
    p = plant_parameters(sc, 0.0, "two_mass", structural_damping=0.01)
    assert p.c == pytest.approx(spring_damping(p.J1, p.J2, p.K, 0.07), rel=1e-12)


def test_the_stage_key_sets_the_compliance_s_ratio_and_a_rigid_stage_refuses_it(ema_dict):
    sc = build(variant(ema_dict, drivetrain__3__damping_ratio=0.08, drivetrain__0__damping_ratio=0.0))
    ratios = [s.damping_ratio for s in sc.drivetrain.chain.springs]
    assert ratios == [0.0, None, None, 0.08]
    bad = variant(ema_dict, drivetrain__0__damping_ratio=0.05, drivetrain__0__torsional_stiffness=None)
    with pytest.raises(SceneError, match=r"drivetrain\[0\]\.damping_ratio.*torsional_stiffness"):
        build(bad)
    with pytest.raises(SceneError, match=r"drivetrain\[3\]\.damping_ratio"):
        build(variant(ema_dict, drivetrain__3__damping_ratio=3.0))


def test_stated_ratios_reach_the_compiled_model_as_the_plant_has_them(ema_dict):
    """The reference EMA with its own ratio on the mesh and the housing: the compiled full
    model's Jacobian at rest is the chain plant's (lossless)."""
    sc = lossless(build(variant(ema_dict, drivetrain__0__damping_ratio=0.01, drivetrain__3__damping_ratio=0.1)))
    model = build_model(sc, None, ModelOptions(chain="full", backlash=False, damping_ratio=0.03))
    P = fill(model, Reference.voltage(0.0))
    x = initial_state(model, P, at_rest=True)
    theta, omega = node_order(model)
    jac = numeric_jacobian(model, P, x, theta + omega + [4])
    A = chain_plant(sc, model.q0, structural_damping=0.03).A
    np.testing.assert_allclose(jac, A, rtol=1e-6, atol=1e-6 * np.max(np.abs(A)))
    assert model.damping["segment_ratios"] == pytest.approx([0.01, 0.03, 0.03, 0.1])
