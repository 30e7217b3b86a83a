"""The compiled model of the full drivetrain chain: every compliance, every mode.

Checked against the chain's linear plant (Jacobian at rest and, with losses, while driving),
against a closed-form three-mass chain (sine dwell at each mode), against energy
conservation, and on every shipped scene by a small-signal sine dwell against the plant.
"""

import math
from dataclasses import replace

import numpy as np
import pytest

from servo_toolkit import load_scene
from servo_toolkit.components.compliance import Compliance, Load
from servo_toolkit.components.gear import GearTrain
from servo_toolkit.components.motor import DCMotor
from servo_toolkit.errors import SimulationError
from servo_toolkit.plant.chain_plant import chain_plant
from servo_toolkit.scene.loader import Scene
from servo_toolkit.sim import ModelOptions, Reference, build_model, run
from servo_toolkit.sim import layout as lo
from servo_toolkit.sim.chain_model import segment_stiffness, segments
from servo_toolkit.sim.chain_split import MIN_BACKDRIVE
from servo_toolkit.sim.ivp import make_fun
from servo_toolkit.sim.reference import fill, initial_state

from .conftest import SCENES

ZETA = 0.05


def lossless(scene, coulomb=0.0):
    stages = tuple(replace(s, efficiency=1.0) if hasattr(s, "efficiency") else s for s in scene.stages)
    return replace(scene, stages=stages, motor=replace(scene.motor, coulomb_friction=coulomb))


def three_mass(j=(1e-3, 4e-3, 2e-3), k=(2.0e3, 5.0e3), load=None):
    """Rotor J1 (with the pinion), a 1:1 gear whose wheel J2 sits beyond its mesh spring k1,
    a shaft k2 to the load J3: the textbook free-free three-mass chain."""
    motor = DCMotor(resistance=1.0, inductance=0.0, torque_constant=0.1, back_emf_constant=0.1,
                    rotor_inertia=j[0], viscous_friction=0.0, coulomb_friction=0.0, current_limit=50.0,
                    voltage_limit=100.0)
    stages = (GearTrain("gear", ratio=1.0, inertias=(0.0, j[1]), torsional_stiffness=k[0]),
              Compliance("shaft", k[1]))
    return Scene("three mass", motor=motor, stages=stages, load=load or Load(inertia=j[2]))


def node_order(model):
    o = int(model.P[lo.OFF_NODE])
    nm = int(model.P[lo.NMID])
    theta = [0] + [o + 2 * j for j in range(nm)] + [2]
    return theta, [i + 1 for i in theta]


def numeric_jacobian(model, P, x0, rows):
    f = make_fun(model, P, [0.0])
    jac = np.zeros((len(rows), len(rows)))
    for c, k in enumerate(rows):
        h = (1e-7 if k != 4 else 1e-4) * (1 + abs(x0[k]))
        xp, xm = x0.copy(), x0.copy()
        xp[k] += h
        xm[k] -= h
        jac[:, c] = (f(0.0, xp)[rows] - f(0.0, xm)[rows]) / (2 * h)
    return jac


def test_reference_ema_full_model_has_every_node():
    model = build_model(load_scene(SCENES / "ema_reference.toml"), None, ModelOptions(chain="full"))
    assert model.P[lo.NMID] == 3 and model.nx == 13
    assert model.state_names[-6:] == ("node[1]_position", "node[1]_rate", "node[2]_position", "node[2]_rate",
                                      "node[3]_position", "node[3]_rate")
    assert max(model.table_error.values()) < 1e-9


@pytest.mark.parametrize("driving", [False, True])
def test_jacobian_is_the_chain_plant_at_rest_and_while_driving(driving):
    """Lossless at rest: exact. With the stages' losses, driving (torque and speed positive,
    the smooth signs saturated): the chain's driving-mode plant, each element and spring at
    its place behind its losses."""
    ema = load_scene(SCENES / "ema_reference.toml")
    sc = replace(ema, motor=replace(ema.motor, coulomb_friction=0.0)) if driving else lossless(ema)
    model = build_model(sc, None, ModelOptions(chain="full", damping_ratio=ZETA, backlash=False))
    P = fill(model, Reference.voltage(0.0))
    x0 = initial_state(model, P, at_rest=True)
    theta, omega = node_order(model)
    if driving:
        speed, force, current = 0.5, 60.0, 30.0
        k = segment_stiffness(sc.drivetrain.chain, [model.q0], segments(sc.drivetrain.chain, model.q0))[:, 0]
        pos = np.cumsum(np.r_[0.0, force / k[::-1]])[::-1] + model.q0  # every spring carries the force
        x0[theta] = pos
        x0[omega] = speed
        x0[4] = current
    jac = numeric_jacobian(model, P, x0, theta + omega + [4])
    A = chain_plant(sc, model.q0, structural_damping=ZETA).A
    tol = 2e-4 if driving else 1e-6
    np.testing.assert_allclose(jac, A, rtol=tol, atol=tol * np.max(np.abs(A)))


def test_three_mass_modes_by_sine_dwell_match_the_closed_form():
    """Three-mass chain: its modes w^2 solve J1 J2 J3 w^4 - (k1 J3 (J1 + J2) + k2 J1 (J2 + J3)) w^2
    + k1 k2 (J1 + J2 + J3) = 0; driven by the motor torque at w, the load moves against the
    motor as (K + j w C - w^2 M)^-1 e1 says (C = beta_1 K_1 + beta_2 K_2, each spring's damper
    set by the mode it dominates: beta_i = 2 zeta / (w_k e_ik), e_ik the share of mode k's
    strain energy in spring i, from the mode shapes of the characteristic equation; the motor's
    own damping acts on node 1 only and does not enter the ratio). A sine dwell of the compiled
    model at 0.9 of each mode measures that ratio of the load's and the motor's speeds."""
    j1, j2, j3 = 1e-3, 4e-3, 2e-3
    k1, k2 = 2.0e3, 5.0e3
    a = j1 * j2 * j3
    b = -(k1 * j3 * (j1 + j2) + k2 * j1 * (j2 + j3))
    c = k1 * k2 * (j1 + j2 + j3)
    w2 = np.sort(np.roots([a, b, c]).real)
    sc = three_mass()
    chain = sc.drivetrain.chain
    np.testing.assert_allclose(chain.eigenfrequencies(0.0) ** 2, w2, rtol=1e-10)
    zeta = 0.05
    model = build_model(sc, None, ModelOptions(chain="full", damping_ratio=zeta, inductance=False))
    assert model.P[lo.NMID] == 1
    theta, omega = node_order(model)
    K = np.array([[k1, -k1, 0], [-k1, k1 + k2, -k2], [0, -k2, k2]])
    M = np.diag([j1, j2, j3])
    shapes = [np.linalg.svd(K - wk2 * M)[2][-1] for wk2 in w2]  # the null vector at each mode
    e = np.array([[k1 * (v[0] - v[1]) ** 2, k2 * (v[1] - v[2]) ** 2] for v in shapes])
    e /= e.sum(axis=1, keepdims=True)
    assert e[0, 0] > e[1, 0] and e[1, 1] > e[0, 1]  # the mesh dominates mode 1, the shaft mode 2
    beta = 2 * zeta / (np.sqrt(w2) * np.diag(e))
    C = beta[0] * np.array([[k1, -k1, 0], [-k1, k1, 0], [0, 0, 0]]) + beta[1] * np.array(
        [[0, 0, 0], [0, k2, -k2], [0, -k2, k2]])
    for wk in np.sqrt(w2):
        f = 0.9 * wk / (2 * math.pi)
        res = run(model, Reference.voltage(0.0, swing=1.0, frequency=f), 40 / f, method="rk4", dt=1 / (f * 400))
        # the forced response: (K + j w C - w^2 M) X = e1 T -> load/motor ratio
        w = 2 * math.pi * f
        x = np.linalg.solve(K + 1j * w * C - w**2 * M, [1.0, 0.0, 0.0])
        ratio = x[2] / x[0]
        tail = res.times > 20 / f
        wm = res.states[tail, 1]
        wl = res.states[tail, 3]
        basis = np.column_stack([np.sin(w * res.times[tail]), np.cos(w * res.times[tail]), np.ones(tail.sum())])
        cm = np.linalg.lstsq(basis, wm, rcond=None)[0]
        cl = np.linalg.lstsq(basis, wl, rcond=None)[0]
        measured = (cl[0] + 1j * cl[1]) / (cm[0] + 1j * cm[1])
        assert abs(measured / ratio - 1) < 1e-3


def test_undamped_lossless_full_chain_conserves_energy():
    sc = three_mass()
    model = build_model(sc, None, ModelOptions(chain="full", damping_ratio=0.0, inductance=False))
    P = fill(model, Reference.voltage(0.0))
    x = initial_state(model, P, at_rest=True)
    theta, omega = node_order(model)
    x[theta] = [0.0, 1e-3, -2e-3]
    x[omega] = [0.0, 0.0, 0.0]
    # open circuit is not modelled: the armature's back-EMF brakes the rotor; take R huge
    P[lo.R] = 1e12
    from servo_toolkit.sim.integrators import integrate
    n = 4000
    out_t, out_x, aux = np.zeros(n + 1), np.zeros((n + 1, model.nx)), np.zeros((n + 1, lo.NAUX))
    integrate(x, P, model.T, 0.0, 1e-6, n, 0, 0.0, False, 1, out_t, out_x, aux)
    jn = [1e-3, 4e-3, 2e-3]
    ks = [2.0e3, 5.0e3]

    def energy(row):
        th, om = row[theta], row[omega]
        return 0.5 * sum(j * w * w for j, w in zip(jn, om)) + 0.5 * (ks[0] * (th[0] - th[1]) ** 2
                                                                      + ks[1] * (th[1] - th[2]) ** 2)
    e = np.array([energy(r) for r in out_x])
    assert np.ptp(e) < 1e-8 * e[0]
    assert np.max(np.abs(out_x[:, omega[0]])) > 1e-3  # it did oscillate


def test_auto_lumps_modes_far_above_the_loop_and_says_so():
    model = build_model(load_scene(SCENES / "ema_reference.toml"), None)
    assert model.P[lo.NMID] == 0
    assert any("lumped into the two-mass reduction" in n and "1633" in n for n in model.notes)


def test_auto_keeps_a_second_mode_near_the_working_frequencies():
    sc = three_mass(k=(20.0, 60.0))  # modes of a few Hz
    assert sc.drivetrain.chain.eigenfrequencies(0.0)[1] / (2 * math.pi) < 80
    model = build_model(sc, None)
    assert model.P[lo.NMID] == 1
    assert any("full drivetrain chain" in n for n in model.notes)


def test_the_paper_scheme_refuses_the_full_chain():
    model = build_model(three_mass(), None, ModelOptions(chain="full"))
    with pytest.raises(SimulationError, match="two-mass"):
        run(model, Reference.voltage(1.0), 0.01, method="paper", dt=1e-5)


def test_rk4_step_follows_the_stiffer_chain():
    """The full chain's fast modes lower RK4's stability limit: the automatic step follows,
    and a user step beyond it is refused naming the limit."""
    sc = load_scene(SCENES / "ema_reference.toml")
    two = build_model(sc, None, ModelOptions(chain="two_mass"))
    full = build_model(sc, None, ModelOptions(chain="full"))
    r2 = run(two, Reference.voltage(1.0), 0.05, method="auto")
    rf = run(full, Reference.voltage(1.0), 0.05, method="auto")
    assert rf.dt_s < 0.5 * r2.dt_s
    with pytest.raises(SimulationError, match="stability region"):
        run(full, Reference.voltage(1.0), 0.002, method="rk4", dt=1e-4)


def _motor_driven(path):
    from servo_toolkit.errors import SceneError
    sc = load_scene(path)
    try:
        sc.drivetrain.check()
    except (SceneError, AttributeError):
        return None
    return sc if sc.motor is not None else None


def _dwell(model, swing, f, settle, periods, dt):
    """Phasors per volt of the motor speed, the output speed and the current: a voltage sine
    of ``swing`` V at f run for ``settle`` s plus ``periods`` periods, fitted over those."""
    duration = settle + periods / f
    res = run(model, Reference.voltage(0.0, swing=swing, frequency=f), duration, method="rk4", dt=dt)
    w = 2 * math.pi * f
    tail = res.times >= duration - periods / f - 0.5 * dt
    t = res.times[tail]
    basis = np.column_stack([np.sin(w * t), np.cos(w * t), np.ones(t.size), t - t.mean()])
    out = {}
    for name, trace in (("omega_m", res.motor_speed[tail]), ("omega", res.states[tail, 3]),
                        ("i", res.motor_current[tail])):
        c = np.linalg.lstsq(basis, trace, rcond=None)[0]
        out[name] = (c[0] + 1j * c[1]) / swing  # |H| sin(wt + phi) = Re(H) sin + Im(H) cos
    return out


@pytest.mark.parametrize("path", sorted(SCENES.glob("*.toml")), ids=lambda p: p.stem)
def test_small_signal_dwell_equals_the_linear_plant_at_every_mode(path):
    """Every shipped scene with a motor-driven drivetrain, lossless, without lash or Coulomb
    friction (a cam's follower weight and guide friction off): a small voltage sine dwell of
    the compiled full model gives the linear chain plant's response (motor speed, output
    speed, current per volt; the hinge's constant moment off, its stiffness kept) within 0.1 dB and 1 deg at half, at and twice the first mode and
    at every further mode (rigid chains: from 1 Hz to 1 kHz)."""
    import control as ct

    from servo_toolkit.plant.linear import plant
    sc = _motor_driven(path)
    if sc is None:
        pytest.skip("no motor-driven drivetrain")
    sc = replace(lossless(sc), load=replace(sc.load, hinge_moment=0.0))  # open loop: no bias to hold
    if sc.drivetrain.ends_in_cam:
        cam = sc.stages[-1]
        sc = replace(sc, stages=sc.stages[:-1] + (replace(cam, follower_weight=0.0, guide_friction_coefficient=0.0),))
    model = build_model(sc, None, ModelOptions(chain="full", damping_ratio=ZETA, backlash=False))
    q0 = model.q0
    chain = sc.drivetrain.chain
    modes = chain.eigenfrequencies(q0, driving=True) / (2 * math.pi)
    freqs = [0.5 * modes[0], modes[0], 2 * modes[0], *modes[1:]] if modes.size else [1.0, 10.0, 100.0, 1000.0]
    g = plant(sc, q0, model="chain", structural_damping=ZETA)
    from servo_toolkit.sim.stability import fastest
    P = fill(model, Reference.voltage(0.0))
    limit = fastest(model, P, [initial_state(model, P, at_rest=True)], [0.0])["dt_limit_s"]
    # the slowest transient: the first mode's ringing (damping ratio ZETA), else 0.3 s
    settle = 12.0 / (ZETA * 2 * math.pi * modes[0]) if modes.size else 0.3
    for f in freqs:
        dt = min(1.0 / (200 * f), 1e-4, 0.5 * limit)
        got = _dwell(model, 1e-3 * min(sc.motor.voltage_limit, 100.0), f, settle, 20, dt)
        resp = ct.frequency_response(g, [2 * math.pi * f])
        for name in ("omega_m", "omega", "i"):
            k = g.output_labels.index(name)
            want = complex(np.asarray(resp.complex)[k, 0].ravel()[0])
            ratio = got[name] / want
            assert abs(20 * math.log10(abs(ratio))) < 0.1, (f, name, got[name], want)
            assert abs(math.degrees(np.angle(ratio))) < 1.0, (f, name, got[name], want)


def _power_terms(sc, model, res):
    """Along a run of the full chain: the power supplied at the motor shaft, the power given
    to the load, the rate of the stored energy, the dampers' dissipation and the losses' power
    by the model's loss law, at every record (W). The energy and the dampers come from the
    drivetrain's own elements and springs (node inertias J_j(p) and their inertias before the
    losses J_w,j(p), segment stiffness k_s(p)), the accelerations from the model's
    right-hand side."""
    from servo_toolkit.drivetrain.chain_damping import chain_damping
    from servo_toolkit.sim.kernel import rhs
    drive, chain = sc.drivetrain, sc.drivetrain.chain
    P = fill(model, Reference.sine(math.radians(2.0), 8.0))
    theta, omega = node_order(model)
    x = res.states
    acc = np.empty_like(x)
    aux = np.empty(lo.NAUX)
    for k in range(len(x)):
        rhs(res.times[k], x[k], P, model.T, res.current_reference[k], acc[k], aux)
    p, pd = x[:, 0], x[:, 1]
    y, yd, ydd = x[:, theta].T, x[:, omega].T, acc[:, omega].T  # (n_nodes, n_t)
    segs = segments(chain, model.q0)
    keep = [0] + [b for _, b in segs]
    jn, djn = (a[keep] for a in chain.node_jets(p))
    jw, djw = (a[keep] for a in chain.node_jets(p, chain.loss_fractions()))
    h = 1e-6
    k = segment_stiffness(chain, p, segs)
    dk = (segment_stiffness(chain, p + h, segs) - segment_stiffness(chain, p - h, segs)) / (2 * h)
    z, zd = y[:-1] - y[1:], yd[:-1] - yd[1:]
    stored_rate = (np.sum(jn * yd * ydd + 0.5 * djn * pd * yd**2, axis=0)
                   + np.sum(k * z * zd + 0.5 * dk * pd * z**2, axis=0))
    beta = chain_damping(chain, model.q0, model.options.damping_ratio).beta[:, None]
    force = k * z + beta * k * zd
    damping = np.sum(beta * k * zd**2, axis=0)
    n = drive.ratio(p)[0]
    m = sc.motor
    nts = n * (m.torque_constant * res.motor_current - m.viscous_friction * n * pd)
    viscous = m.viscous_friction * (n * pd) ** 2
    supplied = n * m.torque_constant * res.motor_current * pd
    q, qd = x[:, 2], x[:, 3]
    to_load = (sc.load.hinge_moment + sc.load.hinge_stiffness * q + sc.load.damping * qd) * qd
    # the loss law: c times the power passed on past the members before the losses (every
    # inertia and spring counted with its share of the chain's loss), c = 1 - eta driving,
    # 1 / eta_b - 1 back-driven, blended by the smooth signs of that torque and of the speed
    eta = chain.efficiency
    pi_s = chain.spring_losses()
    share = np.array([(1 - eta / pi_s[a]) / (1 - eta) for a, _ in segs])[:, None]
    passed = (nts * pd - np.sum(jw * yd * ydd + 0.5 * djw * pd * yd**2, axis=0)
              - np.sum(share * (force * zd + 0.5 * dk * pd * z**2), axis=0))
    jd = jn[0]
    jw_motor = model.P[lo.JW] * n**2
    t_free = ((jd - jw_motor) * nts - jw_motor * (-force[0] - 0.5 * dk[0] * z[0] ** 2)) * model.P[lo.INV_JD0]
    sg = np.tanh(t_free * model.P[lo.INV_TAU_S]) * np.tanh(np.abs(n) * pd * model.P[lo.WS])
    # 1 - eta driving (sg = 1), 1 - 1/eta_b back-driven (sg = -1); on this chain (1/eta_b - 1 below
    # 3 (1 - eta)) blended quadratically in sg (compliance.h's blend)
    c_drive, c_back = 1 - eta, 1 / max(drive.backdrive_efficiency, MIN_BACKDRIVE) - 1
    assert c_back <= 3 * c_drive
    c = 0.5 * (c_drive + c_back) * sg + 0.5 * (c_drive - c_back) * sg**2
    return {"supplied": supplied, "viscous": viscous, "to_load": to_load, "stored_rate": stored_rate,
            "damping": damping, "loss": c * passed, "shaft": nts * pd}


def test_energy_balance_of_the_full_chain_with_losses():
    """Along a closed-loop 8 Hz, 2 deg run of the full reference EMA with its losses (both
    directions of power flow): at every record, the electrical power turned into torque
    equals the rate of the stored energy (every node's kinetic energy with its inertia along
    the stroke, every spring's potential) plus the motor's viscous friction, the compliances'
    dampers, the losses by the model's own loss law (c times the power passed on past the
    members before them) and the power given to the load, to 1e-6 of the peak power; the
    same balance integrated over the run holds to 1e-4 of the energy supplied."""
    from servo_toolkit.sim import controller_for
    ema = load_scene(SCENES / "ema_reference.toml")
    ema = replace(ema, motor=replace(ema.motor, coulomb_friction=0.0))
    model = build_model(ema, controller_for(ema)[0], ModelOptions(chain="full", backlash=False))
    dt = 1e-5
    res = run(model, Reference.sine(math.radians(2.0), 8.0), 0.15, "rk4", dt=dt, output_dt=4 * dt)
    w = _power_terms(ema, model, res)
    out = w["stored_rate"] + w["viscous"] + w["damping"] + w["loss"] + w["to_load"]
    scale = np.max(np.abs(w["supplied"]))
    np.testing.assert_allclose(out, w["supplied"], rtol=0, atol=1e-6 * scale)
    driving = w["shaft"] > 0
    assert driving.mean() > 0.2 and (~driving).mean() > 0.2  # both directions of power flow
    assert np.sum(w["loss"]) > 0.02 * np.sum(np.abs(w["supplied"]))  # the losses matter
    # the loss's sign follows the torque passed on judged without its velocity terms
    # (kernel.loss_coefficient): where the two differ in sign it gives back a trace of power
    assert np.min(w["loss"]) > -1e-3 * scale
    t = res.times

    def integral(f):
        return np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(t))
    gap = integral(w["supplied"] - out)
    assert abs(gap) < 1e-4 * integral(np.abs(w["supplied"]))
