"""From a rig's time log to a frequency response (H1, Welch) and on to the fit: the log of a
broadband current excitation gives the current -> speed response with its coherence, the
CSV `fit` reads, and the fit recovers the rig."""

import json
import math

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


def rig_log(scene, periods=5, seed=0, counts=2 ** 20, noise=1e-5):
    """A rig in steady state under a random-phase multisine current (0.25-400 Hz every
    0.25 Hz, 2 A RMS): the motor angle's spectrum is the current's times the rig's
    current -> speed response over j w; white sensor noise (``noise`` rad, about two counts)
    is added and the encoder quantizes it."""
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
    angle = angle + np.random.default_rng(seed + 100).normal(0, noise, angle.size)
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
    (["--window", "periodic", "--segment", "64"], "--segment"),
    (["--period", "64", "--settle", "100"], "--settle"),
    (["--window", "hann", "--period", "64"], "--period"),
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


@pytest.mark.parametrize("header, row, where, rule", [
    ("time_ms,current_A,motor_angle_rad", None, "header", "column 1 is 'time_ms': the time must be in s"),
    ("time_s,current_A,motor_angle_rad", "0.007,nan,0", "row 9", "current_A must be a finite number (got nan)"),
])
def test_a_log_names_the_column_it_refuses(tmp_path, capsys, header, row, where, rule):
    log = tmp_path / "log.csv"
    rows = [f"{k * 1e-3:g},1,2" for k in range(40)]
    if row is not None:
        rows[7] = row
    log.write_text(header + "\n" + "\n".join(rows) + "\n")
    assert main(["frf", str(log)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and where in err and rule in err, err


def test_a_log_without_time_is_refused(tmp_path, capsys):
    log = tmp_path / "log.csv"
    log.write_text("t,current_A,motor_angle_rad\n" + "0,1,2\n" * 40)
    assert main(["frf", str(log)]) == 2
    assert "time_s" in capsys.readouterr().err


def test_the_coherence_is_the_noise_floor(far_rig):
    """The Hann window's bias around the resonance lowers the coherence there; with the
    coherence and its number of averages the fit judges the estimate against it; without
    them (the scatter about a local fit, which a smooth bias does not show) the same
    estimate reads as a model mismatch at the resonance."""
    from dataclasses import replace

    from servo_toolkit.identify.noise import coherence_sd, frequency_noise
    scene, rig, truth = far_rig
    t, u, angle = rig_log(rig)
    data = estimate_frf(t, u, angle, segment=16384, band=(2, 300), derivative=True)
    assert data.window == "hann" and data.averages == 9  # 5 periods of 16384 samples, half overlap
    assert data.coherence.min() < 0.9  # around the resonance
    with_coherence = fit(rig, data, "plant", KEYS, starts=0)
    blind = fit(rig, replace(data, averages=None), "plant", KEYS, starts=0)
    assert with_coherence.verdict == "fits to the noise", with_coherence.verdict_text()
    assert "coherence of 9 averaged spectra" in with_coherence.verdict_text()
    assert blind.verdict == "model mismatch" and any(
        lo < 25 for lo in (float(m.split()[0].split("-")[0]) for m in blind.misses))
    # the noise is the coherence's alone (Bendat and Piersol), not added to a scatter
    noise = frequency_noise(data)
    np.testing.assert_allclose(noise.phase_deg, np.maximum(np.degrees(coherence_sd(data.coherence, 9)), 1e-6))
    np.testing.assert_allclose(coherence_sd([1.0, 0.5, 0.0], averages=8), [0.0, math.sqrt(1 / 16), math.inf])


def test_a_multisine_log_is_cut_into_its_periods(far_rig, tmp_path, capsys):
    """By default a periodic log is estimated period by period with rectangular windows: no
    leakage, the estimate is the rig's to its sensor noise (the Hann estimate of the same log
    is off by 0.9 dB at the resonance), and the fit finds the rig to 1e-5."""
    scene, rig, truth = far_rig
    t, u, angle = rig_log(rig)
    log = tmp_path / "rig_log.csv"
    np.savetxt(log, np.column_stack([t, u, angle]), delimiter=",", header="time_s,current_A,motor_angle_rad",
               comments="", fmt="%.10g")
    out = tmp_path / "frf.csv"
    assert main(["frf", str(log), "--derivative", "--band", "2:300", "-o", str(out), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["window"] == "periodic" and d["averages"] == 4  # 5 periods, the first left out as settling
    data = read_data(out)
    assert data.averages == 4
    # the estimate's error is the sensor noise the coherence states (Bendat and Piersol)
    from servo_toolkit.identify.noise import frequency_noise
    err = data.gain_db - 20 * np.log10(np.abs(plant_response(rig, data.frequency_hz)))
    assert np.sqrt(np.mean((err / frequency_noise(data).gain_db) ** 2)) < 2
    near = (data.frequency_hz > 15) & (data.frequency_hz < 40)  # around the antiresonance and resonance
    assert np.max(np.abs(err[near])) < 0.01
    r = fit(scene, data, "plant", KEYS, starts=0)
    assert r.values == pytest.approx(truth, rel=1e-5)
    assert r.verdict == "fits to the noise", r.verdict_text()


def linear_rig_log(rig, u, fs):
    """The rig's motor speed under a current ``u`` (the linear plant from rest; python-control
    joins the input's samples by straight lines), and the response a log of it shows: the
    rig's continuous response times that of the first-order hold, sinc^2(f / fs) (real: the
    triangle is even; the current is the straight line, not a drive's held steps)."""
    import control as ct

    from servo_toolkit.plant.linear import mechanics
    from servo_toolkit.plant.sampled import drive_plant_response
    m = mechanics(rig)
    sub = rig.motor.torque_constant * m[m.output_labels.index("omega_m"), m.input_labels.index("tau_m")]
    t = np.arange(u.size) / fs
    return t, np.asarray(ct.forced_response(sub, t, u).outputs).reshape(-1), \
        lambda f: drive_plant_response(rig, f, sample_time=0.0) * np.sinc(f / fs) ** 2


@pytest.mark.parametrize("excitation", ["chirp", "noise"])
def test_h1_of_a_chirp_and_of_band_limited_noise(far_rig, excitation):
    """A logarithmic chirp 1-300 Hz repeated 8 times, and band-limited noise (white noise
    through a 4th-order Butterworth band pass 1-300 Hz), on the rig simulated from rest; the
    speed carries white noise of 0.1 % of its RMS. Welch's H1 gives the rig's response where
    the coherence says the estimate is good."""
    from scipy import signal
    _, rig, _ = far_rig
    fs, n = 2048.0, 2 ** 16
    rng = np.random.default_rng(7)
    if excitation == "chirp":
        one = np.arange(n // 8) / fs
        u = np.tile(signal.chirp(one, 1.0, one[-1], 300.0, method="logarithmic"), 8)
    else:
        sos = signal.butter(4, [1.0, 300.0], btype="bandpass", fs=fs, output="sos")
        u = signal.sosfilt(sos, rng.normal(size=n))
        u /= u.std()
    t, w, exact = linear_rig_log(rig, u, fs)
    w = w + rng.normal(0, 1e-3 * w.std(), w.size)
    data = estimate_frf(t, u, w, window="hann", band=(3, 250))
    assert data.window == "hann" and data.averages == 15  # 8 segments of 8192 samples, half overlap
    good = data.coherence > 0.99
    assert good.mean() > 0.9
    ratio = data.complex[good] / exact(data.frequency_hz[good])
    assert np.median(np.abs(20 * np.log10(np.abs(ratio)))) < 0.05
    assert np.median(np.abs(np.angle(ratio, deg=True))) < 0.5


def test_the_period_of_a_log_is_found_or_refused(tmp_path, capsys):
    from servo_toolkit.core.spectra import find_period
    rng = np.random.default_rng(3)
    one = rng.normal(size=300)
    assert find_period(np.tile(one, 4)) == 300
    assert find_period(rng.normal(size=1200)) is None
    log = tmp_path / "log.csv"
    t = np.arange(1200) * 1e-3
    np.savetxt(log, np.column_stack([t, rng.normal(size=1200), rng.normal(size=1200)]), delimiter=",",
               header="time_s,current_A,motor_angle_rad", comments="")
    assert main(["frf", str(log), "--window", "periodic"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--window" in err and "repeats" in err


def test_frf_reads_what_simulate_writes(tmp_path, capsys):
    """``simulate -o`` then ``frf`` on that file: the time column t_s is recognised, the run's
    last, shorter step (0.8105 s is not a whole number of 0.2 ms records) is left out with a
    note, and the closed loop's response at the 8 Hz command equals the sine-dwell
    correlation of the same trace over the same whole periods (read independently)."""
    from servo_toolkit.studies.sine_dwell import fundamental
    scene = tmp_path / "ema.toml"
    scene.write_text((SCENES / "ema_reference.toml").read_text() + '\n[studies.short]\nkind = "simulate"\n'
                     'frequency = "8 Hz"\namplitude = "2 deg"\nduration = "0.8105 s"\n')
    trace = tmp_path / "trace.csv"
    assert main(["simulate", str(scene), "--study", "short", "-o", str(trace)]) == 0
    capsys.readouterr()
    data = np.genfromtxt(trace, delimiter=",", names=True)
    t = data["t_s"]
    steps = np.diff(t)
    assert 0 < steps[-1] < 0.99 * steps[0]  # the case: a last, shorter step
    # the default output column is a rig's: the error names the option, its role and the columns there are
    assert main(["frf", str(trace)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "--output motor_angle_rad" in err and "output (response) signal's column" in err
    assert "output_angle_rad, output_rate_rad_s" in err
    period = round(3 / 8 / steps[0])  # 3 periods of 8 Hz, a whole number of records
    assert main(["frf", str(trace), "--input", "reference_angle_rad", "--output", "output_angle_rad",
                 "--period", str(period), "--settle", "1", "--json"]) == 0
    captured = capsys.readouterr()
    out = json.loads(captured.out)
    assert out["time_column"] == "t_s" and "left out the last sample" in captured.err
    assert len(out["log_notes"]) == 1 and f"t = {t[-1]:.6g} s" in out["log_notes"][0]
    k = out["frequency_hz"].index(pytest.approx(8.0, rel=1e-3))
    window = period * steps[0]
    h = (fundamental(t, data["output_angle_rad"], 8.0, window, 3)
         / fundamental(t, data["reference_angle_rad"], 8.0, window, 3))
    assert out["gain_db"][k] == pytest.approx(20 * np.log10(abs(h)), abs=0.01)
    assert out["phase_deg"][k] == pytest.approx(np.degrees(np.angle(h)), abs=0.1)
    assert out["coherence"][k] > 0.99


@pytest.mark.parametrize("last, uneven_row, kept", [(0.4e-3, None, 99), (1e-3, None, 100), (1.6e-3, 101, None)])
def test_only_a_last_shorter_step_is_left_out(tmp_path, last, uneven_row, kept):
    """A log whose every step is 1 ms but the last: a shorter last step (a run stopping at its
    final time) loses that sample with a note; an even one is kept whole; a longer one, or an
    uneven step anywhere else, is refused naming the row, the time column and the rule."""
    from servo_toolkit import SceneError
    from servo_toolkit.identify.frf import read_time_log
    t = np.append(np.arange(99) * 1e-3, 98e-3 + last)
    log = tmp_path / "trace.csv"
    np.savetxt(log, np.column_stack([t, np.sin(50 * t), np.cos(50 * t)]), delimiter=",",
               header="t_s,reference_angle_rad,output_angle_rad", comments="", fmt="%.10g")
    if kept is None:
        with pytest.raises(SceneError, match=rf"row {uneven_row}: t_s must increase equally spaced"):
            read_time_log(log)
    else:
        got = read_time_log(log)
        assert got.time_column == "t_s" and got.time_s.size == kept and got.columns["output_angle_rad"].size == kept
        assert len(got.notes) == (kept == 99)
    t[50] += 0.3e-3  # one uneven step in the middle: refused whatever the last step
    np.savetxt(log, np.column_stack([t, np.sin(50 * t), np.cos(50 * t)]), delimiter=",",
               header="t_s,reference_angle_rad,output_angle_rad", comments="", fmt="%.10g")
    with pytest.raises(SceneError, match=r"row 52: t_s must increase equally spaced, every step within 1%"):
        read_time_log(log)


def _run(argv, capsys):
    code = main([str(a) for a in argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def _periodic_log(path, head: str, period: int = 64, periods: int = 5):
    k = np.arange(period * periods)
    u = sum(np.cos(2 * np.pi * m * k / period + m * m) for m in range(3, 8))
    y = 0.5 * np.roll(u, 2)
    path.write_text(head + "time_s,current_A,motor_angle_rad\n"
                    + "".join(f"{t * 1e-3:.6f},{a:.17g},{b:.17g}\n" for t, a, b in zip(k, u, y)))


def test_frf_takes_the_period_a_log_records(tmp_path, capsys):
    """A log's comment lines before its header record its period, settling periods and
    excited bins: frf uses them (4 of 5 periods averaged with one settling, the bins named
    and no other), an option overrides them, and a recorded value that is not a whole
    number, a period longer than the log or bins beyond half of it is one line naming it."""
    log = tmp_path / "log.csv"
    _periodic_log(log, "# rig log\n# period_samples: 64\n# settle_periods: 1\n# excited_bins: 4:6\n")
    code, out, err = _run(["frf", log, "--json"], capsys)
    got = json.loads(out)
    assert code == 0 and got["averages"] == 4, err
    np.testing.assert_allclose(got["frequency_hz"], np.array([4, 5, 6]) / 0.064)
    code, out, err = _run(["frf", log, "--json", "--settle", "2"], capsys)
    assert code == 0 and json.loads(out)["averages"] == 3, err
    for head, key in (("# period_samples: x\n", "# period_samples"), ("# period_samples: 999\n", "# period_samples"),
                      ("# period_samples: 64\n# settle_periods: 5\n", "# settle_periods"),
                      ("# period_samples: 64\n# excited_bins: 7:3\n", "# excited_bins"),
                      ("# period_samples: 64\n# excited_bins: 3:40\n", "# excited_bins")):
        _periodic_log(log, head)
        code, _, err = _run(["frf", log], capsys)
        assert code == 2 and err.count("servo-toolkit: error") == 1 and key in err, err


@pytest.mark.parametrize("args, option", [(["--band", "500:600"], "--band"), (["--settle", "10"], "--settle")])
def test_a_failing_estimate_prints_its_error_alone(args, option, tmp_path, capsys):
    """The note of the period a log records comes with a result, never before the error of
    a run that fails: stderr is the one error line."""
    log = tmp_path / "log.csv"
    _periodic_log(log, "# period_samples: 64\n# settle_periods: 1\n# excited_bins: 4:6\n")
    code, _, err = _run(["frf", log, *args], capsys)
    assert code == 2 and err.strip().splitlines() == [err.strip()] and option in err, err
    code, _, err = _run(["frf", log], capsys)
    assert code == 0 and "the period as the log records it" in err, err
