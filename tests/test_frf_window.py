"""Which window ``frf`` takes and what it reports: a period is a real repeat (a slow sine,
held in steps as a controller's samples are, is not periodic at a few samples' lag), Hann
segments that cannot resolve the input are refused, and the phase stays on the branch of
its well-measured lines across poorly coherent ones."""

import math

import numpy as np
import pytest

from servo_toolkit import SceneError
from servo_toolkit.cli import main
from servo_toolkit.core.spectra import find_period
from servo_toolkit.identify.frf import estimate_frf

FS = 2500.0  # samples per second


def _held(x, hold):
    """``x`` held for ``hold`` samples at a time (a staircase: a controller's output logged
    faster than it updates)."""
    return np.repeat(x[::hold], hold)[: x.size]


def _periodic_response(u, period, h):
    """The periodic steady state of a system of response ``h(f)`` (Hz) to ``u``, which
    repeats every ``period`` samples: each period's DFT times ``h`` at its bins."""
    f = np.fft.rfftfreq(period, 1.0 / FS)
    one = np.fft.irfft(np.fft.rfft(u[:period]) * h(f), period)
    return np.resize(one, u.size)


def _closed_loop(f):
    """A second-order closed loop, 9 Hz natural frequency, damping 0.7."""
    s = 2j * np.pi * np.asarray(f, float)
    wn = 2 * np.pi * 9.0
    return wn ** 2 / (s ** 2 + 2 * 0.7 * wn * s + wn ** 2)


def test_a_slow_sine_held_in_steps_repeats_only_at_its_period():
    """A 2 Hz sine of 5 deg over 2 periods at 2.5 kHz, held 2 samples at a time (a 1250 Hz
    controller): it changes by under 1 % over 16 samples, but a period is where it repeats,
    1250 samples; the response is the closed loop's at 2 Hz, the only frequency it excites
    (a period of 16 samples was found, and lines from 156 Hz up: smoothness taken for a
    period)."""
    n = 2501
    t = np.arange(n) / FS
    u = _held(np.radians(5.0) * np.sin(2 * np.pi * 2.0 * t), 2)
    assert find_period(u) == 1250
    y = _periodic_response(u, 1250, _closed_loop)
    data = estimate_frf(t, u, y)
    assert data.window == "periodic" and data.averages == 2
    assert data.frequency_hz.tolist() == pytest.approx([2.0])
    exact = _closed_loop(2.0)
    assert data.gain_db[0] == pytest.approx(20 * math.log10(abs(exact)), abs=1e-9)
    assert data.phase_deg[0] == pytest.approx(math.degrees(np.angle(exact)), abs=1e-7)


@pytest.mark.parametrize("signal, period", [
    ("slow_sine", None),        # 0.4 of a period: smooth, repeats nowhere
    ("held_ramp", None),        # a ramp in steps of 8 samples
    ("sine_10_periods", 250),   # 10 Hz, held 2 samples at a time
    ("chirp", None),
    ("noise", None),
    ("multisine", 500),         # lines 3 to 40 of a 500-sample period, 5 periods
])
def test_find_period_takes_repeats_not_smoothness(signal, period):
    rng = np.random.default_rng(5)
    n = 2500
    t = np.arange(n) / FS
    if signal == "slow_sine":
        u = np.sin(2 * np.pi * 0.4 * t)
    elif signal == "held_ramp":
        u = _held(t, 8)
    elif signal == "sine_10_periods":
        u = _held(np.sin(2 * np.pi * 10.0 * t), 2)
    elif signal == "chirp":
        from scipy.signal import chirp
        u = chirp(t, 1.0, t[-1], 200.0)
    elif signal == "noise":
        u = rng.normal(size=n)
    else:
        k = np.arange(3, 41)
        one = np.sum(np.cos(2 * np.pi * np.outer(np.arange(500), k) / 500 + rng.uniform(0, 2 * np.pi, k.size)), 1)
        u = np.tile(one, 5)
    assert find_period(u) == period


def test_hann_segments_that_cannot_resolve_the_input_are_refused(tmp_path, capsys):
    """A 1 Hz sine over 1 s: the default Hann segments (256 samples) have their lowest line at
    9.8 Hz, and their lines hold only the window's leakage of the 1 Hz (the estimate had
    lines at 9.8, 19.5 ... 49 Hz, gains near 0 dB): refused naming --segment, the share below
    the lowest line and the fix; the period given, the 1 Hz response is the loop's."""
    n = 2501
    t = np.arange(n) / FS
    u = np.radians(5.0) * np.sin(2 * np.pi * 1.0 * t)
    y = _periodic_response(u, 2500, _closed_loop)
    with pytest.raises(SceneError, match=r"--segment: 100% of the input's power lies below the lowest line of "
                                         r"256-sample Hann segments \(9\.766 Hz"):
        estimate_frf(t, u, y)
    log = tmp_path / "trace.csv"
    np.savetxt(log, np.column_stack([t, u, y]), delimiter=",", header="t_s,reference_angle_rad,output_angle_rad",
               comments="", fmt="%.12g")
    args = ["frf", str(log), "--input", "reference_angle_rad", "--output", "output_angle_rad"]
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "--segment" in err and "--window periodic --period" in err
    # a 5 Hz sine: 512-sample segments (lowest line 4.9 Hz) resolve it, 256-sample ones are refused
    five = np.sin(2 * np.pi * 5.0 * t[:2500])
    assert estimate_frf(t[:2500], five, 0.5 * five, segment=512).window == "hann"
    with pytest.raises(SceneError, match=r"give --segment 500 or more \(at most 1250\)"):
        estimate_frf(t[:2500], five, 0.5 * five, segment=256)
    data = estimate_frf(t, u, y, window="periodic", period=2500)
    exact = _closed_loop(1.0)
    assert data.frequency_hz.tolist() == pytest.approx([1.0])
    assert data.complex[0] == pytest.approx(exact, rel=1e-9)


def test_the_phase_keeps_its_branch_across_poorly_coherent_lines(tmp_path):
    """A periodic log of a response whose phase falls smoothly from 0 to -150 deg; in a band
    of 40 lines the excitation is 1000 times weaker, so noise leaves the coherence there near
    0 and the phase at random. The well-measured lines keep the response's phase (within 3
    deg), every poor line lies within half a turn of it, and the CSV written says the same
    (the unwrapping across the poor lines had shifted every line after them by a
    turn)."""
    rng = np.random.default_rng(1)
    period, periods = 400, 4
    lines = np.arange(1, 121)
    weak = (lines >= 40) & (lines < 80)
    amplitude = np.where(weak, 1e-3, 1.0)
    one = np.zeros(period // 2 + 1, complex)
    one[lines] = amplitude * np.exp(2j * np.pi * rng.uniform(size=lines.size))
    u_one = np.fft.irfft(one, period)

    def h(f):
        return np.exp(-1j * np.radians(150.0) * np.asarray(f) / (lines[-1] * FS / period))

    u = np.tile(u_one, periods)
    y = _periodic_response(u, period, h) + rng.normal(0, 0.02 * np.std(u_one), u.size)
    t = np.arange(u.size) / FS
    data = estimate_frf(t, u, y, window="periodic", period=period, settle=0, lines=lines)
    truth = np.degrees(np.angle(h(data.frequency_hz)))
    good = data.coherence > 0.99
    assert good.sum() == 80 and np.all(data.coherence[weak] < 0.9)
    assert np.max(np.abs(data.phase_deg[good] - truth[good])) < 3.0
    assert np.max(np.abs(data.phase_deg - truth)) <= 180.0
    from servo_toolkit.identify.frf import frf_csv
    written = np.genfromtxt(frf_csv(data).splitlines(), delimiter=",", names=True)
    assert np.max(np.abs(written["phase_deg"][good] - truth[good])) < 3.0


def test_a_tones_hann_leakage_is_not_taken_for_excited_lines():
    """A sine half a line off the lines of Hann segments (2048 samples at 1 kHz: 0.49 Hz
    lines) leaks into lines 1.5 and 2.5 lines away at -15 and -32 dB, within 40 dB of its
    peak, and the segments' leftover mean into the lowest line: their H1 is another line's
    response put at their frequencies. Only the tone's own two lines are kept. Noise, white
    or low-passed on an offset, loses no line over 40 logs."""
    from scipy import signal as sig

    from servo_toolkit.core.spectra import hann_leakage, leakage_lines, welch_h1
    assert hann_leakage([0.0, 1.0, 2.0]) == pytest.approx([1.0, 0.25, 0.0], abs=1e-12)
    fs, n, segment = 1000.0, 40960, 2048
    step = fs / segment
    f0 = 15.5 * step
    t = np.arange(n) / fs
    tone = welch_h1(fs, np.sin(2 * np.pi * f0 * t), 0.5 * np.sin(2 * np.pi * f0 * t - 0.3), segment)
    assert tone.frequency_hz == pytest.approx([f0 - step / 2, f0 + step / 2])
    _, suu = sig.welch(np.sin(2 * np.pi * f0 * t), fs=fs, window="hann", nperseg=segment, noverlap=segment // 2)
    within = (suu >= suu.max() * 1e-4)[1:]
    assert int(within.sum()) == 7  # the 40 dB threshold alone: the lowest line and the leakage 1.5 and 2.5 off too
    rng = np.random.default_rng(3)
    b, a = sig.butter(4, 0.05)
    for _ in range(20):
        noise = rng.normal(size=n)
        for x in (noise, sig.lfilter(b, a, noise) + 3.0):
            _, suu = sig.welch(x, fs=fs, window="hann", nperseg=1024, noverlap=512)
            assert not leakage_lines(suu)[suu >= suu[1:].max() * 1e-4].any()
