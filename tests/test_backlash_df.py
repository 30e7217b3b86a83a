"""The play's describing function and the limit cycle it predicts, against the compiled
simulation; the encoder's quantization ripple against a sampled experiment."""

from __future__ import annotations

import math

import numpy as np
import pytest

from servo_toolkit.loop.backlash_df import backlash_df, backlash_limit_cycle, quantization_ripple
from servo_toolkit.loop.controller import CascadeController
from servo_toolkit.loop.nominal_search import _delay_response
from servo_toolkit.loop.structures import Motion
from servo_toolkit.plant.current_loop import current_loop_gains
from servo_toolkit.plant.linear import plant_parameters
from servo_toolkit.scene.loader import scene_from_dict
from servo_toolkit.sim import ModelOptions, Reference, simulate

N, JM, KT, TS, PLAY_DEG = 10.0, 1e-4, 0.1, 5e-4, 1.0
HALF = math.radians(PLAY_DEG) / 2


def _play_operator(x, b):
    """The backlash operator on the samples x (starting in contact from below)."""
    y = np.empty_like(x)
    yy = x[0] - b
    for k, xv in enumerate(x):
        if xv - yy > b:
            yy = xv - b
        elif xv - yy < -b:
            yy = xv + b
        y[k] = yy
    return y


@pytest.mark.parametrize("ratio", [1.01, 1.5, 3.0, 10.0])
def test_describing_function_is_the_operators_fundamental(ratio):
    """N(A) = first Fourier coefficients of the operator's steady output over A (second
    period of a numerical run), to 1e-6."""
    b, a = 1.0, ratio
    t = np.linspace(0.0, 4 * math.pi, 400001)[:-1]
    y = _play_operator(a * np.sin(t), b)[t.size // 2:]
    tt = t[t.size // 2:]
    n = (2 * np.mean(y * np.sin(tt)) + 2j * np.mean(y * np.cos(tt))) / a
    assert abs(complex(backlash_df(a, b)) - n) < 1e-6
    assert backlash_df(0.9, 1.0) == 0.0


def _loop(kp, wv):
    """A position loop on the load through 1 deg of play: motor 1e-4 kg*m^2 through 10:1 and
    a stiff mesh to a light load (1e-6 kg*m^2, 0.01 N*m*s/rad: it stops when the motor side
    lets go of it, the backlash operator's premise); cascade with speed-loop crossover wv."""
    scene = scene_from_dict({
        "name": "play_loop",
        "motor": {"kind": "dc", "resistance": "1 ohm", "inductance": "1 mH", "torque_constant": f"{KT} N*m/A",
                  "back_emf_constant": f"{KT} V*s/rad", "rotor_inertia": f"{JM} kg*m^2",
                  "voltage_limit": "1000 V", "current_limit": "100 A"},
        "drivetrain": [{"kind": "gear", "name": "gear", "ratio": N, "torsional_stiffness": "1e4 N*m/rad",
                        "backlash": f"{PLAY_DEG} deg"}],
        "load": {"inertia": "1e-6 kg*m^2", "damping": "0.01 N*m*s/rad"},
        "sensors": {"sample_time": f"{TS} s"}})
    p = plant_parameters(scene, 0.0)
    gains = current_loop_gains(scene.motor, 1000.0)
    motion = Motion("cascade", {"kp": kp, "kv": JM * wv / KT * N, "wvi": wv / 4}, ratio=p.N)
    ctrl = CascadeController(motion.state_space(), *gains, TS, motion.describe())
    predicted = backlash_limit_cycle(p, motion, gains, lambda s: _delay_response(s, TS), HALF)
    run = simulate(scene, ctrl, reference=Reference.step(math.radians(0.5)), duration=4.0, method="rk4",
                   dt=2.5e-5, options=ModelOptions(friction="off"), output_dt=1e-4)
    keep = run.times > 2.0
    t, p_side = run.times[keep], run.states[keep, 0]
    x = p_side - p_side.mean()
    up = np.nonzero((x[:-1] < 0) & (x[1:] >= 0))[0]
    return predicted, t, p_side, x, up


def test_backlash_limit_cycle_predicted_as_simulated():
    """kp = 150 1/s over a 50 rad/s speed loop: the describing function predicts a limit
    cycle of the motor side at 2.43 b and 10.95 Hz; the compiled simulation (the
    elasto-backlash contact, a real load) settles into one within 20 % in amplitude (its
    fundamental) and 10 % in frequency (the operator's premise, a load that stops at once,
    holds only nearly: it runs 2.09 b at 10.2 Hz)."""
    predicted, t, p_side, x, up = _loop(150.0, 50.0)
    assert predicted is not None
    f_sim = (up.size - 1) / (t[up[-1]] - t[up[0]])
    w0 = 2 * math.pi * f_sim
    m = np.column_stack([np.sin(w0 * t), np.cos(w0 * t), np.ones_like(t)])
    c, *_ = np.linalg.lstsq(m, p_side, rcond=None)
    amp_sim = math.hypot(c[0], c[1])
    assert amp_sim > 1.5 * HALF                                     # a limit cycle, not a rest
    assert amp_sim == pytest.approx(predicted.amplitude, rel=0.2)
    assert f_sim == pytest.approx(predicted.frequency_hz, rel=0.1)


def test_no_limit_cycle_predicted_none_simulated():
    """kp = 60 1/s over a 100 rad/s speed loop: no intersection, and no oscillation after
    2 s (the motor side creeps on to its contact, its speed never reversing)."""
    predicted, t, p_side, x, up = _loop(60.0, 100.0)
    assert predicted is None
    step = np.diff(p_side)
    assert np.all(step >= 0) or np.all(step <= 0)
    assert np.ptp(p_side) < 0.5 * HALF


def test_quantization_ripple_matches_a_sampled_encoder():
    """A motion whose speed sweeps 0 .. 20 counts per sample, read by a 2048-count encoder and
    differenced over 0.2 ms, times the speed gain: the rms of the current it adds is
    Kv LSB / (Ts sqrt(6)) within 3 %. (At one speed the difference toggles between two counts:
    variance phi (1 - phi) LSB^2 with phi the fractional counts per sample, 1/6 on average over
    the sweep, the white model's 2 LSB^2 / 12.)"""
    counts, ts, kv = 2048, 2e-4, 0.25
    lsb = 2 * math.pi / counts
    t = np.arange(200000) * ts
    accel = 20 * lsb / ts / t[-1]
    angle = 0.5 * accel * t**2
    read = lsb * np.floor(angle / lsb + 0.5)
    ripple = kv * (np.diff(read) - np.diff(angle)) / ts
    assert np.std(ripple) == pytest.approx(quantization_ripple(kv, counts, ts), rel=0.03)
    # at one speed, phi = 0.43 counts per sample: sqrt(phi (1 - phi)) LSB, not the average
    steady = 2.43 * lsb / ts * t
    read = lsb * np.floor(steady / lsb + 0.5)
    one = kv * (np.diff(read) - np.diff(steady)) / ts
    assert np.std(one) == pytest.approx(kv * lsb / ts * math.sqrt(0.43 * 0.57), rel=0.03)
