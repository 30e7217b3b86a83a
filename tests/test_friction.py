"""Friction that holds: exact stick below breakaway, breakaway above it, the Stribeck law while
sliding, the classic stick-slip cycle against its closed form and an event-driven solution,
its energy balance, and friction that never supplies power."""

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from servo_toolkit import load_scene
from servo_toolkit.components.compliance import Compliance, Load
from servo_toolkit.components.gear import GearTrain
from servo_toolkit.components.motor import DCMotor
from servo_toolkit.scene.loader import Scene
from servo_toolkit.sim import ModelOptions, Reference, build_model, run
from servo_toolkit.sim import layout as lo
from servo_toolkit.sim.kernel import gear_at_rest, slip_friction, stuck_or_breaking

from . import rhs_reference
from .conftest import SCENES

KT, R = 0.2, 0.5
STICK = ModelOptions(friction="stick")


def geared(tc=0.02, ts=None, vs=0.0, stages=None, load=None):
    """A motor with Coulomb (and static) friction driving an inertia through a lossless 10:1
    gear; no other load."""
    motor = DCMotor(resistance=R, inductance=0.0, torque_constant=KT, back_emf_constant=KT, rotor_inertia=2e-4,
                    viscous_friction=1e-4, coulomb_friction=tc, static_friction=ts, stribeck_speed=vs,
                    voltage_limit=100.0, current_limit=50.0)
    stages = stages or (GearTrain("gear", ratio=10.0, inertias=(1e-5, 1e-3)),)
    return Scene("friction test", motor=motor, stages=stages, load=load or Load(inertia=0.05))


@pytest.mark.parametrize("chain", ["rigid", "two_mass", "full"])
def test_a_motor_below_breakaway_stands_still_exactly(chain):
    """Open loop at 99 % of the breakaway voltage R Ts / Kt (above the Coulomb level): the
    rotor never moves, to the last bit; at 101 % it breaks away."""
    ts, tc = 0.05, 0.02
    stages = {"rigid": None,
              "two_mass": (GearTrain("gear", ratio=10.0, inertias=(1e-5, 1e-3)), Compliance("shaft", 2e3)),
              "full": (GearTrain("gear", ratio=10.0, inertias=(1e-5, 1e-3), torsional_stiffness=5e3),
                       Compliance("shaft", 2e3))}[chain]
    sc = geared(tc=tc, ts=ts, stages=stages)
    model = build_model(sc, None, ModelOptions(chain="full" if chain == "full" else "two_mass", friction="stick"))
    assert model.rigid == (chain == "rigid") and (model.P[lo.NMID] > 0) == (chain == "full")
    still = run(model, Reference.voltage(0.99 * R * ts / KT), 0.3, method="rk4", dt=1e-5)
    assert np.all(still.states[:, 1] == 0.0) and np.all(still.states[:, 0] == still.states[0, 0])
    moving = run(model, Reference.voltage(1.01 * R * ts / KT), 0.3, method="rk4", dt=1e-5)
    assert moving.motor_speed[-1] > 0.01


def test_sliding_speed_is_the_dc_motor_closed_form():
    """Above breakaway the steady speed of the unloaded motor is w = (Kt V - R Tc) / (Kt Ke + R b)
    (the Stribeck drop decayed: w >> w_st)."""
    tc, ts, b = 0.02, 0.05, 1e-4
    sc = geared(tc=tc, ts=ts, vs=0.5)
    model = build_model(sc, None, STICK)
    v = 6.0
    res = run(model, Reference.voltage(v), 0.5, method="rk4", dt=1e-4)  # 50 time constants
    w = (KT * v - R * tc) / (KT * KT + R * b)
    assert res.motor_speed[-1] == pytest.approx(w, rel=1e-6)


def test_smooth_friction_creeps_where_stick_holds():
    """The smooth model (no stick) creeps below breakaway: what the stick model fixes."""
    sc = geared(tc=0.02)
    volts = 0.9 * R * 0.02 / KT
    held = run(build_model(sc, None, STICK), Reference.voltage(volts), 0.5, method="rk4", dt=1e-5)
    creep = run(build_model(sc, None, ModelOptions(friction="smooth")), Reference.voltage(volts), 0.5,
                method="rk4", dt=1e-5)
    assert held.motor_speed[-1] == 0.0 and creep.motor_speed[-1] > 0.01


def stick_slip_closed_form(k, m, v, ts, tc):
    """Mass m on a spring k whose far end moves at v, friction Ts (static) and Tc (sliding),
    no damping. Stick: the force rises at k v from 2 Tc - Ts to Ts; slip: the mass swings at
    w = sqrt(k / m) about the Coulomb level (the force Tc +- k A) until its speed is 0 again.
    Returns the period, the stick time and the swing's force amplitude k A."""
    w = math.sqrt(k / m)
    d = (ts - tc) / k            # displacement of the swing's centre at breakaway
    # slip: y = x - (v t - Tc / k); y(0) = -d, y'(0) = -v; y = A cos(w t + phi)
    amp = math.hypot(d, v / w)
    phi = math.atan2(v / w, -d)  # A cos(phi) = -d, A w sin(phi) = v
    t_slip = (3 * math.pi - 2 * phi) / w  # y' = -v again (x' = 0) at the mirrored phase
    t_stick = 2 * (ts - tc) / (k * v)
    return t_slip + t_stick, t_stick, k * amp


#: the mass-spring-belt: spring (N*m/rad), load inertia, belt speed (rad/s), static and Coulomb
#: friction (N*m); the belt is the motor side, a huge rotor driven at the speed's voltage
BELT = dict(k=400.0, m=0.2, v=0.05, ts=2.0, tc=1.2)
BELT_ROTOR = 5e3
BELT_DT = 2e-5


@pytest.fixture(scope="module")
def belt():
    """The classic stick-slip run: the motor side (a huge inertia) turns at about constant
    speed v and pulls the load through a spring; the load has static and Coulomb friction."""
    k, m, v, ts, tc = (BELT[key] for key in ("k", "m", "v", "ts", "tc"))
    motor = DCMotor(resistance=R, inductance=0.0, torque_constant=KT, back_emf_constant=KT, rotor_inertia=BELT_ROTOR,
                    viscous_friction=0.0, coulomb_friction=0.0, voltage_limit=100.0, current_limit=50.0)
    sc = Scene("stick-slip", motor=motor, stages=(Compliance("spring", k),),
               load=Load(inertia=m, coulomb_friction=tc, static_friction=ts))
    model = build_model(sc, None, ModelOptions(damping_ratio=0.0, backlash=False, friction="stick"))
    assert not model.rigid
    x0 = np.zeros(model.nx)
    x0[0] = x0[2] = model.q0
    x0[1] = v
    n = abs(float(sc.drivetrain.ratio([model.q0])[0][0]))
    volts = KT * n * v
    res = run(model, Reference.voltage(volts), 2.0, method="rk4", dt=BELT_DT, x0=x0, output_dt=BELT_DT)
    return res, n, volts


def test_stick_slip_of_a_mass_pulled_through_a_spring(belt):
    """The cycle's period, stick time and force extremes are the closed form's."""
    k, m, v, ts, tc = (BELT[key] for key in ("k", "m", "v", "ts", "tc"))
    res = belt[0]
    force = k * (res.states[:, 0] - res.states[:, 2])
    stuck = res.states[:, 3] == 0.0
    starts = np.flatnonzero(stuck[:-1] & ~stuck[1:])  # breakaways
    assert len(starts) >= 4
    # the rotor slows by a few 1e-4 under the spring's mean pull: each cycle at its own speed
    for a, b in zip(starts[1:-1], starts[2:]):
        speed = float(np.mean(res.states[a:b, 1]))
        period, t_stick, swing = stick_slip_closed_form(k, m, speed, ts, tc)
        assert res.times[b] - res.times[a] == pytest.approx(period, rel=1e-3)
    period, t_stick, swing = stick_slip_closed_form(k, m, v, ts, tc)
    cycle = (res.times > res.times[starts[1]]) & (res.times < res.times[starts[-1]])
    assert force[cycle].max() == pytest.approx(tc + swing, rel=2e-3)
    assert force[cycle].min() == pytest.approx(tc - swing, abs=2e-3 * ts)
    # each stick begins at 2 Tc - Ts and ends at the breakaway level Ts
    ends = np.flatnonzero(~stuck[:-1] & stuck[1:]) + 1
    np.testing.assert_allclose(force[ends[1:-1]], 2 * tc - ts, atol=2e-3 * ts)
    np.testing.assert_allclose(force[starts[1:]], ts, atol=2e-3 * ts)
    stick_time = stuck[cycle].mean() * period
    assert stick_time == pytest.approx(t_stick, rel=5e-3)


def test_stick_slip_against_an_event_driven_solution(belt):
    """The same run against an independent event-driven solution (``solve_ivp`` between stick
    and slip events at 1e-10, tests/test_hunting.stick_slip), rotor included. RK4 locates each
    breakaway and each stick within its step (``split_step.h``): over the
    11 cycles every one falls in the same step as the reference's event (no drift), and the
    load's trace follows the reference to 1e-5 of the swing (1e-6 seen, the reference's own
    dense output; with the switches at step boundaries and a linear estimate it was 4e-3)."""
    from .test_hunting import sample, stick_slip
    k, m, ts, tc = (BELT[key] for key in ("k", "m", "ts", "tc"))
    res, n, volts = belt

    def applied(t, y):  # the spring's moment on the load; y = [q, q', p, p']
        return k * (y[2] - y[0])

    def rotor(t, y):  # the motor side at the output (p, ratio n): N Kt i, i = (V - Ke N p') / R, the spring
        return [y[3], (n * KT * (volts - KT * n * y[3]) / R - k * (y[2] - y[0])) / (BELT_ROTOR * n**2)]
    y0 = [res.states[0, 2], 0.0, res.states[0, 0], res.states[0, 1]]
    pieces = stick_slip(res.t_final, y0, applied, rotor, m, tc, ts)
    slips = np.array([a for a, _, stuck, _ in pieces if not stuck and a > 0.0])
    sticks = np.array([a for a, _, stuck, _ in pieces if stuck and a > 0.0])
    stuck = res.states[:, 3] == 0.0
    t_slip = res.times[np.flatnonzero(stuck[:-1] & ~stuck[1:])]  # last record stuck before each breakaway
    t_stick = res.times[np.flatnonzero(~stuck[:-1] & stuck[1:]) + 1]  # first record stuck
    assert len(slips) >= 10 and len(t_slip) == len(slips) and len(t_stick) == len(sticks) == len(slips)
    eps = 1e-9 * BELT_DT  # the records' times
    assert np.all((t_slip > slips - BELT_DT) & (t_slip <= slips + eps))  # the last record stuck
    assert np.all((t_stick >= sticks - eps) & (t_stick < sticks + BELT_DT))  # the first record stuck
    ref = sample(pieces, res.times)
    swing = stick_slip_closed_form(k, m, BELT["v"], ts, tc)[2] / k
    assert np.max(np.abs(res.states[:, 2] - ref[:, 0])) < 1e-5 * swing


def test_energy_balance_of_a_stick_slip_run(belt):
    """Along the stick-slip run the friction's work on the load, from the trajectory alone (the
    load's kinetic energy less the spring's work on it), never grows (friction never supplies
    energy, at a stick or a breakaway neither) and equals the Coulomb law's dissipation
    Tc int |q'| dt; the motor's work Kt i p' is the stored energy plus that dissipation."""
    k, m, tc = BELT["k"], BELT["m"], BELT["tc"]
    res, n, _ = belt
    p, pd, q, qd = (res.states[:, j] for j in range(4))
    t = res.times

    def integral(y):
        return np.concatenate([[0.0], np.cumsum(0.5 * (y[1:] + y[:-1]) * np.diff(t))])
    spring_on_load = integral(k * (p - q) * qd)
    friction_work = 0.5 * m * qd**2 - spring_on_load  # q' = 0 at the start
    dissipated = integral(tc * np.abs(qd))
    assert dissipated[-1] > 0.05  # J: the run slides for most of its 2 s
    assert np.all(np.diff(friction_work) <= 1e-6 * dissipated[-1])
    np.testing.assert_allclose(friction_work, -dissipated, atol=1e-5 * dissipated[-1])
    stored = 0.5 * BELT_ROTOR * (n * pd)**2 + 0.5 * m * qd**2 + 0.5 * k * (p - q)**2
    motor_work = integral(res.motor_torque * n * pd)
    np.testing.assert_allclose(motor_work, stored - stored[0] + dissipated, atol=1e-5 * dissipated[-1])


@settings(max_examples=200, deadline=None)
@given(v=st.floats(-1e3, 1e3).filter(lambda x: x != 0), tc=st.floats(0, 10), extra=st.floats(0, 10),
       vs=st.floats(1e-6, 1e3), applied=st.floats(-50, 50))
def test_friction_never_supplies_power(v, tc, extra, vs, applied):
    """Sliding, the friction opposes the speed and lies between Tc and Ts; at rest it takes at
    most the applied moment and never turns it around."""
    ts = tc + extra
    f = slip_friction(v, tc, ts, 1.0 / vs, 0.0)
    assert f * v >= 0.0
    assert tc - 1e-12 <= abs(f) <= ts + 1e-12
    net = stuck_or_breaking(applied, ts)
    assert abs(net) <= abs(applied) and net * applied >= 0.0


def test_the_reference_ema_holds_its_position_exactly_at_rest():
    """The shipped EMA, open loop below breakaway and its hinge moment off: nothing moves (the
    smooth friction lets the rotor creep under any torque)."""
    ema = load_scene(SCENES / "ema_reference.toml")
    sc = replace(ema, load=replace(ema.load, hinge_moment=0.0, hinge_stiffness=0.0))
    model = build_model(sc, None, ModelOptions(inductance=False, friction="stick"))
    res = run(model, Reference.voltage(0.9 * sc.motor.resistance * sc.motor.breakaway_torque
                                       / sc.motor.torque_constant), 0.2, method="rk4", dt=1e-4)
    assert np.all(res.motor_speed == 0.0)


# --- the compiled laws against their transcription (tests/rhs_reference.py) -----------------

#: magnitudes across the scales the right-hand side meets, and the edge values
LAW_VALUES = st.one_of(st.floats(-1e6, 1e6, allow_nan=False), st.sampled_from([0.0, -0.0, 1.0, -1.0, 1e-300, -1e-300]))
LAW_LEVELS = st.one_of(st.floats(0.0, 1e6), st.sampled_from([0.0, math.inf]))


def _same(a, b):
    """The same double (the sign of a zero aside: the kernels ignore signed zeros), or both NaN."""
    return a == b or (math.isnan(a) and math.isnan(b))


@settings(max_examples=2000, deadline=None)
@given(applied=LAW_VALUES, cap=LAW_LEVELS)
def test_stuck_or_breaking_is_its_transcription(applied, cap):
    """The stick law compares and subtracts once: the transcription's value exactly."""
    assert _same(stuck_or_breaking(applied, cap), rhs_reference.stuck_or_breaking(applied, cap))


@settings(max_examples=3000, deadline=None)
@given(torque=LAW_VALUES, moment=LAW_VALUES, cap_t=LAW_LEVELS, cap_m=LAW_LEVELS,
       fwd_loss=st.one_of(st.just(0.0), st.floats(0.0, 20.0)), back_loss=st.one_of(st.just(0.0), st.floats(0.0, 1.0)),
       gauge=st.sampled_from([0.0, 1.0, 2.0]))
def test_gear_at_rest_is_its_transcription(torque, moment, cap_t, cap_m, fwd_loss, back_loss, gauge):
    """The lossy gear at rest: the breakaway distances m + loss m may be fused into a
    multiply-add (the kernels' floating-point licence): the gauges within that rounding
    (relative, and absolute at the subnormal scale), the
    net moment the transcription's exactly unless a distance is within that rounding of 0
    (where the decision may go either way)."""
    args = (torque, moment, cap_t, cap_m, fwd_loss, back_loss, gauge)
    got, want = gear_at_rest(*args), rhs_reference.gear_at_rest(*args)
    if not math.isfinite(cap_t + cap_m):
        assert _same(got, want) or math.isnan(got) or math.isnan(want)
        return
    # each operation rounds within eps of its value plus, in the subnormal range, half the
    # smallest subnormal (the standard model's underflow term): a moment of 5e-324 times a
    # loss of 0.5 is 0 or 5e-324 as the multiply-add is fused or not
    span = 8 * np.finfo(float).eps * (abs(torque) + cap_t + (abs(moment) + cap_m) * (1.0 + fwd_loss)) \
        + 4 * math.ulp(0.0)
    if gauge > 0.0:
        assert abs(got - want) <= span, args
    else:
        fwd, bwd = (rhs_reference.gear_at_rest(*args[:-1], g) for g in (1.0, 2.0))
        near_zero = min(abs(fwd), abs(fwd - bwd)) <= span or abs(bwd) <= span
        assert _same(got, want) or near_zero, args


@settings(max_examples=3000, deadline=None)
@given(v=st.one_of(st.floats(-1e3, 1e3, allow_nan=False), st.sampled_from([0.0, -0.0, 1e-12, -1e-12])),
       tc=st.floats(0.0, 10.0), drop=st.floats(0.0, 10.0), inv_vs=st.one_of(st.floats(0.0, 1e4), st.just(math.inf)),
       direction=st.sampled_from([0.0, 1.0, -1.0]))
def test_slip_friction_is_its_transcription(v, tc, drop, inv_vs, direction):
    """The Stribeck sliding law: the kernels' exponential (within 1 ulp of the C library's,
    which the transcription calls) and a multiply-add: within 2 ulp of the breakaway level, of
    the same sign; NaN where v / v_s is (0 times an infinite 1 / v_s)."""
    ts = tc + drop
    args = (v, tc, ts, inv_vs, direction)
    got = slip_friction(*args)
    if math.isnan(v * inv_vs):
        assert math.isnan(got)
        return
    want = rhs_reference.slip_friction(*args)
    assert abs(got - want) <= 2 * math.ulp(ts), args
    assert math.copysign(1.0, got) == math.copysign(1.0, want)
