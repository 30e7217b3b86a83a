"""A drive's log samples its current and its motor angle at the control instants: the response
``frf`` estimates from such a log is the ratio of the held current reference's zero-order-hold
responses (:mod:`servo_toolkit.plant.sampled`), which ``fit --response plant`` compares. Checked
against the textbook zero-order-hold equivalent, and on the toolkit's own simulated log of a
linear rotary scene: no delay left between the log's response and the model's beyond the
estimator's noise, and the excite -> frf -> fit loop calibrates the scene to the noise."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from servo_toolkit import load_scene
from servo_toolkit.cli import main
from servo_toolkit.identify.frf import estimate_frf, read_time_log
from servo_toolkit.identify.model import plant_response
from servo_toolkit.identify.noise import frequency_noise
from servo_toolkit.plant.current_loop import current_loop_gains
from servo_toolkit.plant.sampled import drive_plant_response, zero_order_hold

#: a gearmotor (50:1) turning a flap inertia against a torsion spring, every effect linear;
#: sampled at 5 kHz, its 1 kHz current loop leaves a tenth of a sample between the current's
#: samples and the current the mechanics feel
SCENE = """
name = "rot_spring"
[motor]
kind = "dc"
resistance = "0.8 ohm"
inductance = "0.6 mH"
torque_constant = "0.15 N*m/A"
back_emf_constant = "0.15 V*s/rad"
rotor_inertia = "1.5e-4 kg*m^2"
viscous_friction = "5e-5 N*m*s/rad"
coulomb_friction = "0 N*m"
voltage_limit = "48 V"
current_limit = "20 A"
[[drivetrain]]
kind = "gear"
name = "planetary"
ratio = 50.0
inertia = ["2e-6 kg*m^2", "1e-4 kg*m^2"]
efficiency = 1.0
torsional_stiffness = "{stiffness} N*m/rad"
backlash = "0 deg"
stroke = ["-45 deg", "45 deg"]
[load]
inertia = "{inertia} kg*m^2"
hinge_moment = "0 N*m"
hinge_stiffness = "20 N*m/rad"
damping = "0.1 N*m*s/rad"
[sensors]
output_encoder_bits = 16
motor_encoder_counts = 4096
sample_time = "0.2 ms"
[requirements]
bandwidth = "4 Hz"
"""
TRUTH = {"stiffness": 6.4e3, "inertia": 0.26}
#: the rig's current sensor noise (A rms) added to the simulated log
CURRENT_NOISE = 0.05


def _scene_file(path, **values):
    path.write_text(SCENE.format(**{**TRUTH, **values}))
    return path


@pytest.fixture(scope="module")
def simulated_log(tmp_path_factory):
    """``excite -o`` on the linear scene: the excitation and the model's run of it."""
    folder = tmp_path_factory.mktemp("rig")
    scene = _scene_file(folder / "truth.toml")
    out = folder / "stimulus.csv"
    assert main(["excite", str(scene), "-o", str(out), "--resolution", "0.5 Hz", "--periods", "4"]) == 0
    return load_scene(scene), out


def _with_current_noise(src, dst, seed=1, counts=0):
    """The log with white noise on its current column (the rig's current sensor), and its
    motor angle rounded to an encoder's ``counts`` per revolution (0: not rounded)."""
    text = src.read_text().splitlines()
    head = [line for line in text if line.startswith("#")]
    header = text[len(head)]
    data = np.loadtxt(src, delimiter=",", comments="#", skiprows=len(head) + 1)
    column = header.split(",").index("current_A")
    data[:, column] += np.random.default_rng(seed).normal(0.0, CURRENT_NOISE, len(data))
    if counts:
        angle, step = header.split(",").index("motor_angle_rad"), 2 * math.pi / counts
        data[:, angle] = np.round(data[:, angle] / step) * step
    with open(dst, "w") as f:
        f.write("\n".join(head + [header]) + "\n")
        np.savetxt(f, data, delimiter=",", fmt="%.12g")
    return dst


def _estimate(path):
    log = read_time_log(path)
    lines = list(range(log.excited_bins[0], log.excited_bins[1] + 1))
    return estimate_frf(log.time_s, log.columns["current_A"], log.columns["motor_angle_rad"],
                        period=log.period_samples, settle=log.settle_periods, lines=lines, derivative=True)


def test_zero_order_hold_equivalent_of_an_integrator_behind_a_lag():
    """K / (s (tau s + 1)) held for T: the textbook equivalent (Franklin, Powell and Workman,
    Digital Control of Dynamic Systems, table of zero-order-hold equivalents)
    K ((T - tau (1 - a)) z + tau (1 - a) - a T) / ((z - 1)(z - a)), a = exp(-T / tau)."""
    K, tau, T = 3.0, 1.6e-4, 2e-4
    A = np.array([[0.0, K], [0.0, -1 / tau]])
    B = np.array([[0.0], [1 / tau]])
    Ad, Bd = zero_order_hold(A, B, T)
    z = np.exp(2j * np.pi * np.array([1.0, 40.0, 700.0]) * T)
    got = np.array([(np.linalg.solve(zk * np.eye(2) - Ad, Bd)[0, 0]) for zk in z])
    a = math.exp(-T / tau)
    want = K * ((T - tau * (1 - a)) * z + tau * (1 - a) - a * T) / ((z - 1) * (z - a))
    np.testing.assert_allclose(got, want, rtol=1e-10)


def test_a_drive_samples_the_plant_ahead_of_the_continuous_one(tmp_path):
    """The current loop steps the current towards each held reference within the sample, so its
    samples at the control instants trail the current the mechanics feel: the sampled response
    leads the continuous one by T / (1 - a) - tau - T / 2 (a = exp(-T / tau), tau the 1 kHz
    loop's time constant; the first-order lag's step against the straight line joining its
    samples), 20.4 us here, with the same gain, and equals it at low frequency."""
    scene = load_scene(_scene_file(tmp_path / "s.toml"))
    f = np.linspace(2.0, 60.0, 30)
    sampled = drive_plant_response(scene, f)
    continuous = drive_plant_response(scene, f, sample_time=0.0)
    T = 2e-4
    tau = scene.motor.inductance / current_loop_gains(scene.motor)[0]
    a = math.exp(-T / tau)
    lead = T / (1 - a) - tau - T / 2
    ratio = sampled / continuous
    slope = np.polyfit(f, np.unwrap(np.angle(ratio)), 1)[0] / (2 * np.pi)
    assert slope == pytest.approx(lead, rel=0.05)  # the back-emf's coupling aside
    assert np.max(np.abs(20 * np.log10(np.abs(ratio)))) < 0.01
    assert np.array_equal(plant_response(scene, f), sampled)


def _phase_residual(data, scene):
    model = plant_response(scene, data.frequency_hz)
    return (data.phase_deg - np.degrees(np.angle(model)) + 180) % 360 - 180, \
        data.gain_db - 20 * np.log10(np.abs(model))


def test_the_simulated_log_has_no_delay_against_the_model(simulated_log, tmp_path):
    """The toolkit's own log of the linear scene. Noise-free, its response is the model's on
    every line, and a straight line through the phase residual leaves under 1 us of delay
    (the sampling's lead was 21.6 us; the model's run, RK4 at half the sample time against the
    0.16 ms current loop, leaves 0.3 us, 0.001 us at an eighth of it). With the rig's current
    noise, the line weighted by each line's phase noise (from its coherence) moves from the
    noise-free one by less than three of its standard errors (the lead was a hundred)."""
    scene, log = simulated_log
    clean = _estimate(log)
    phase, gain = _phase_residual(clean, scene)
    assert np.max(np.abs(phase)) < 0.02 and np.max(np.abs(gain)) < 0.002
    clean_delay = -np.polyfit(clean.frequency_hz, phase, 1)[0] / 360
    assert abs(clean_delay) < 1e-6, clean_delay
    data = _estimate(_with_current_noise(log, tmp_path / "rig.csv"))
    phase, _ = _phase_residual(data, scene)
    sd = frequency_noise(data).phase_deg
    X = np.column_stack([data.frequency_hz, np.ones(data.points)]) / sd[:, None]
    coef, *_ = np.linalg.lstsq(X, phase / sd, rcond=None)
    delay, delay_sd = -coef[0] / 360, math.sqrt(np.linalg.inv(X.T @ X)[0, 0]) / 360
    assert delay_sd < 1e-6  # the noise leaves the test able to see the lead
    assert abs(delay - clean_delay) < 3 * delay_sd, (delay, clean_delay, delay_sd)


def test_excite_frf_fit_calibrates_the_scene_to_the_noise(simulated_log, tmp_path, capsys):
    """The rig loop on the simulated log with the rig's current noise: ``frf --derivative``,
    then ``fit`` of the load's inertia and the gear's stiffness from a scene 23 % lighter and 25 %
    stiffer gives the truth back within its intervals, and the fit's residual is the noise's."""
    _, log = simulated_log
    out, _, code = _loop(log, tmp_path, capsys)
    assert out["verdict"] == "fits to the noise", out["verdict"]
    assert code == 0
    truth = {"load.inertia": TRUTH["inertia"], "drivetrain[0].torsional_stiffness": TRUTH["stiffness"]}
    for p in out["parameters"]:
        lo, hi = p["ci95"]
        assert lo <= truth[p["key"]] <= hi, p


def _loop(log, tmp_path, capsys, counts=0):
    """``frf --derivative`` of the noisy log, then ``fit`` of the load's inertia and the gear's
    stiffness from a scene 23 % lighter and 25 % stiffer: the fit's JSON, the response file and
    the exit code."""
    rig = _with_current_noise(log, tmp_path / "rig.csv", counts=counts)
    frf = tmp_path / "frf.csv"
    assert main(["frf", str(rig), "--derivative", "-o", str(frf)]) == 0
    start = _scene_file(tmp_path / "start.toml", stiffness=8e3, inertia=0.2)
    capsys.readouterr()
    code = main(["fit", str(start), str(frf), "--param", "load.inertia", "--param",
                 "drivetrain[0].torsional_stiffness", "--json"])
    return json.loads(capsys.readouterr().out), frf, code


def test_excite_frf_fit_with_the_encoders_counts_fits_to_the_noise(simulated_log, tmp_path, capsys):
    """The rig loop with the motor angle as the scene's 4096-count encoder logs it. The log
    repeats each period, so does the angle's rounding error: the coherence stays 1 where it
    lands, on the excitation's lines. Left out of the noise it read as "model mismatch"
    (residual 2.58 against the floor of 1); with the rounding's error per line (the step the
    log records) the fit reaches the noise and its intervals hold the truth."""
    _, log = simulated_log
    out, frf, _ = _loop(log, tmp_path, capsys, counts=4096)
    assert out["verdict"] == "fits to the noise", (out["verdict"], out["residual_rms"])
    text = frf.read_text()
    assert "# resolution of motor_angle_rad: 0.00153398 rad, as the log records it" in text
    assert "resolution of current_A: none" in text
    assert "and the logged signals' resolution" in out["noise_basis"]
    truth = {"load.inertia": TRUTH["inertia"], "drivetrain[0].torsional_stiffness": TRUTH["stiffness"]}
    for p in out["parameters"]:
        lo, hi = p["ci95"]
        assert lo <= truth[p["key"]] <= hi, p
