"""The describing-function estimate of the mass-spring-belt stick-slip against the compiled
model's cycle (and so against the closed form the model is checked on in test_friction)."""

import math

import numpy as np
import pytest

from servo_toolkit.components.compliance import Compliance, Load
from servo_toolkit.components.motor import DCMotor
from servo_toolkit.scene.loader import Scene
from servo_toolkit.sim import ModelOptions, Reference, build_model, run
from servo_toolkit.studies.stick_slip import stick_slip_estimate

from .test_friction import BELT, BELT_DT, BELT_ROTOR, KT, R

K, M, V, TC = BELT["k"], BELT["m"], BELT["v"], BELT["tc"]


def belt_cycle(ts, duration=1.0):
    """Swing of the spring's moment about Tc and the period between breakaways of the belt
    run (test_friction.belt) with breakaway level ts, over its cycles after the first."""
    motor = DCMotor(resistance=R, inductance=0.0, torque_constant=KT, back_emf_constant=KT, rotor_inertia=BELT_ROTOR,
                    viscous_friction=0.0, coulomb_friction=0.0, voltage_limit=100.0, current_limit=50.0)
    sc = Scene("stick-slip", motor=motor, stages=(Compliance("spring", K),),
               load=Load(inertia=M, coulomb_friction=TC, static_friction=ts))
    model = build_model(sc, None, ModelOptions(damping_ratio=0.0, backlash=False, friction="stick"))
    x0 = np.zeros(model.nx)
    x0[0] = x0[2] = model.q0
    x0[1] = V
    n = abs(float(sc.drivetrain.ratio([model.q0])[0][0]))
    res = run(model, Reference.voltage(KT * n * V), duration, method="rk4", dt=BELT_DT, x0=x0, output_dt=BELT_DT)
    stuck = res.states[:, 3] == 0.0
    starts = np.flatnonzero(stuck[:-1] & ~stuck[1:])
    assert len(starts) >= 4
    cycle = (res.times > res.times[starts[1]]) & (res.times < res.times[starts[-1]])
    force = K * (res.states[cycle, 0] - res.states[cycle, 2])
    return 0.5 * float(np.ptp(force)), float(np.mean(np.diff(res.times[starts[1:]])))


def test_the_estimate_is_the_small_drop_limit_of_the_stick_slip():
    """At a static drop r = (Ts - Tc) / (v sqrt(k m)) = 0.1 the describing function neglects
    only the stick phase: the swing is within r^2 / 2 = 0.5 % and the period within
    r^3 / (3 pi) = 1e-4 (the neglected terms), plus the run's own 1e-3 (its rotor slows by a
    few 1e-4 and the records are 2e-5 s apart); both from below."""
    est0 = stick_slip_estimate(K, M, V, TC, TC)
    r = 0.1
    ts = TC + r * est0.force_amplitude
    est = stick_slip_estimate(K, M, V, ts, TC)
    assert est.drop_ratio == pytest.approx(r, rel=1e-12)
    assert est.period == pytest.approx(2 * math.pi * math.sqrt(M / K), rel=1e-15)
    swing, period = belt_cycle(ts)
    assert 0.0 <= swing / est.force_amplitude - 1.0 <= r**2 / 2 + 1e-3
    assert abs(period / est.period - 1.0) <= r**3 / (3 * math.pi) + 1e-3


def test_a_large_static_drop_is_beyond_the_estimate_by_its_stated_factors():
    """The classic run (r = 1.8): the estimate is a lower bound, the swing short by
    sqrt(1 + r^2) and the period by (2 pi + 2 (r - atan r)) / (2 pi), as stated."""
    est = stick_slip_estimate(K, M, V, BELT["ts"], TC)
    r = est.drop_ratio
    assert r == pytest.approx(1.789, rel=1e-3)
    swing, period = belt_cycle(BELT["ts"])
    assert swing > est.force_amplitude and period > est.period
    assert swing == pytest.approx(est.force_amplitude * math.hypot(1.0, r), rel=3e-3)
    assert period == pytest.approx(est.period * (1 + (r - math.atan(r)) / math.pi), rel=3e-3)


def test_the_estimate_refuses_what_it_cannot_describe_and_shows_its_figures():
    with pytest.raises(ValueError, match="Ts >= Tc"):
        stick_slip_estimate(K, M, V, 1.0, 2.0)
    est = stick_slip_estimate(K, M, V, BELT["ts"], TC)
    assert set(est.to_dict()) == {"amplitude", "force_amplitude", "period_s", "drop_ratio"}
    assert "\n" not in repr(est) and "period" in repr(est) and "lower bound" in est._repr_html_()
