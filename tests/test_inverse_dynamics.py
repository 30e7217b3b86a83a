"""Inverse dynamics along a prescribed motion (seed 000): round trip, closed forms, losses."""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.interpolate import CubicSpline

from servo_toolkit.components.compliance import Load
from servo_toolkit.components.gear import GearTrain
from servo_toolkit.components.motor import DCMotor
from servo_toolkit.drivetrain.reflected import Drivetrain
from servo_toolkit.scene.loader import load_scene
from servo_toolkit.studies.mechanisms.inverse_dynamics import inverse_dynamics
from servo_toolkit.studies.kv.study import with_load_inertia
from servo_toolkit.studies.trajectories import SineMotion

from .conftest import SCENES, build, variant


@pytest.fixture(scope="module")
def ema():
    return load_scene(SCENES / "ema_reference.toml")


def _forward(dt, motion, t_end):
    """Rigid one-DOF model J(q) qdd + (1/2) J'(q) qd^2 = N(q) (T_m - friction) - loads,
    driven by the inverse-dynamics torque (a cubic spline through 2000 samples per piece);
    written from J, J' and N only. The Coulomb
    friction opposes the direction of motion of each piece between speed reversals (the
    integration is split there, so that every piece has a smooth right-hand side)."""
    m, load = dt.motor, dt.load

    def rhs(t, x, direction, torque):
        q, qd = x
        j, dj = dt.inertia([q])
        n, _ = dt.ratio([q])
        wm = n[0] * qd
        tm = torque(t)
        drive = n[0] * (tm - m.viscous_friction * wm - m.coulomb_friction * direction * np.sign(n[0]))
        loads = load.hinge_moment + load.hinge_stiffness * q + load.damping * qd
        return [qd, (drive - loads - 0.5 * dj[0] * qd**2) / j[0]]

    # integrate between the speed reversals, where the Coulomb term switches
    edges = [0.0] + [e for e in (t_end / 4, 3 * t_end / 4) if e < t_end] + [t_end]
    q0, qd0, _ = motion(0.0)
    x = [float(q0), float(qd0)]
    pieces = []
    for a, b in zip(edges[:-1], edges[1:]):
        direction = float(np.sign(motion(0.5 * (a + b))[1]))
        nodes = np.linspace(a, b, 2001)[1:-1]    # the torque command, sampled inside the piece
        torque = CubicSpline(nodes, inverse_dynamics(dt, motion, nodes, losses="none").motor_torque)
        sol = solve_ivp(rhs, (a, b), x, method="DOP853", rtol=1e-9, atol=1e-11, dense_output=True,
                        args=(direction, torque))
        assert sol.success, sol.message
        pieces.append((a, b, sol.sol))
        x = sol.y[:, -1]

    def path(t):
        t = np.asarray(t)
        out = np.empty((2, t.size))
        for a, b, f in pieces:
            sel = (t >= a) & (t <= b)
            out[:, sel] = f(t[sel])
        return out
    return path


@pytest.mark.parametrize("amplitude_deg, frequency, inertia", [(30.0, 1 / 0.6, 1.0), (4.0, 8.0, 2.3)])
def test_inverse_torque_drives_the_forward_model_along_the_motion(ema, amplitude_deg, frequency, inertia):
    dt = with_load_inertia(ema.drivetrain, inertia)
    motion = SineMotion(math.radians(amplitude_deg), frequency)
    path = _forward(dt, motion, motion.period)
    t = np.linspace(0, motion.period, 301)
    q, qd = path(t)
    amp = motion.amplitude
    assert np.max(np.abs(q - motion.position(t))) < 1e-6 * amp
    assert np.max(np.abs(qd - motion.speed(t))) < 1e-5 * amp * motion.omega


def test_forward_model_notices_a_wrong_torque(ema):
    """The round trip can fail: 2 % less torque leaves the motion."""
    dt = with_load_inertia(ema.drivetrain, 1.0)
    motion = SineMotion(math.radians(30), 1 / 0.6)

    class Scaled:
        def __call__(self, t):
            q, qd, qdd = motion(t)
            return q, qd, 0.98 * qdd
    path = _forward(dt, Scaled(), motion.period / 4)
    t = np.linspace(0, motion.period / 4, 101)
    assert np.max(np.abs(path(t)[0] - motion.position(t))) > 1e-3 * motion.amplitude


def _gear_chain(eta, inertia=0.5, hinge=40.0):
    motor = DCMotor(resistance=1.0, inductance=0.0, torque_constant=0.1, back_emf_constant=0.1,
                    rotor_inertia=1e-4, viscous_friction=2e-4, coulomb_friction=0.01)
    gear = GearTrain("gear", ratio=50.0, efficiency=eta)
    return Drivetrain(motor, (gear,), Load(inertia=inertia, hinge_moment=hinge))


def test_single_gear_closed_form_with_directional_efficiency():
    eta, n = 0.8, 50.0
    dt = _gear_chain(eta)
    motion = SineMotion(0.3, 2.0)
    t = motion.times(400)
    q, qd, qdd = motion(t)
    r = inverse_dynamics(dt, motion, t)
    load_side = 0.5 * qdd + 40.0
    through = np.where(load_side * qd >= 0, load_side / (n * eta), load_side * eta / n)
    wm = n * qd
    expected = through + 1e-4 * n * qdd + 2e-4 * wm + 0.01 * np.sign(wm)
    np.testing.assert_allclose(r.motor_torque, expected, rtol=1e-12, atol=1e-12)
    parts = r.inertial_torque + r.external_torque + r.loss_torque + r.friction_torque
    np.testing.assert_allclose(parts, r.motor_torque, rtol=1e-12, atol=1e-12)
    assert r.screw_thrust is None and r.rod_force is None


def test_a_back_driven_screw_loses_with_its_back_drive_efficiency():
    """Gear (eta_g both ways) then ball screw (eta forward, 2 - 1/eta back-driven) moving a
    mass along a sine: the motor torque is the load's force through each stage with the
    efficiency of the direction the power flows in, as the simulation's loss model has it."""
    from servo_toolkit.components.ball_screw import BallScrew
    motor = DCMotor(resistance=1.0, inductance=0.0, torque_constant=0.1, back_emf_constant=0.1,
                    rotor_inertia=0.0, viscous_friction=0.0, coulomb_friction=0.0)
    eta_g, eta_s, lead, mass, force = 0.95, 0.9, 0.005, 20.0, 300.0
    gear = GearTrain("gear", ratio=3.0, efficiency=eta_g)
    screw = BallScrew("screw", lead=lead, efficiency=eta_s)
    dt = Drivetrain(motor, (gear, screw), Load(inertia=mass, hinge_moment=force))
    motion = SineMotion(0.01, 5.0)
    t = motion.times(400)
    q, qd, qdd = motion(t)
    r = inverse_dynamics(dt, motion, t)
    eta_b = 2.0 - 1.0 / eta_s
    assert screw.backdrive_efficiency == pytest.approx(eta_b)
    nut = mass * qdd + force                          # N on the nut
    screw_torque = np.where(nut * qd >= 0, nut / eta_s, nut * eta_b) * lead / (2 * np.pi)
    motor_torque = np.where(screw_torque * qd >= 0, screw_torque / eta_g, screw_torque * eta_g) / 3.0
    back = nut * qd < 0
    assert back.any() and (~back).any()
    np.testing.assert_allclose(r.motor_torque, motor_torque, rtol=1e-10, atol=1e-12)


def test_losses_never_lower_the_motor_power(ema):
    dt = with_load_inertia(ema.drivetrain, 2.0)
    motion = SineMotion(math.radians(30), 1 / 0.6)
    t = motion.times(800)
    lossy = inverse_dynamics(dt, motion, t)
    ideal = inverse_dynamics(dt, motion, t, losses="none")
    dp = (lossy.motor_torque - ideal.motor_torque) * lossy.motor_speed
    assert np.all(dp >= -1e-9)
    assert np.max(dp) > 0.05 * np.max(np.abs(ideal.motor_torque * ideal.motor_speed))


def test_static_loads_match_the_geometry(ema):
    """Near standstill at q = 0: thrust = M_h / r (dx_A/dphi = r there), rod force = thrust
    (rod parallel to the screw), motor torque = M_h / (N eta) + Coulomb friction."""
    dt = ema.drivetrain
    motion = SineMotion(1e-9, 1e-6)          # q ~ 0, qd > 0 tiny, qdd ~ 0
    r = inverse_dynamics(dt, motion, [0.0])
    arm = dt.stages[2].arm_length
    hinge = dt.load.hinge_moment
    assert r.screw_thrust[0] == pytest.approx(hinge / arm, rel=1e-9)
    assert r.rod_force[0] == pytest.approx(hinge / arm, rel=1e-9)
    n = (52 / 24) * (2 * math.pi / 0.005) * arm
    assert r.ratio[0] == pytest.approx(n, rel=1e-12)
    expected = hinge / (n * dt.efficiency) + ema.motor.coulomb_friction
    assert r.motor_torque[0] == pytest.approx(expected, rel=1e-9)


def test_nut_and_output_inertia_enter_the_thrust(ema):
    """At the stroke centre with zero speed the thrust's inertial part is
    (m_nut + rod/2) r qdd + (J_shaft + J_load + m_rod/2 r^2 - m_rod l^2/6 psi'^2) qdd / r."""
    dt = with_load_inertia(ema.drivetrain, 1.0)
    qdd0 = 100.0

    def motion(t):
        return np.zeros_like(t), np.zeros_like(t), np.full_like(t, qdd0)
    link = dt.stages[2]
    r = link.arm_length
    base = inverse_dynamics(with_load_inertia(ema.drivetrain, 1.0), lambda t: (0 * t, 0 * t, 0 * t), [0.0])
    res = inverse_dynamics(dt, motion, [0.0])
    psi1 = link.rod_angle(np.array([0.0])).d1[0]
    beyond_nut = (link.output_shaft_inertia + 1.0 + link.rod_mass / 2 * r**2 + link.rod_mass / 2 * r**2
                  - link.rod_mass * link.rod_length**2 / 6 * psi1**2) * qdd0 / r
    expected = base.screw_thrust[0] + beyond_nut + dt.stages[1].nut_mass * r * qdd0
    assert res.screw_thrust[0] == pytest.approx(expected, rel=1e-9)


# --- round trip through the toolkit's own forward model ---------------------------------

def _sim_round_trip(scene, h, inductance, losses="none", f=8.0, amp=math.radians(2.0), periods=2):
    """Drive the compiled simulation model (open loop, rigid chain) with the armature voltage
    that makes the motor produce the inverse-dynamics torque, integrate with classical RK4
    at step h, and return max |q_sim - q_prescribed| / amplitude.

    u = R i + L di/dt + Ke w_m with i = T_em / Kt. The simulation model runs lossless
    (``efficiency=False``: no drivetrain loss) and smooths Coulomb friction as Tc tanh(w_m / w_s); the electromagnetic
    torque it needs is the inverse dynamics' torque with its friction part (b w + Tc sign w)
    replaced by the model's (b w + Tc tanh(w / w_s)). The voltage is evaluated exactly at
    the RK4 stage times (t, t + h/2, t + h), so the only error left is the integrator's."""
    from servo_toolkit.sim import ModelOptions, Reference, build_model
    from servo_toolkit.sim import layout as lo
    from servo_toolkit.sim.ivp import make_fun
    from servo_toolkit.sim.reference import fill

    model = build_model(scene, None, ModelOptions(compliance=False, inductance=inductance, efficiency=False))
    assert model.rigid and not model.closed_loop
    P = fill(model, Reference.voltage(0.0))
    motor, drive = scene.motor, scene.drivetrain
    motion = SineMotion(amp, f, model.q0)
    n = int(round(periods / f / h))
    t = np.arange(2 * n + 1) * (h / 2)

    def electromagnetic_torque(times):
        r = inverse_dynamics(drive, motion, times, losses=losses)
        w = r.motor_speed
        return r, r.motor_torque - r.friction_torque + motor.viscous_friction * w \
            + motor.coulomb_friction * np.tanh(w * P[lo.WS])

    r, tau = electromagnetic_torque(t)
    u = motor.resistance * tau / motor.torque_constant + motor.back_emf_constant * r.motor_speed
    if inductance:
        d = 1e-6
        dtau = (electromagnetic_torque(t + d)[1] - electromagnetic_torque(t - d)[1]) / (2 * d)
        u = u + motor.inductance * dtau / motor.torque_constant
    assert np.max(np.abs(u)) < motor.voltage_limit      # no clipping: the model sees u itself
    fun = make_fun(model, P, [0.0])

    def rate(k, x):
        P[lo.V_OPEN] = u[k]
        return fun(t[k], x)

    x = np.zeros(model.nx)
    q0, qd0, _ = motion(0.0)
    x[[0, 1, 2, 3]] = q0, qd0, q0, qd0
    x[4] = tau[0] / motor.torque_constant
    err = 0.0
    for s in range(n):
        k = 2 * s
        k1 = rate(k, x)
        k2 = rate(k + 1, x + 0.5 * h * k1)
        k3 = rate(k + 1, x + 0.5 * h * k2)
        k4 = rate(k + 2, x + h * k3)
        x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        err = max(err, abs(x[0] - r.q[k + 2]))
    return err / amp


@pytest.mark.parametrize("inductance", [False, True])
def test_round_trip_through_the_simulation_model(ema_dict, inductance):
    """The motor torque found by inverse dynamics, fed to the toolkit's own forward model
    (servo_toolkit.sim, open loop, rigid chain), reproduces the prescribed 2 deg, 8 Hz
    motion of the reference EMA over two periods.

    Tolerance from the step: RK4's global error goes as h^4, so halving h must divide the
    error by ~16 (12..20 accepted) - a mismatch between the two models would instead leave
    a floor that does not shrink - and at h = 0.1 ms (omega h = 5e-3 for the motion,
    |lambda h| = 0.1 for the armature's R/L = 1 ms) it is below 1e-9 of the amplitude.
    With the armature inductance the voltage needs L di/dt, which the smoothed Coulomb
    friction makes steep at the speed reversals (width ~ w_s / (dw_m/dt) ~ 0.1 ms); that
    case runs without Coulomb friction so that h resolves the input."""
    scene = build(variant(ema_dict, motor__coulomb_friction=0) if inductance else ema_dict)
    errors = [_sim_round_trip(scene, h, inductance) for h in (4e-4, 2e-4, 1e-4)]
    assert 12 < errors[0] / errors[1] < 20 and 12 < errors[1] / errors[2] < 20, errors
    assert errors[2] < 1e-9, errors


def test_round_trip_sees_a_model_mismatch(ema):
    """The same round trip with the directional stage losses in the torque (the simulation
    model is lossless): the motion departs by far more than the integration error - the
    round trip is a real check of the two models' agreement."""
    assert _sim_round_trip(ema, 2e-4, False, losses="directional") > 1e-3
