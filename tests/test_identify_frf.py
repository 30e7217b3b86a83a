"""From a rig's time log to a frequency response (H1, Welch) and on to the fit: the log of a
broadband current excitation gives the current -> speed response with its coherence, the
CSV `fit` reads, and the fit recovers the rig."""

import json

import numpy as np
import pytest

from servo_toolkit import load_scene
from servo_toolkit.cli import main
from servo_toolkit.identify import fit, read_data
from servo_toolkit.identify.frf import estimate_frf
from servo_toolkit.identify.model import plant_response
from servo_toolkit.identify.params import SceneTemplate

from .conftest import SCENES

EMA = str(SCENES / "ema_reference.toml")
KEYS = ["load.inertia", "drivetrain[3].stiffness"]
FS = 4096.0


def rig_log(scene, periods=5, seed=0, counts=2 ** 20):
    """A rig in steady state under a random-phase multisine current (0.25-400 Hz every
    0.25 Hz, 2 A RMS): the motor angle's spectrum is the current's times the rig's
    current -> speed response over j w; the encoder quantizes it."""
    rng = np.random.default_rng(seed)
    n = int(FS / 0.25)  # one period: 4 s
    spectrum = np.zeros(n // 2 + 1, complex)
    f = np.arange(1, int(400 / 0.25)) * 0.25
    k = np.round(f / 0.25).astype(int)
    spectrum[k] = np.exp(2j * np.pi * rng.uniform(size=k.size))
    angle_spectrum = np.zeros_like(spectrum)
    angle_spectrum[k] = spectrum[k] * plant_response(scene, f) / (2j * np.pi * f)
    scale = 2 / np.sqrt(np.mean(np.fft.irfft(spectrum, n) ** 2))
    u = np.tile(np.fft.irfft(spectrum, n) * scale, periods)
    angle = np.tile(np.fft.irfft(angle_spectrum, n) * scale, periods)
    t = np.arange(u.size) / FS
    q = 2 * np.pi / counts
    return t, u, np.round(angle / q) * q


@pytest.fixture(scope="module")
def far_rig():
    scene = load_scene(EMA)
    template = SceneTemplate(scene, KEYS)
    values = np.array(template.initial) * [1.5, 0.7]
    return scene, template.scene(values), values


def test_h1_gives_the_speed_response_with_its_coherence(far_rig):
    _, rig, _ = far_rig
    t, u, angle = rig_log(rig)
    data = estimate_frf(t, u, angle, segment=16384, band=(2, 300), derivative=True)
    assert data.frequency_hz[0] >= 2 and data.frequency_hz[-1] <= 300
    exact = plant_response(rig, data.frequency_hz)
    good = data.coherence > 0.95
    assert good.mean() > 0.9
    err_db = data.gain_db[good] - 20 * np.log10(np.abs(exact[good]))
    assert np.median(np.abs(err_db)) < 0.1
    # noise on the output lowers the coherence, not the H1 gain
    noisy = angle + np.random.default_rng(1).normal(0, 2e-3, angle.size)
    worse = estimate_frf(t, u, noisy, segment=16384, band=(2, 300), derivative=True)
    assert np.median(worse.coherence) < np.median(data.coherence)


def test_log_to_frf_to_fit_recovers_the_rig(far_rig, tmp_path, capsys):
    scene, rig, truth = far_rig
    t, u, angle = rig_log(rig)
    log = tmp_path / "rig_log.csv"
    np.savetxt(log, np.column_stack([t, u, angle]), delimiter=",", header="time_s,current_A,motor_angle_rad",
               comments="", fmt="%.10g")
    out = tmp_path / "frf.csv"
    assert main(["frf", str(log), "--derivative", "--segment", "16384", "--band", "2:300", "-o", str(out),
                 "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["points"] > 100 and d["output_file"] == str(out)
    data = read_data(out)
    assert data.points == d["points"] and (data.coherence <= 1).all()
    r = fit(scene, data, "plant", KEYS)
    for key, true in zip(KEYS, truth):
        assert r.value(key) == pytest.approx(true, rel=0.01), key
    # the Hann window's bias around the resonance stays (a tenth of a dB), below the noise a
    # rig's log would carry
    assert r.residual_db_rms < 0.15 and r.residual_phase_deg_rms < 1.0
    # ... and the coherence says where: the fit is judged against it, not blamed on the model
    assert r.verdict == "fits to the noise", r.verdict_text()
    assert main(["frf", str(log)]) == 0
    assert "H1" in capsys.readouterr().out


@pytest.mark.parametrize("args, where", [
    (["--input", "voltage_V"], "--input"),
    (["--output", "speed"], "--output"),
    (["--band", "300:2"], "--band"),
    (["--segment", "1000000"], "--segment"),
    (["-o", "{log}"], "-o"),
])
def test_bad_frf_options_are_one_line(tmp_path, capsys, args, where):
    log = tmp_path / "log.csv"
    t = np.arange(0, 1, 1e-3)
    np.savetxt(log, np.column_stack([t, np.sin(50 * t), np.cos(50 * t)]), delimiter=",",
               header="time_s,current_A,motor_angle_rad", comments="")
    before = log.read_text()
    assert main(["frf", str(log), *[a.format(log=log) for a in args]]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and where in err, err
    assert log.read_text() == before


def test_a_log_without_time_is_refused(tmp_path, capsys):
    log = tmp_path / "log.csv"
    log.write_text("t,current_A,motor_angle_rad\n" + "0,1,2\n" * 40)
    assert main(["frf", str(log)]) == 2
    assert "time_s" in capsys.readouterr().err


def test_the_coherence_enters_the_noise_floor(far_rig):
    """The window's bias around the resonance lowers the coherence there; without the
    coherence the same estimate reads as a model mismatch at the resonance."""
    from dataclasses import replace

    from servo_toolkit.identify.verdict import coherence_variance
    scene, rig, truth = far_rig
    t, u, angle = rig_log(rig)
    data = estimate_frf(t, u, angle, segment=16384, band=(2, 300), derivative=True)
    assert data.coherence.min() < 0.9  # around the resonance
    with_coherence = fit(scene, data, "plant", KEYS, starts=0)
    blind = fit(scene, replace(data, coherence=np.ones(data.points)), "plant", KEYS, starts=0)
    assert with_coherence.verdict == "fits to the noise"
    assert blind.verdict == "model mismatch" and any(lo < 25 for lo in
                                                     (float(m.split()[0].split("-")[0]) for m in blind.misses))
    assert with_coherence.noise_floor > 3 * blind.noise_floor
    np.testing.assert_allclose(coherence_variance([1.0, 0.5, 0.0], averages=8), [0.0, 1 / 32, 1 / 16])
