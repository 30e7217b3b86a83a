"""The error a logged signal's resolution (an encoder's counts) leaves in a frequency response
estimated from a periodic log: it repeats each period, so the coherence does not see it, and
its size per line is the rounding's uniform error (variance step^2 / 12, white) at that line
over the signal's own power there. Checked against the error the rounding actually leaves on a
periodic log, and carried from the log through ``frf`` to ``fit``'s noise."""

from __future__ import annotations

import math

import numpy as np
import pytest

from servo_toolkit.core.spectra import periodic_h1, resolution_sd
from servo_toolkit.errors import SceneError
from servo_toolkit.identify.data import read_data
from servo_toolkit.identify.frf import estimate_frf, read_time_log
from servo_toolkit.identify.noise import DB_PER_NEPER, frequency_noise
from servo_toolkit.identify.resolution import column_resolution, values_step

#: samples per period, periods, sample rate (Hz), the excited bins
PERIOD, PERIODS, FS, LINES = 4000, 4, 1000.0, np.arange(3, 201)


def _periodic_log(seed=0):
    """A multisine current (random phases) through a lightly damped mode and an integrator
    to an angle, in periodic steady state: ``(u, y)`` over whole periods."""
    rng = np.random.default_rng(seed)
    U = np.zeros(PERIOD // 2 + 1, complex)
    U[LINES] = np.exp(2j * np.pi * rng.random(LINES.size))
    s = 2j * np.pi * np.fft.rfftfreq(PERIOD, 1 / FS)
    w = 2 * np.pi * 40.0
    H = np.zeros_like(U)
    H[1:] = 1.0 / (s[1:] * (1 + 2 * 0.05 * s[1:] / w + (s[1:] / w) ** 2))
    u, y = np.fft.irfft(U, PERIOD), np.fft.irfft(U * H, PERIOD)
    return np.tile(u / np.ptp(u) * 10.0, PERIODS), np.tile(y / np.ptp(y), PERIODS)


@pytest.mark.parametrize("steps", [(0.0, 1 / 300), (0.0, 1 / 3000), (10 / 200, 0.0), (10 / 500, 1 / 1000)])
def test_the_stated_error_is_the_error_the_rounding_leaves(steps):
    """Rounding the input (10 A peak to peak) and the output (1 rad) of a periodic log to a few
    hundred to a few thousand steps: the estimate moves from the unrounded one, the coherence
    stays 1 (the same error in every period), and the moves over the stated standard deviation
    (real and imaginary parts of the relative error, 396 values) have an RMS of 1 (the white
    model; 0.5 or 2 if the statement were twice or half too large)."""
    u, y = _periodic_log()
    qu, qy = steps
    rounded = [np.round(x / q) * q if q else x for x, q in ((u, qu), (y, qy))]
    clean = periodic_h1(FS, u, y, PERIOD, lines=LINES)
    spec = periodic_h1(FS, *rounded, PERIOD, lines=LINES)
    assert spec.coherence.min() > 1 - 1e-12
    rel = spec.response / clean.response - 1
    sd = resolution_sd(spec, qu, qy)
    z = np.r_[rel.real, rel.imag] / np.r_[sd, sd]
    assert math.sqrt(np.mean(z ** 2)) == pytest.approx(1.0, abs=0.15)


def test_the_error_does_not_average_down_over_periods():
    """The same log with four times the periods: the rounding's error is the same, and so is
    its stated standard deviation (the coherence's falls by two)."""
    u, y = _periodic_log()
    q = 1 / 1000
    sds = []
    for periods in (PERIODS, 4 * PERIODS):
        uu, yy = np.tile(u[:PERIOD], periods), np.tile(y[:PERIOD], periods)
        sds.append(resolution_sd(periodic_h1(FS, uu, np.round(yy / q) * q, PERIOD, lines=LINES), 0.0, q))
    np.testing.assert_allclose(sds[1], sds[0], rtol=1e-9)


def test_a_column_resolution_from_the_log_or_from_its_values():
    """The step a log records is taken when the values lie on its grid (any offset); values
    that do not (a model's run) are not rounded to it; without a record, the values' own
    grid gives it, and a signal that is not rounded has none."""
    _, y = _periodic_log()
    q = 2 * math.pi / 4096
    counts = (np.round(y * 100 / q) + 17) * q + 0.3
    on = column_resolution(counts, "motor_angle_rad", q)
    assert on.step == q and on.basis == "as the log records it" and on.unit == "rad"
    found = column_resolution(counts, "motor_angle_rad")
    assert found.step == pytest.approx(q, rel=1e-9) and "smallest step" in found.basis
    assert values_step(np.round(counts, 9)) == pytest.approx(q, rel=1e-9)  # a log's digits
    coarse = column_resolution(np.round(counts / (4 * q)) * 4 * q, "motor_angle_rad", q)
    assert coarse.step == pytest.approx(4 * q, rel=1e-9) and "4 times" in coarse.basis
    assert column_resolution(y, "motor_angle_rad", q).step == 0.0
    assert column_resolution(y, "motor_angle_rad").step == 0.0
    assert "none" in column_resolution(y, "motor_angle_rad").text()


def _log_file(path, y, extra=""):
    t = np.arange(y.size) / FS
    u, _ = _periodic_log()
    rows = "\n".join(f"{a:.9g},{b:.12g},{c:.12g}" for a, b, c in zip(t, u, y))
    path.write_text(f"# period_samples: {PERIOD}\n{extra}time_s,current_A,motor_angle_rad\n{rows}\n")
    return path


def test_the_log_records_a_resolution_and_a_bad_one_is_refused(tmp_path):
    """``# resolution_COLUMN: STEP`` before the header is read per column; a step that is not
    a positive number is refused naming its key."""
    _, y = _periodic_log()
    log = read_time_log(_log_file(tmp_path / "a.csv", y, "# resolution_motor_angle_rad: 0.0015\n"))
    assert log.resolutions == {"motor_angle_rad": 0.0015}
    with pytest.raises(SceneError, match="resolution_motor_angle_rad.*positive step"):
        read_time_log(_log_file(tmp_path / "b.csv", y, "# resolution_motor_angle_rad: -1\n"))


def test_the_response_file_carries_the_resolution_and_fit_adds_it_in_power(tmp_path):
    """``frf_csv`` writes the rounding's standard deviations in dB and deg; read back, the
    noise of each point is the root-sum-square of the coherence's and the resolution's. A
    file without them reads as before; a negative one, or one column of the two, is refused."""
    from servo_toolkit.identify.frf import frf_csv
    u, y = _periodic_log()
    q = 1 / 1000
    noisy = np.round((y + np.random.default_rng(3).normal(0, 2e-4, y.size)) / q) * q
    data = estimate_frf(np.arange(y.size) / FS, u, noisy, period=PERIOD, settle=0, resolution=(0.0, q))
    path = tmp_path / "frf.csv"
    path.write_text(frf_csv(data))
    back = read_data(path)
    np.testing.assert_allclose(back.resolution_deg, np.degrees(back.resolution_db / DB_PER_NEPER), rtol=1e-5)
    noise = frequency_noise(back)
    from servo_toolkit.core.spectra import coherence_sd
    coh = coherence_sd(back.coherence, back.averages)
    np.testing.assert_allclose(noise.gain_db, np.hypot(DB_PER_NEPER * coh, back.resolution_db), rtol=1e-12)
    assert noise.basis == "coherence of 4 averaged spectra and the logged signals' resolution"
    path.write_text("\n".join(line.rsplit(",", 2)[0] for line in frf_csv(data).splitlines()) + "\n")
    plain = read_data(path)
    assert plain.resolution_db is None
    np.testing.assert_allclose(frequency_noise(plain).gain_db, DB_PER_NEPER * coh, rtol=1e-12)
    text = frf_csv(data).splitlines()
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join([text[0], text[1].rsplit(",", 1)[0] + ",-1"] + text[2:]) + "\n")
    with pytest.raises(SceneError, match="row 2.*resolution_deg"):
        read_data(bad)
    bad.write_text("\n".join(line.rsplit(",", 1)[0] for line in text) + "\n")
    with pytest.raises(SceneError, match="header"):
        read_data(bad)


def test_a_hann_estimate_of_an_input_that_does_not_repeat_adds_nothing():
    """Noise through the same mode: the rounding changes from segment to segment, the coherence
    sees it, and no resolution is added; the same input repeated adds it."""
    rng = np.random.default_rng(5)
    u = rng.normal(size=8 * 2048)
    y = np.cumsum(np.convolve(u, np.ones(8) / 8, "same")) * 1e-2
    q = np.ptp(y) / 2000
    t = np.arange(u.size) / FS
    noise = estimate_frf(t, u, np.round(y / q) * q, window="hann", resolution=(0.0, q))
    assert noise.resolution_db is None
    u, y = _periodic_log()
    again = estimate_frf(np.arange(u.size) / FS, u, np.round(y / q) * q, window="hann", resolution=(0.0, q))
    assert again.resolution_db is not None and np.all(again.resolution_db > 0)


def test_a_signal_moving_less_than_half_a_step_rms_is_named_coarse():
    """Widrow's model of the rounding needs a signal that crosses steps: a sine of 0.3 steps
    on a drift is named coarse (its line says what the figures may understate), one of three
    steps is not; the RMS is taken about the trend, so a drift over many steps does not hide
    a small motion."""
    t = np.arange(4096)
    q = 1e-3
    small = q * np.round((0.3 * np.sin(2 * np.pi * t / 256) + 0.01 * t) + 0.2)
    large = q * np.round(3.0 * np.sin(2 * np.pi * t / 256) + 0.2)
    coarse = column_resolution(small, "motor_angle_rad", q)
    fine = column_resolution(large, "motor_angle_rad", q)
    assert coarse.step == pytest.approx(q) and coarse.coarse and coarse.rms_steps < 0.5
    assert "steps RMS" in coarse.text() and coarse.to_dict()["coarse"] is True
    assert not fine.coarse and fine.rms_steps == pytest.approx(3.0 / math.sqrt(2), rel=0.05)
    assert "steps RMS" not in fine.text()
