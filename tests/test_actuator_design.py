"""Design for the actuator it has: the speed-loop gain bounded by the encoder's ripple and the
play's limit cycle, and a step command within the motor's reach, on a small DC gearmotor
(50:1 gearhead with 0.5 deg of play, 10 mm ball screw, 20 kg carriage, 2048-count motor
encoder at 0.2 ms) whose unbounded design reads the encoder into 1.5 A rms of current."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from servo_toolkit.loop.actuator_bounds import RIPPLE_OF_CONTINUOUS, RIPPLE_OF_LIMIT, ripple_allowance
from servo_toolkit.loop.design import design
from servo_toolkit.loop.reach import REACH_FRACTION, reach, reach_profile
from servo_toolkit.plant.linear import plant_parameters
from servo_toolkit.scene import load_scene
from servo_toolkit.sim import ModelOptions, Reference, simulate
from servo_toolkit.studies.actuator import spec

from .conftest import ROOT

STEP = 0.5e-3


@pytest.fixture(scope="module")
def scene():
    return load_scene(ROOT / "tests" / "scenes" / "gearmotor_carriage.toml")


@pytest.fixture(scope="module")
def designed(scene):
    return design(scene)


def test_speed_gain_bounded_by_the_encoder_ripple(scene, designed):
    """The unbounded search's speed gain (0.2475 A*s/rad) reads the 2048-count encoder into
    Kv LSB / (Ts sqrt 6) = 1.55 A rms; the design lowers it until the ripple is within check's
    default allowance for its current_ripple row (5 % of the 10 A limit), meets every linear
    requirement still, and says so in its notes, its table and its JSON."""
    b = designed.actuator
    assert b is not None and b.met
    lsb = 2 * math.pi / 2048
    kv = designed.motion.gains["kv"] / designed.parameters.N
    assert b.speed_gain == pytest.approx(kv)
    assert b.quantization == pytest.approx(kv * lsb / (2e-4 * math.sqrt(6)), rel=1e-12)
    assert b.allowance == pytest.approx(0.5) and b.quantization <= 0.5
    assert b.capped_from == pytest.approx(0.2475, rel=0.01)
    assert designed.passed
    assert any(n.startswith("speed-loop gain lowered from 0.2475") for n in designed.notes)
    assert any("motor encoder 2048 counts/rev" in n for n in designed.notes)
    assert any("play 18.9 um at the output" in n for n in designed.notes)
    assert "actuator bounds on the speed loop" in designed.table()
    assert designed.to_dict()["actuator_bounds"]["met"] is True


def test_default_allowance_is_checks_current_ripple_default(scene, designed):
    """The design bounds the ripple by the figure check's current_ripple row judges by
    default: 5 % of the current limit, or 10 % of a continuous current the motor gives; the
    scene's max_current_ripple when it sets one."""
    assert spec.plan(scene, designed).bound("current_ripple").value == pytest.approx(designed.actuator.allowance)
    assert (RIPPLE_OF_CONTINUOUS, RIPPLE_OF_LIMIT) == (0.10, 0.05)
    assert ripple_allowance(scene)[0] == pytest.approx(0.05 * 10.0)
    rated = replace(scene, motor=replace(scene.motor, continuous_torque=0.3))
    assert ripple_allowance(rated)[0] == pytest.approx(0.1 * 0.3 / 0.06)
    given = replace(scene, requirements=replace(scene.requirements, time=replace(
        scene.requirements.time, max_current_ripple=0.2)))
    assert ripple_allowance(given) == (0.2, "the scene's max_current_ripple")


def test_tight_allowance_trades_the_margins_and_says_so(scene):
    """An allowance of 0.05 A: the speed gain comes down a hundredfold, the play's limit
    cycle appears in the slow loop (the describing function predicts it, and its current is
    bounded too), and the margins the unbounded design met are missed, each with its
    shortfall in the notes: the bound is kept, the cost is stated."""
    r = design(scene, current_ripple=0.05)
    b = r.actuator
    assert b.capped_from is not None and b.speed_gain < 0.01
    assert b.quantization == pytest.approx(b.speed_gain * 2 * math.pi / 2048 / (2e-4 * math.sqrt(6)))
    assert b.quantization <= 0.05 and b.limit_cycle_current <= 0.05
    assert not r.passed
    assert any("short by" in n for n in r.notes)
    assert any("speed-loop gain lowered from 0.2475" in n and "0.05 A rms (given)" in n for n in r.notes)


def test_reach_profile_within_the_motor_limits(scene):
    """The profile's peak acceleration needs REACH_FRACTION of the current limit beyond the
    load's friction, through the inertia the motor drives (its rotor reflected: 21 t of
    carriage-equivalent mass), and its peak speed REACH_FRACTION of the voltage."""
    p = plant_parameters(scene)
    r = reach(scene)
    inertia, gain = p.J1 + p.J2, p.torque_gain
    assert (inertia * r.a_max + 10.0) / gain == pytest.approx(REACH_FRACTION * 10.0, rel=1e-12)
    i_acc = inertia * r.a_max / gain
    assert r.v_max * 0.06 * p.N + 1.2 * i_acc * REACH_FRACTION == pytest.approx(REACH_FRACTION * 48.0, rel=1e-12)
    prof = reach_profile(scene, STEP)
    assert prof.peak_acceleration <= r.a_max * (1 + 1e-12) and prof.peak_speed <= r.v_max * (1 + 1e-12)


def test_step_through_the_reach_profile_stays_linear(scene, designed):
    """The 0.5 mm step with the full model and friction that holds: as a raw step it drives
    the current to its limit; through the reach profile the current stays below 90 % of it
    and the carriage arrives without 2 % overshoot."""
    opts = ModelOptions(chain="full", friction="stick")
    t_at = 0.01
    raw = simulate(scene, designed.controller, reference=Reference.step(STEP, at=t_at), duration=0.3,
                   method="rk4", options=opts)
    prof = reach_profile(scene, STEP)
    move = simulate(scene, designed.controller,
                    reference=Reference.move(prof.distance, prof.v_max, prof.a_max, prof.j_max, at=t_at),
                    duration=0.3, method="rk4", options=opts)
    assert np.max(np.abs(raw.motor_current)) > 0.99 * 10.0
    assert np.max(np.abs(move.motor_current)) < 0.9 * 10.0
    y = move.output_angle - move.output_angle[0]
    assert np.max(y) < 1.02 * STEP
    assert abs(y[-1] - STEP) < 0.02 * STEP


def test_design_command_options_carry_the_reach(scene, designed):
    """``design``'s command options (its text and ``--json``'s ``command``) state the limits
    a command within the motor's reach keeps."""
    from servo_toolkit.loop.command_design import command_design
    c = command_design(scene, designed)
    r = reach(scene, designed.q0)
    assert c.reach == r
    assert c.to_dict()["reach"]["a_max"] == pytest.approx(r.a_max)
    assert "loop.reach.reach_profile" in c.lines()[-1] and "80% of the motor's limits" in c.lines()[-1]
