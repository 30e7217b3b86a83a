"""Direct checks of single model features against independent statements: the cam paper's
play law inside the compiled scheme, the output-encoder grid seen by the controller, viscous
friction against the DC motor's closed-form steady speed, and the CLI's trace-file check."""

from __future__ import annotations

import dataclasses
import math
import tomllib

import numpy as np
import pytest

from servo_toolkit import SceneError
from servo_toolkit.cli import main
from servo_toolkit.components.cam.drive import clearance_hysteresis
from servo_toolkit.sim import ModelOptions, Reference, build_model, default_controller, run, simulate
from servo_toolkit.sim import layout as lo
from servo_toolkit.sim.kernel import controller_sample
from servo_toolkit.sim.reference import fill, initial_state
from servo_toolkit.sim.result import check_trace_path

from .conftest import SCENES, build, variant

BASE = tomllib.loads((SCENES / "ema_reference.toml").read_text())


def test_paper_scheme_play_state_is_the_play_operator_of_the_motor_side_travel():
    """Seed 002 eqs 6-8 with c = 1 deg applied (by the cam module's own implementation) to
    the recorded motor-side travel reproduce the kernel's play state at every step."""
    scene = build(variant(BASE, load__hinge_moment="0 N*m"))
    model = build_model(scene, default_controller(scene),
                        ModelOptions(controller_mode="continuous", play=math.radians(2.0)))
    dt = 2e-5
    res = run(model, Reference.sine(math.radians(5.0), 8.0), 0.25, "paper", dt, output_dt=dt)
    p, s = res.trace("motor_side_angle_rad"), res.trace("play_state_rad")
    c = math.radians(1.0)
    expected = clearance_hysteresis(p, c, s0=s[0])
    assert np.max(np.abs(s - expected)) <= 1e-12
    # the operator did work: s held inside the play and dragged along on both sides
    held = np.diff(s) == 0.0
    assert 0.05 < held.mean() < 0.95
    assert np.max(p - s) == pytest.approx(c, rel=1e-9) and np.min(p - s) == pytest.approx(-c, rel=1e-9)


def test_sampled_controller_sees_the_output_angle_on_the_encoder_grid():
    """16-bit output encoder: every output angle within half a count of a grid point gives
    the same controller update; without quantization the update follows the angle."""
    scene = build(BASE)
    lsb = 2 * math.pi / 2**16
    outs = {}
    for quant in (True, False):
        model = build_model(scene, default_controller(scene), ModelOptions(quantization=quant))
        assert model.parameters()[lo.LSB] == (pytest.approx(lsb) if quant else 0.0)
        P = fill(model, Reference(offset=0.0))
        x0 = initial_state(model, P)
        k = 1234
        irefs, states = [], []
        for frac in (-0.49, -0.2, 0.0, 0.3, 0.49, 0.51):
            x = x0.copy()
            x[2] = (k + frac) * lsb
            irefs.append(controller_sample(0.0, x, P, model.T, np.empty(model.nx)))
            states.append(x[lo.NX_PHYS:].copy())
        outs[quant] = (np.array(irefs), np.array(states))
    irefs, states = outs[True]
    assert np.all(irefs[:5] == irefs[0]) and np.all(states[:5] == states[0])
    assert irefs[5] != irefs[0]                                  # next count
    assert len(set(outs[False][0].tolist())) == 6


def test_hold_run_regulates_the_measured_angle_to_the_grid():
    """Holding 0.3 count off the grid: the loop can only null the measured (rounded) angle,
    so the output stays within one count of the command but does not settle on it."""
    scene = build(BASE)
    lsb = 2 * math.pi / 2**16
    # lossless chain without Coulomb friction: with the drivetrain's losses the hinge moment
    # holds the output in a friction band wherever it stops (test_sim_efficiency.py), and
    # friction that holds stops it within its dead band (test_friction.py)
    model = build_model(scene, default_controller(scene), ModelOptions(efficiency=False, friction="off"))
    r = (200 + 0.3) * lsb
    res = run(model, Reference(offset=r), 0.2, "rk4")
    q = res.output_angle[len(res.times) // 2:]
    assert np.max(np.abs(q - r)) < 1.0 * lsb
    # the command rounds to count 200 but the loop's integral wants +0.3 count: the output
    # hovers at the switching boundary 200.5 counts, never at the command
    assert np.min(np.abs(q - r)) > 0.05 * lsb
    assert abs(np.mean(q) / lsb - 200.5) < 0.1
    ideal = run(build_model(scene, default_controller(scene), ModelOptions(quantization=False, efficiency=False,
                                                                           friction="off")),
                Reference(offset=r), 0.2, "rk4").output_angle[len(res.times) // 2:]
    assert np.max(np.abs(ideal - r)) < 1e-3 * lsb


def test_viscous_friction_open_loop_steady_speed_matches_closed_form():
    """Constant voltage on the cam drive with a massless follower: the motor settles where
    Kt (V - Ke w) / R = Tc + b w, i.e. w = (Kt V - R Tc) / (Kt Ke + R b)."""
    data = tomllib.loads((SCENES / "cam_follower.toml").read_text())
    b = 2e-4
    scene = build(variant(data, motor__viscous_friction=f"{b} N*m*s/rad"))
    cam = dataclasses.replace(scene.stages[0], follower_mass=1e-9, follower_weight=0.0)
    scene = dataclasses.replace(scene, stages=(cam,))
    m = scene.motor
    v = 3.5
    w = (m.torque_constant * v - m.resistance * m.coulomb_friction) / (
        m.torque_constant * m.back_emf_constant + m.resistance * b)
    res = simulate(scene, voltage=v, duration=3.0, method="rk4", dt=1e-3)
    assert res.motor_speed[-1] == pytest.approx(w, rel=1e-4)
    # b visibly slows it: without it the speed is higher by R b w / (Kt Ke) ~ 18 %
    w0 = (m.torque_constant * v - m.resistance * m.coulomb_friction) / (m.torque_constant * m.back_emf_constant)
    assert w0 / w > 1.1


def test_trace_file_name_is_checked_before_the_run(tmp_path, monkeypatch, capsys):
    with pytest.raises(SceneError, match=r"--output: trace file 'tr.txt' must end in .csv or .npz"):
        check_trace_path(tmp_path / "tr.txt")
    with pytest.raises(SceneError, match="does not exist"):
        check_trace_path(tmp_path / "missing" / "tr.csv")
    assert check_trace_path(tmp_path / "tr.npz") == tmp_path / "tr.npz"

    def no_run(*args, **kwargs):  # the simulation must not start
        raise AssertionError("simulation ran before the output name was checked")

    import servo_toolkit.sim as sim
    import servo_toolkit.studies.time.run as time_run  # imported before patching: it binds simulate
    monkeypatch.setattr(sim, "simulate", no_run)
    monkeypatch.setattr(time_run, "simulate", no_run)
    code = main(["simulate", str(SCENES / "ema_reference.toml"), "-o", str(tmp_path / "tr.txt")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "--output" in err[0]
