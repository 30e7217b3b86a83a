"""The inverse dynamics (``size``, ``kv``) takes every friction a scene gives: the motor's, each
stage's at its output (beyond its loss) and the load's, against a hand calculation."""

from __future__ import annotations

import math
import tomllib

import numpy as np
import pytest

from servo_toolkit.studies.mechanisms.inverse_dynamics import inverse_dynamics
from servo_toolkit.studies.kv.study import default_kv_study, kv_study
from servo_toolkit.studies.sizing import size

from .conftest import SCENES, build, variant
from .test_friction_choice import GEARMOTOR

#: motor friction, the gearhead's output shaft friction, the screw nut's guide friction, the load's
TC_M, B_M = 0.004, 2e-6          # N*m, N*m*s/rad at the motor
TC_G, B_G = 0.3, 1e-3            # N*m, N*m*s/rad at the gearhead's output (the screw shaft)
TC_S, B_S = 25.0, 40.0           # N, N*s/m at the screw's output (the nut, the travel)
TC_L, C_L = 10.0, 50.0           # N, N*s/m: the carriage


@pytest.fixture(scope="module")
def frictional():
    data = tomllib.loads(GEARMOTOR)
    return build(variant(data, motor__coulomb_friction=f"{TC_M} N*m", motor__viscous_friction=f"{B_M} N*m*s/rad",
                         drivetrain__0__coulomb_friction=f"{TC_G} N*m",
                         drivetrain__0__viscous_friction=f"{B_G} N*m*s/rad",
                         drivetrain__1__coulomb_friction=f"{TC_S} N", drivetrain__1__viscous_friction=f"{B_S} N*s/m"))


@pytest.mark.parametrize("v", [0.02, -0.02])
def test_a_constant_speed_segment_needs_every_node_s_friction_through_the_losses(frictional, v):
    """At a constant carriage speed v (no inertial force) the motor torque is, by hand, with
    the screw turning s = 2 pi / 10 mm rad per m and N = 50 s:
    the carriage c v + Tc_L sign v and the nut's Tc_S sign v + B_S v pass the screw's loss
    (divided by 0.9 while motoring), the screw shaft's Tc_G + B_G s v, times s, joins them and
    passes the gearhead's (/ 0.8), and the motor adds its own b N v + Tc_M. Backward (v < 0)
    the motor still drives every friction (they all oppose the motion): the same figure,
    negative."""
    s = 2 * math.pi / 0.01
    n = 50 * s
    sign = math.copysign(1.0, v)
    beyond_screw = (C_L * v + TC_L * sign) + (TC_S * sign + B_S * v)
    at_screw_shaft = beyond_screw / 0.9 + (TC_G * sign + B_G * s * v) * s
    hand = at_screw_shaft / 0.8 / n + B_M * n * v + TC_M * sign
    drive = frictional.drivetrain
    q0 = float(np.mean(drive.stroke))
    res = inverse_dynamics(drive, lambda t: (q0 + v * np.asarray(t), np.full_like(t, v), np.zeros_like(t)),
                           np.linspace(0.0, 0.01, 5), stage_friction=frictional.stage_friction)
    np.testing.assert_allclose(res.motor_torque, hand, rtol=1e-9)
    # the parts still add up, the screw's thrust carries the nut's friction and the carriage's
    parts = res.inertial_torque + res.external_torque + res.loss_torque + res.friction_torque
    np.testing.assert_allclose(parts, res.motor_torque, rtol=1e-12)
    np.testing.assert_allclose(res.screw_thrust, beyond_screw, rtol=1e-9)


def test_kv_takes_the_stages_and_the_load_s_friction_and_says_so(frictional):
    """``kv`` of the gearmotor with and without its stages' and load's friction: the peak motor
    torque grows (by at least the Coulomb levels reflected losslessly, about 8e-3 N*m), and
    the notes name each node's Coulomb level instead of claiming the motor's friction."""
    bare = build(tomllib.loads(GEARMOTOR))
    study = default_kv_study(bare, amplitude=0.5e-3, frequency=2.0)
    with_f = kv_study(frictional, study, progress=False)
    without = kv_study(bare, study, progress=False)
    s = 2 * math.pi / 0.01
    floor = (TC_L + TC_S + TC_G * s) / (50 * s) + TC_M
    assert with_f.cases[0].peak_motor_torque - without.cases[0].peak_motor_torque > floor * 0.9
    note = next(x for x in with_f.notes if x.startswith("Coulomb friction in the loads"))
    assert f"drivetrain[1] {TC_S:g} at its output" in note and f"load {TC_L:g} N" in note
    assert not any("motor friction" in x for x in with_f.notes)


def test_size_takes_the_screw_s_and_the_load_s_friction():
    """``size`` of the sizing EMA with 2000 N of friction at the screw's nut and 300 N*m at the
    load: the RMS torque and the peak current grow, and the notes name both levels (before,
    every figure was identical to the scene without them)."""
    data = tomllib.loads((SCENES / "ema_sizing.toml").read_text())
    base = size(build(data), sweep=False)
    rough = size(build(variant(data, drivetrain__1__coulomb_friction="2000 N", load__coulomb_friction="300 N*m",
                               load__static_friction="400 N*m")), sweep=False)
    rms = {m.name: m.value for m in base.margins}, {m.name: m.value for m in rough.margins}
    assert rms[1]["RMS torque"] > rms[0]["RMS torque"] * 1.01
    assert rms[1]["peak current"] > rms[0]["peak current"]
    note = next(x for x in rough.notes if x.startswith("Coulomb friction in the loads"))
    assert "drivetrain[1] 2000 at its output" in note and "load 300 N*m" in note
    assert any("breakaway excess Ts - Tc" in x and "load 100 N*m" in x for x in rough.notes)
