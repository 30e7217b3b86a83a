"""A lossy gear at rest holds (LossyGear's stuck mode): with friction that holds, a rigid ball
screw under a hinge force stays at rest while the motor torque lies within the band the
efficiencies give, computed here by hand from a force balance at the nut, and breaks away just
outside it (RK4, the reference solver and the batch of variants); a self-locking screw holds any
load with no current; the gear never supplies power along a run that sticks, drives and is
back-driven; the smooth model is untouched."""

import math
from dataclasses import replace

import numpy as np
import pytest

from servo_toolkit.components.ball_screw import BallScrew
from servo_toolkit.components.compliance import Load
from servo_toolkit.components.motor import DCMotor
from servo_toolkit.scene.loader import Scene
from servo_toolkit.sim import ModelOptions, Reference, build_model, run
from servo_toolkit.sim import layout as lo
from servo_toolkit.sim.reference import fill, initial_state

R, KT, LEAD = 0.5, 0.2, 0.005
J_ROTOR, J_SCREW, M_NUT, M_LOAD = 2e-4, 1e-5, 0.5, 10.0
TC_M, TS_M, B_M = 0.02, 0.03, 1e-4  # the motor's friction (N*m, N*m*s/rad)
TC_L, TS_L, F_H = 50.0, 80.0, 2000.0  # the load's friction and the hinge force against +x (N)
N = 2.0 * math.pi / LEAD  # motor rad per m of nut travel
STICK = ModelOptions(friction="stick")
#: forward efficiencies: eta_b = 2 - 1/eta (the screw catalogues' relation) 0.889, 0.6 and
#: -0.5 (self-locking)
ETAS = (0.9, 5.0 / 7.0, 0.4)


def screw(eta, hinge=F_H):
    motor = DCMotor(resistance=R, inductance=0.0, torque_constant=KT, back_emf_constant=KT, rotor_inertia=J_ROTOR,
                    viscous_friction=B_M, coulomb_friction=TC_M, static_friction=TS_M, voltage_limit=100.0,
                    current_limit=50.0)
    return Scene("lossy screw", motor=motor,
                 stages=(BallScrew("screw", lead=LEAD, screw_inertia=J_SCREW, nut_mass=M_NUT, efficiency=eta),),
                 load=Load(inertia=M_LOAD, hinge_moment=hinge, coulomb_friction=TC_L, static_friction=TS_L))


def band(eta, hinge=F_H):
    """The motor torques (N*m) between which the screw at rest holds, by a force balance at the
    nut. Forward the motor drives the nut against the hinge force and both frictions: eta N
    (tau - Ts_m) = F_h + Ts_L. Backward the hinge force (less the load's friction) drives the
    screw back through the thread, which passes eta_b of it to the shaft, against the motor
    torque and the motor's friction: eta_b (F_h - Ts_L) = N (tau + Ts_m); a self-locking
    screw (eta_b <= 0) passes nothing back, so the motor must drive it back itself: tau <
    -Ts_m."""
    eta_b = 2.0 - 1.0 / eta
    upper = TS_M + (hinge + TS_L) / (eta * N)
    lower = max(eta_b, 0.0) * (hinge - TS_L) / N - TS_M
    return lower, upper


@pytest.fixture(scope="module")
def models():
    return {eta: build_model(screw(eta), None, STICK) for eta in ETAS}


def _torques(eta):
    """Motor torques at 1 % inside and outside both band edges, and the direction (+1, 0, -1)
    each must move in."""
    lower, upper = band(eta)
    edge = max(abs(lower), TS_M)  # a self-locking screw's lower edge is -Ts_m
    return [(upper - 0.01 * upper, 0), (upper + 0.01 * upper, 1),
            (lower + 0.01 * edge, 0), (lower - 0.01 * edge, -1)]


def test_the_hand_band_against_the_lossless_one(models):
    """The loss widens the band on both sides; the self-locking screw's lower edge is the
    motor's own friction; the model states the efficiencies it holds with."""
    for eta in ETAS:
        lower, upper = band(eta)
        assert lower < (F_H - TS_L) / N - TS_M and upper > (F_H + TS_L) / N + TS_M
        P = models[eta].P
        assert P[lo.HOLD_FWD] == pytest.approx(1.0 / eta - 1.0)
        assert P[lo.HOLD_BACK] == pytest.approx(1.0 - max(2.0 - 1.0 / eta, 0.0))
    assert band(0.4)[0] == -TS_M


@pytest.mark.parametrize("method", ["rk4", "reference"])
@pytest.mark.parametrize("eta", ETAS)
def test_holds_inside_the_band_and_breaks_away_outside(models, eta, method):
    """99 % / 101 % of both band edges: at rest to the last bit inside, sliding the right way
    outside."""
    model = models[eta]
    for tau, way in _torques(eta):
        res = run(model, Reference.voltage(R * tau / KT), 0.005, method=method,
                  **({"dt": 1e-5} if method == "rk4" else {}))
        speed = res.states[:, 1]
        if way == 0:
            assert np.all(speed == 0.0) and np.all(res.states[:, 0] == res.states[0, 0]), (tau, way)
        else:
            assert way * speed[-1] > 1e-5, (tau, way, speed[-1])


@pytest.mark.parametrize("eta", ETAS)
def test_the_two_mass_motor_side_holds_within_the_band_of_its_spring_moment(eta):
    """An axially compliant screw (two-mass): the motor side at rest holds while the gear's
    torques stay in the band about the spring's moment, which at rest carries the hinge force
    (the load keeps its own stick law beyond the spring, so its friction is not in the band):
    eta_b F_h / N - Ts_m .. F_h / (eta N) + Ts_m; 99 % / 101 % of both edges."""
    sc = screw(eta)
    model = build_model(replace(sc, stages=(replace(sc.stages[0], axial_stiffness=2e8),)), None, STICK)
    assert not model.rigid
    upper = TS_M + F_H / (eta * N)
    lower = max(2.0 - 1.0 / eta, 0.0) * F_H / N - TS_M
    edge = max(abs(lower), TS_M)
    # the moving loss of a self-locking chain (modelled back-driven at eta_b = 0.1, smoothed
    # over the friction speed) is stiff where the spring drives it: a smaller step there
    dt = 1e-6 if eta > 0.5 else 2.5e-7
    for tau, way in ((0.99 * upper, 0), (1.01 * upper, 1), (lower + 0.01 * edge, 0), (lower - 0.01 * edge, -1)):
        for method in ("rk4", "reference"):
            res = run(model, Reference.voltage(R * tau / KT), 0.003, method=method,
                      **({"dt": dt} if method == "rk4" else {}))
            speed = res.states[:, 1]
            if way == 0:
                assert np.all(speed == 0.0) and np.all(res.states[:, 2] == res.states[0, 2]), (tau, method)
            else:
                assert way * speed[-1] > 1e-5, (tau, way, method, speed[-1])


@pytest.mark.parametrize("eta", ETAS)
def test_a_variant_holds_and_breaks_away_as_its_single_run(models, eta):
    """The same eight torques (with the lossless band's edges, which hold too) as variants of
    the batch: on one and two threads each is its single run to the bit, and moves the way
    the band says."""
    from .test_batch import assert_as_single_runs
    model = models[eta]
    cases = _torques(eta) + [((F_H + TS_L) / N + TS_M, 0), ((F_H - TS_L) / N - TS_M, 0)]
    P = np.array([fill(model, Reference.voltage(R * tau / KT)) for tau, _ in cases])
    X0 = np.array([initial_state(model, p) for p in P])
    X = assert_as_single_runs(P, model.T[None], np.zeros(len(X0), dtype=np.int64), X0, 1, 500, 1e-5,
                              threads=(1, 2))[0]
    for (_, way), x, x0 in zip(cases, X, X0):
        if way == 0:
            assert x[1] == 0.0 and x[0] == x0[0]
        else:
            assert way * x[1] > 1e-5


@pytest.mark.parametrize("hinge", [F_H, -F_H, 5.0 * F_H, -5.0 * F_H])
def test_a_self_locking_screw_holds_any_load_without_current(hinge):
    """No voltage, no current: the self-locking screw (eta 0.4, eta_b = -0.5) holds a hinge
    force pushing either way, also 5 times the rated one; the same screw at eta 0.9
    (eta_b 0.889) is back-driven by it."""
    for method in ("rk4", "reference"):
        held = run(build_model(screw(0.4, hinge), None, STICK), Reference.voltage(0.0), 0.005, method=method,
                   **({"dt": 1e-5} if method == "rk4" else {}))
        assert np.all(held.states[:, 1] == 0.0) and np.all(held.states[:, 0] == held.states[0, 0])
        assert np.all(held.motor_current == 0.0)
    slid = run(build_model(screw(0.9, hinge), None, STICK), Reference.voltage(0.0), 0.005, method="rk4", dt=1e-5)
    assert -np.sign(hinge) * slid.states[-1, 1] > 0.0


def test_the_gear_never_supplies_power():
    """A sine voltage across the band of the eta_b = 0.6 screw: the nut sticks, is driven
    forward and is back-driven. The gear's loss, taken from the trajectory alone (the motor's
    electromechanical work less the kinetic energy, the work against the hinge force and the
    frictions' dissipation, all by hand), never decreases and is 0 while the nut is at rest."""
    eta = 5.0 / 7.0
    lower, upper = band(eta)
    mid, swing = 0.5 * (lower + upper), 0.9 * (upper - lower)
    model = build_model(screw(eta), None, STICK)
    res = run(model, Reference.voltage(R * mid / KT, R * swing / KT, 5.0), 0.4, method="rk4", dt=1e-5,
              output_dt=1e-5)
    t, x, v = res.times, res.states[:, 0], res.states[:, 1]
    w = N * v  # motor speed
    mass = (J_ROTOR + J_SCREW) * N**2 + M_NUT + M_LOAD

    def integral(y):
        return np.concatenate([[0.0], np.cumsum(0.5 * (y[1:] + y[:-1]) * np.diff(t))])
    supplied = integral(KT * res.motor_current * w)
    dissipated = integral(B_M * w**2 + TC_M * np.abs(w) + TC_L * np.abs(v))
    loss = supplied - 0.5 * mass * v**2 - F_H * (x - x[0]) - dissipated
    rest = v == 0.0
    assert rest.mean() > 0.1 and (v > 0).mean() > 0.1 and (v < 0).mean() > 0.1
    assert loss[-1] > 0.0
    # the trapezoid's error where the nut breaks away within a record interval: 1e-8 of the loss
    assert np.all(np.diff(loss) >= -1e-7 * loss[-1])
    assert np.all(np.diff(loss)[rest[1:] & rest[:-1]] == 0.0)
