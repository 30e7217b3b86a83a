"""Friction at a drivetrain stage's output: read from the scene, reflected by the ratio and
lumped onto the motor side or the load side of the two-mass split."""

from dataclasses import replace

import numpy as np
import pytest

from servo_toolkit.components.compliance import Compliance, Load
from servo_toolkit.components.gear import GearTrain
from servo_toolkit.components.stage_friction import StageFriction
from servo_toolkit.errors import SceneError
from servo_toolkit.scene.loader import scene_from_dict
from servo_toolkit.sim import ModelOptions, Reference, build_model, run
from servo_toolkit.sim import layout as lo

from .test_friction import KT, R, geared

N = 10.0
STICK = ModelOptions(friction="stick", chain="two_mass")
GEAR = GearTrain("gear", ratio=N, inertias=(1e-5, 1e-3))
SHAFT = Compliance("shaft", 2e3)


def scene_dict(**gear) -> dict:
    return {"name": "stage friction", "motor": {"resistance": "0.5 ohm", "torque_constant": "0.2 N*m/A",
                                                "back_emf_constant": "0.2 V*s/rad", "rotor_inertia": 2e-4},
            "drivetrain": [{"kind": "gear", "ratio": N, **gear}, {"kind": "ball_screw", "lead": "5 mm"}],
            "load": {"inertia": "10 kg"}}


def test_the_scene_reads_a_stage_friction_in_its_output_units():
    """The gear's output is a shaft (N*m), the screw's a travel (N); a scene without stage
    friction keeps none."""
    sc = scene_from_dict(scene_dict(coulomb_friction="0.3 N*m", static_friction="0.5 N*m", stribeck_speed="2 rad/s",
                                    viscous_friction="1e-3 N*m*s/rad"))
    assert sc.stage_friction == (StageFriction(0.3, 0.5, 2.0, 1e-3), None)
    d = scene_dict()
    d["drivetrain"][1]["coulomb_friction"] = "20 N"
    assert scene_from_dict(d).stage_friction == (None, StageFriction(20.0))
    assert scene_from_dict(scene_dict()).stage_friction == ()


@pytest.mark.parametrize("keys, bad", [({"coulomb_friction": "0.5 N*m", "static_friction": "0.3 N*m"},
                                        "drivetrain[0].static_friction"),
                                       ({"coulomb_friction": "-1 N*m"}, "drivetrain[0].coulomb_friction"),
                                       ({"coulomb_friction": "1 N"}, "drivetrain[0].coulomb_friction")])
def test_a_bad_stage_friction_names_its_key(keys, bad):
    with pytest.raises(SceneError) as err:
        scene_from_dict(scene_dict(**keys))
    assert err.value.key == bad


def test_a_stage_friction_reflected_to_the_motor_is_the_same_friction_at_the_motor():
    """Rigid chain: friction (Tc, Ts, v_st, B) at the gear's output runs as Tc/N, Ts/N,
    N v_st, B/N^2 added at the motor shaft (the Stribeck speeds reflected alike), to the last
    bits of a run through breakaway and sliding, in RK4 and in the reference solver."""
    tc, ts, vs = 0.02, 0.05, 0.5
    fr = StageFriction(coulomb_friction=0.3, static_friction=0.6, stribeck_speed=vs / N, viscous_friction=2e-2)
    at_stage = replace(geared(tc=tc, ts=ts, vs=vs), stage_friction=(fr,))
    at_motor = geared(tc=tc + 0.3 / N, ts=ts + 0.6 / N, vs=vs)
    at_motor = replace(at_motor, motor=replace(at_motor.motor, viscous_friction=1e-4 + 2e-2 / N**2))
    a, b = build_model(at_stage, None, STICK), build_model(at_motor, None, STICK)
    assert a.rigid and np.allclose(a.P, b.P, rtol=1e-14, atol=0)
    volts = Reference.voltage(1.5 * R * (ts + 0.06) / KT)
    ra, rb = (run(m, volts, 0.2, method="rk4", dt=1e-4) for m in (a, b))
    assert ra.motor_speed.max() > 1.0
    assert np.allclose(ra.states, rb.states, rtol=1e-12, atol=1e-12)
    # the reference solver (its events at the breakaway) reads the same slots
    ra, rb = (run(m, volts, 0.2, method="reference", output_dt=1e-3) for m in (a, b))
    assert np.allclose(ra.states, rb.states, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("chain", ["rigid", "two_mass"])
def test_a_stuck_chain_breaks_away_at_the_sum_of_the_reflected_static_levels(chain):
    """Open loop, the stall torque Kt V / R against the motor's breakaway plus the gear
    output's reflected to the motor, Ts_m + Ts_g / N: at 99 % of it nothing moves, to the
    last bit; at 101 % the rotor breaks away. (Two-mass: the gear's output sits on the motor
    side of the shaft.)"""
    ts_m, ts_g = 0.05, 0.4
    stages = None if chain == "rigid" else (GEAR, SHAFT)
    sc = replace(geared(tc=0.02, ts=ts_m, stages=stages), stage_friction=(StageFriction(0.2, ts_g),)
                 + ((None,) if stages else ()))
    model = build_model(sc, None, STICK)
    assert model.rigid == (chain == "rigid")
    cap = ts_m + ts_g / N
    still = run(model, Reference.voltage(0.99 * R * cap / KT), 0.2, method="rk4", dt=1e-5)
    assert np.all(still.states[:, 1] == 0.0) and np.all(still.states[:, 0] == still.states[0, 0])
    moving = run(model, Reference.voltage(1.01 * R * cap / KT), 0.2, method="rk4", dt=1e-5)
    assert moving.motor_speed[-1] > 0.01


def test_a_stage_beyond_the_split_joins_the_load_friction():
    """A compliance stage's output is the load's node: its friction joins the load's (the
    output's units: u' = 1), the motor's stays its own; the notes say where it went."""
    sc = replace(geared(tc=0.02, ts=0.05, stages=(GEAR, SHAFT), load=Load(inertia=0.05, coulomb_friction=0.1)),
                 stage_friction=(None, StageFriction(0.5, 0.8, 0.01)))
    model = build_model(sc, None, STICK)
    assert not model.rigid
    assert (model.P[lo.TC], model.P[lo.TS_M]) == (0.02, 0.05)
    assert model.P[lo.TC_L] == pytest.approx(0.6) and model.P[lo.TS_L] == pytest.approx(0.9)
    assert model.P[lo.INV_VS_L] == pytest.approx(1 / 0.01)
    assert any("drivetrain[1]" in n and "load" in n for n in model.notes)


def test_the_linear_plant_keeps_a_stage_viscous_friction_and_says_it_drops_the_rest():
    """The rigid plant's damping at the output is b_m N^2 + B_g (gear output = output), and its
    notes name the stage's Coulomb friction as left out."""
    from servo_toolkit.plant.linear import friction_note, plant_parameters
    sc = replace(geared(tc=0.0), stage_friction=(StageFriction(0.3, 0.5, 0.0, 2e-2),))
    p = plant_parameters(sc, model="rigid")
    assert p.b1 == pytest.approx(1e-4 * N**2 + 2e-2, rel=1e-12)
    assert "drivetrain[0]'s Coulomb friction 0.3 N*m, static 0.5 N*m" in friction_note(sc)[0]


def test_the_dead_band_counts_a_stage_friction_reflected_to_the_motor():
    """The proportional path's dead band (hunting.dead_band) with the gear output's breakaway
    Ts_g is the one with Ts_m + Ts_g / N at the motor, the closed form (Ts_m + Ts_g / N) / (Kt Kp)."""
    from servo_toolkit.studies.hunting import dead_band

    from .test_hunting import controller, gains, scene
    sc = scene()
    j, kp, _, kd = gains(sc, integral=0.0)
    ctrl = controller(kp, 0.0, kd)
    ts_g = 0.4
    with_stage = replace(sc, stage_friction=(StageFriction(0.2, ts_g),) + (None,) * (len(sc.stages) - 1))
    n = abs(float(sc.drivetrain.ratio([0.0])[0][0]))
    assert dead_band(with_stage, ctrl) == pytest.approx(dead_band(sc, ctrl) + ts_g / n / (KT * kp), rel=1e-9)
