"""The rig excitation (``excite``): the crest factor of its signals against closed forms, an
excitation that stays within the scene's limits in the model's own run, and a file that
``frf`` reads as it is and from which it recovers the model's response at the excited lines."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from servo_toolkit import load_scene
from servo_toolkit.cli import main
from servo_toolkit.drivetrain.operating_point import operating_point
from servo_toolkit.errors import SceneError
from servo_toolkit.plant.linear import DEFAULT_STRUCTURAL_DAMPING
from servo_toolkit.studies.excite import excite
from servo_toolkit.studies.excite.signals import crest_factor, multisine, prbs
from servo_toolkit.plant.sampled import drive_plant_response
from servo_toolkit.studies.multisine import schroeder

from .conftest import SCENES, memoized_designs
from .test_multisine import linear_ema

EMA = SCENES / "ema_reference.toml"


@pytest.fixture(scope="module", autouse=True)
def memoized_design():
    """The loop design once per scene (it is deterministic): keeps each run short."""
    with memoized_designs():
        yield


def _analytic(x, lines):
    """The analytic signal of a real signal whose spectrum holds only ``lines`` (positive bins)."""
    spectrum = np.fft.fft(x)
    z = np.zeros_like(spectrum)
    z[lines] = 2 * spectrum[lines]
    return np.fft.ifft(z)


@pytest.mark.parametrize("count", [31, 101])
def test_schroeder_multisine_meets_its_closed_form(count):
    """Schroeder's phases -pi n (n - 1) / N on N equal lines (Schroeder 1970) are a
    quadratic-phase sequence: for an odd N the analytic signal's magnitude is exactly sqrt(N)
    times a line's amplitude at the N instants m T / N (a Gauss sum), while the rms is sqrt(N / 2)
    of it: at those instants the signal reaches at most sqrt(2) times its rms, the crest factor
    of the chirp the construction imitates. Between them the envelope ripples, so the period's
    crest factor lies between sqrt(2) and 2, against sqrt(2 N) for the same lines in phase; the
    excitation's multisine keeps the lines, equal, and lowers the crest factor further."""
    lines = np.arange(7, 7 + count)
    samples = 16 * count
    x = schroeder(lines, samples)
    envelope = np.abs(_analytic(x, lines))[::16]
    rms = math.sqrt(float(np.mean(x * x)))
    np.testing.assert_allclose(envelope, math.sqrt(2) * rms, rtol=1e-9)
    assert np.max(np.abs(x[::16])) <= math.sqrt(2) * rms * (1 + 1e-12)
    assert math.sqrt(2) < crest_factor(x) < 2.0
    in_phase = np.cos(2 * np.pi * np.outer(np.arange(samples) / samples, lines)).sum(axis=1)
    assert crest_factor(in_phase) == pytest.approx(math.sqrt(2 * count), rel=1e-9)
    y = multisine(lines, samples, seed=0)
    assert np.max(np.abs(y)) == pytest.approx(1.0)
    assert crest_factor(y) <= crest_factor(x) and crest_factor(y) < 1.6
    spectrum = np.abs(np.fft.rfft(y))
    np.testing.assert_allclose(spectrum[lines], spectrum[lines].mean(), rtol=1e-9)
    others = np.setdiff1d(np.arange(spectrum.size), lines)
    assert np.max(spectrum[others]) < 1e-9 * spectrum[lines].mean()


@pytest.mark.parametrize("bits", [5, 10])
def test_prbs_has_the_binary_sequences_crest_factor_and_flat_spectrum(bits):
    """A maximum-length sequence of L = 2^n - 1 values +-1 sums to 1, so with its mean 1/L
    removed its two levels are 1 - 1/L and -1 - 1/L: crest factor sqrt((1 + 1/L) / (1 - 1/L));
    its period's DFT has the same magnitude sqrt(L + 1) at every nonzero bin."""
    length = 2 ** bits - 1
    x = prbs(bits, 1, seed=3)
    assert x.size == length
    assert crest_factor(x) == pytest.approx(math.sqrt((1 + 1 / length) / (1 - 1 / length)), rel=1e-12)
    levels = x * (1 + 1 / length) / np.max(np.abs(x))  # back to the +-1 sequence less its mean
    magnitude = np.abs(np.fft.fft(levels))[1:]
    np.testing.assert_allclose(magnitude, math.sqrt(length + 1), rtol=1e-9)


@pytest.mark.parametrize("drive", ["current", "speed"])
def test_the_excitation_stays_within_the_limits_in_the_models_run(drive):
    """The reference EMA under its 700 N*m hinge moment (25 A hold it), its limits 60 A and
    270 V: the chosen amplitude keeps the model's own run (every RK4 step's current, every
    sample's voltage) under 90 % of both limits and inside the stroke, and an amplitude beyond
    the limits is refused naming --amplitude."""
    scene = load_scene(EMA)
    r = excite(scene, input=drive, resolution=2.0, periods=2)
    assert r.amplitude_source == "chosen" and r.amplitude > 0
    assert r.run_peak_current_A < 0.9 * scene.motor.current_limit
    assert r.run_peak_voltage_V < 0.9 * scene.motor.voltage_limit
    assert np.max(np.abs(r.log["current_A"])) <= r.run_peak_current_A
    assert np.max(np.abs(r.log["voltage_V"])) <= r.run_peak_voltage_V
    lo, hi = scene.drivetrain.stroke
    out = r.log["output_angle_rad"]
    assert lo < out.min() and out.max() < hi
    assert r.operating_current_A == pytest.approx(25.2, abs=0.1)
    assert np.ptp(r.log["current_A"]) > 2 * r.breakaway_current_A  # above the breakaway level here
    assert r.amplitude <= min(b.amplitude for b in r.bounds) * (1 + 1e-12)
    with pytest.raises(SceneError) as info:
        excite(scene, input=drive, resolution=2.0, periods=2, amplitude=20 * r.amplitude)
    assert info.value.key == "--amplitude" and "limit" in info.value.rule


def _cli(argv, capsys):
    code = main([str(a) for a in argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_frf_reads_the_file_and_recovers_the_models_response(tmp_path, capsys):
    """The reference EMA without its nonlinearities: ``excite -o`` writes the excitation and
    the model's run of it, and ``frf`` reads that file as it is (the period from its comment
    line, the settling period left out) and recovers the linear plant's motor speed per current
    at every excited line within 0.02 dB and 0.1 deg, from the motor angle (--derivative) and
    from the motor speed alike, each line's coherence 1: the response as the drive samples the
    current and the speed at its control instants (the continuous one is 0.13 deg away)."""
    scene = linear_ema(tmp_path / "linear.toml")
    stimulus = tmp_path / "stimulus.csv"
    code, out, err = _cli(["excite", tmp_path / "linear.toml", "-o", stimulus, "--resolution", "2", "--periods", "3",
                           "--json"], capsys)
    assert code == 0, err
    made = json.loads(out)
    lines = np.array([p["frequency_hz"] for p in made["points"]])
    assert made["periods"] == 3 and made["output_file"] == str(stimulus)
    text = stimulus.read_text()
    assert f"# period_samples: {made['period_samples']}\n" in text and "# settle_periods: " in text
    linear = drive_plant_response(scene, lines, operating_point(scene)[0], DEFAULT_STRUCTURAL_DAMPING)
    for extra in (["--derivative"], ["--output", "motor_speed_rad_s"]):
        code, out, err = _cli(["frf", stimulus, "--json", *extra], capsys)
        assert code == 0, err
        assert "the period as the log records it" in err
        got = json.loads(out)
        assert got["window"] == "periodic" and got["averages"] == 3
        f = np.array(got["frequency_hz"])
        at = np.array([int(np.argmin(np.abs(f - x))) for x in lines])
        np.testing.assert_allclose(f[at], lines, rtol=1e-6)
        gain, phase = np.array(got["gain_db"])[at], np.array(got["phase_deg"])[at]
        assert np.max(np.abs(gain - 20 * np.log10(np.abs(linear)))) < 0.02, extra
        dp = (phase - np.degrees(np.angle(linear)) + 180) % 360 - 180
        assert np.max(np.abs(dp)) < 0.1, extra
        assert np.min(np.array(got["coherence"])[at]) > 0.999


@pytest.mark.parametrize("argv, option", [
    (["--band", "50:5"], "--band"),
    (["--band", "5 Hz:50 V"], "--band"),
    (["--band", "5"], "--band"),
    (["--resolution", "0"], "--resolution"),
    (["--amplitude", "-3"], "--amplitude"),
    (["--amplitude", "3 V"], "--amplitude"),
    (["-o", "{tmp}/stimulus.txt"], "-o"),
    (["--band", "1:5000"], "--band"),
    (["--resolution", "0.001"], "--resolution"),
    (["--periods", "500"], "--periods"),
    (["--input", "speed", "--amplitude", "1e5 rpm"], "--amplitude"),
])
def test_bad_input_is_one_line_naming_the_option(argv, option, tmp_path, capsys):
    out = tmp_path / "out.csv"
    code, _, err = _cli(["excite", EMA, "-o", out, *[a.replace("{tmp}", str(tmp_path)) for a in argv]], capsys)
    lines = [ln for ln in err.splitlines() if ln.startswith("servo-toolkit: error")]
    assert code == 2 and len(lines) == 1 and option in lines[0], err
    assert "Traceback" not in err and not out.exists() and not (tmp_path / "stimulus.txt").exists()


def test_a_band_beyond_the_limit_states_the_limit(tmp_path, capsys):
    """The reference EMA samples at 10 kHz: the line states the highest frequency it takes."""
    code, _, err = _cli(["excite", EMA, "--band", "1:5000"], capsys)
    assert code == 2 and "must be at most 1250 Hz, an eighth of the drive's sample rate 10000 Hz" in err, err


def test_the_commands_choices_are_the_librarys():
    """``excite --signal`` and ``--input`` offer what the study takes (the parser names them
    without loading the study)."""
    from servo_toolkit.cli import cmd_excite
    from servo_toolkit.studies.excite import drive, signals
    assert cmd_excite.SIGNALS == signals.SIGNALS
    assert cmd_excite.INPUTS == drive.INPUTS and cmd_excite.UNITS == drive.UNITS
