"""Sine-dwell sweep of the nonlinear closed loop against the linear closed loop."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from servo_toolkit import SceneError, load_scene
from servo_toolkit.cli import main
from servo_toolkit.sim import ModelOptions
from servo_toolkit.studies.sine_dwell import DwellPlan, fundamental
from servo_toolkit.studies.sweep.compute import study_points, sweep

from .conftest import build, variant


def test_fundamental_rejects_mean_and_harmonics():
    """Correlation over whole cycles returns the drive-frequency phasor; the mean and the
    harmonics drop out, and what remains is the linear-interpolation error of resampling,
    below (w h)^2 / 8 = 7.9e-5 relative for a record step h = 0.5 ms at 8 Hz."""
    f, a, phi = 8.0, 0.7, -1.1
    t = np.linspace(0.0, 3.0, 6001)
    y = 0.3 + a * np.sin(2 * np.pi * f * t + phi) + 0.2 * np.sin(2 * np.pi * 3 * f * t) \
        + 0.05 * np.cos(2 * np.pi * 2 * f * t)
    z = fundamental(t, y, f, 1.0, 8)
    bound = (2 * np.pi * f * (t[1] - t[0])) ** 2 / 8
    assert abs(abs(z) - a) / a < bound
    assert abs(np.angle(z) - phi) < bound


def _lossless(data):
    """The scene dict with every stage's efficiency 1 (no drivetrain loss)."""
    for stage in data["drivetrain"]:
        if "efficiency" in stage:
            stage["efficiency"] = 1.0
    return data


def test_small_signal_sweep_matches_linear_loop(ema_dict):
    """Backlash, friction (the motor's and the drivetrain's losses, which under the hinge
    moment act as a load-proportional friction) and quantization off, a small amplitude: the
    nonlinear loop's sine-dwell response equals the linear closed loop within 0.5 dB and 3 deg."""
    scene = build(_lossless(variant(ema_dict, motor__coulomb_friction=0)))
    opts = ModelOptions(backlash=False, quantization=False)
    res = sweep(scene, frequencies=[1.0, 8.0, 20.0, 30.0], amplitudes=[math.radians(0.2)],
                options=opts, progress=False)
    assert not res.saturated.any()
    assert all(e is None for e in res.errors)
    dg = np.abs(res.gain_db[0] - res.linear_gain_db)
    dp = np.abs(res.phase_deg[0] - res.linear_phase_deg)
    assert np.max(dg) < 0.5, dg
    assert np.max(dp) < 3.0, dp
    # the points are not trivially flat: the loop rolls off and lags across the sweep
    assert res.linear_phase_deg[-1] < -60
    d = res.to_dict()
    for key in ("frequency_hz", "gain_db", "phase_deg", "linear_gain_db", "linear_phase_deg"):
        assert key in d["points"][0]
    assert d["model"]["reduced"] is False


def test_saturation_lowers_the_gain_and_is_flagged(ema_dict):
    """A 5 deg command at 20 Hz needs more current than the limit: the output falls short
    of the linear loop and the point is flagged, while 0.2 deg follows the linear loop (on a
    lossless chain: with the drivetrain's losses 0.2 deg sticks in the friction band the
    hinge moment holds, see test_sim_efficiency.py, and without the motor's Coulomb friction,
    which at 0.2 deg and 20 Hz weighs about 0.5 dB)."""
    scene = build(_lossless(variant(ema_dict, motor__coulomb_friction=0)))
    res = sweep(scene, frequencies=[20.0], amplitudes=[math.radians(0.2), math.radians(5.0)],
                options=ModelOptions(stroke_end="stop"), progress=False)
    small, large = res.gain_db[:, 0]
    assert not res.saturated[0, 0] and res.saturated[1, 0]
    assert res.peak_current_A[1, 0] == pytest.approx(scene.motor.current_limit, rel=1e-6)
    assert abs(small - res.linear_gain_db[0]) < 0.5
    assert large < res.linear_gain_db[0] - 1.0


def test_default_sweep_runs_the_reduced_model_and_says_so():
    """The default runs the reduced model, lists what it left out and keeps 8 Hz."""
    scene = load_scene()
    name, freqs, amps = study_points(scene)
    assert 8.0 in freqs and name == "sweep"
    res = sweep(scene, frequencies=[8.0], progress=False)
    assert res.reduced and res.left_out
    assert "left out" in res.table()
    assert any("reduced model" in n for n in res.notes)


def test_sweep_study_errors_name_the_key(ema_dict):
    """A sweep study without amplitude, or with a bad frequency table, names its key."""
    data = variant(ema_dict, studies__sweep__amplitude=None)
    with pytest.raises(SceneError, match=r"studies\.sweep\.amplitude"):
        study_points(build(data))
    data = variant(ema_dict, studies__sweep__frequencies={"start": "40 Hz", "stop": "1 Hz"})
    with pytest.raises(SceneError, match=r"studies\.sweep\.frequencies"):
        study_points(build(data))


def test_cli_sweep_json(capsys, scenes_dir):
    """``sweep --json`` prints the points with the documented keys; bad input exits 2."""
    code = main(["sweep", str(scenes_dir / "ema_reference.toml"), "--frequency", "8", "--json"])
    assert code == 0
    out = json.loads(capsys.readouterr().out)
    assert [p["frequency_hz"] for p in out["points"]] == [8.0]
    assert {"gain_db", "phase_deg", "linear_gain_db", "linear_phase_deg"} <= set(out["points"][0])
    # the option's value is refused before any work, in one line
    assert main(["sweep", str(scenes_dir / "ema_reference.toml"), "--amplitude", "-1"]) == 2
    err = capsys.readouterr().err
    assert "--amplitude" in err and "positive" in err and len(err.strip().splitlines()) == 1


def test_a_named_study_keeps_8hz_unless_frequencies_are_given():
    """The seed's 8 Hz joins a named study's frequencies (once) as it joins the default;
    explicit frequencies replace the whole list."""
    scene = load_scene()
    name, freqs, _ = study_points(scene, "sweep")
    assert name == "sweep" and 8.0 in freqs
    assert len(freqs) == 31 and freqs == tuple(sorted(freqs))     # 30 log points + 8 Hz
    assert study_points(scene, "sweep") == study_points(scene)
    res = sweep(scene, "sweep", frequencies=[3.0], amplitudes=[math.radians(0.5)], progress=False)
    assert res.frequencies_hz.tolist() == [3.0]


def test_a_study_of_another_kind_is_refused(capsys, scenes_dir):
    """``sweep --study kv_8hz`` is a kv study: SceneError naming studies.kv_8hz.kind, exit 2."""
    with pytest.raises(SceneError, match=r"studies\.kv_8hz\.kind.*frequency_sweep"):
        study_points(load_scene(), "kv_8hz")
    assert main(["sweep", str(scenes_dir / "ema_reference.toml"), "--study", "kv_8hz", "--frequency", "8"]) == 2
    err = capsys.readouterr().err
    assert "studies.kv_8hz.kind" in err and err.count("\n") == 1


def test_a_point_that_fails_after_reaching_a_limit_is_flagged_saturated():
    """Commands beyond the +-30 deg stroke end the run at the stroke end. At 2 Hz a 35 deg
    command needs far more than the 60 A limit (the current reference is clipped there before
    the failure): failed and saturated. At 0.5 Hz a 31 deg command stays below both limits
    until it reaches the stroke end: failed, not saturated."""
    scene = load_scene()
    opts = ModelOptions()    # stroke_end="error"
    fast = sweep(scene, frequencies=[2.0], amplitudes=[math.radians(35.0)], options=opts, progress=False)
    slow = sweep(scene, frequencies=[0.5], amplitudes=[math.radians(31.0)], options=opts, progress=False)
    assert fast.failed[0, 0] and slow.failed[0, 0]
    assert "stroke end" in fast.errors[0] and "stroke end" in slow.errors[0]
    assert fast.saturated[0, 0]
    assert fast.peak_current_A[0, 0] == pytest.approx(scene.motor.current_limit, rel=1e-9)
    assert not slow.saturated[0, 0]
    assert slow.peak_current_A[0, 0] < scene.motor.current_limit
    assert slow.peak_voltage_V[0, 0] < scene.motor.voltage_limit
    point = fast.to_dict()["points"][0]
    assert point["failed"] is True and point["saturated"] is True
    assert "saturated before failing" in fast.table()
    assert "saturated" not in slow.table().split("amplitude 31 deg")[1].split("FAILED")[0]


def _second_order(f, fn, zeta):
    s, wn = 2j * np.pi * np.asarray(f, dtype=float), 2 * np.pi * fn
    return wn**2 / (s**2 + 2 * zeta * wn * s + wn**2)


def test_summary_is_over_valid_points_and_the_phase_never_jumps_a_turn():
    """A loop whose resonance moved from 30 Hz (linear) to 25 Hz with 6 ms more delay
    (closed forms): its phase falls more than 180 deg behind the linear loop's between
    27 and 29 Hz. The phase and the difference are unwrapped along frequency (no 360 deg
    step between rows; the difference at each row is the closed form's unwrapped one), and
    the summary's largest difference is over the points that ran within the limits and
    settled, naming how many were saturated, unsettled or failed (a saturated row with a
    20 dB error, an unsettled row and a failed one would otherwise dominate it)."""
    from servo_toolkit.studies.sweep.compute import SweepResult
    f = np.array([5, 10, 20, 24, 26, 27, 28, 29, 31, 35, 40, 45.0])
    lin = _second_order(f, 30.0, 0.05)
    resp = (_second_order(f, 25.0, 0.05) * np.exp(-2j * np.pi * f * 0.006))[None, :]
    expected_dp = np.degrees(np.unwrap(np.angle(resp[0] / lin)))
    assert expected_dp.min() < -180  # the case the wrapped phase got wrong
    resp[0, 9] *= 10  # 35 Hz: saturated
    resp[0, 11] = complex(math.nan, math.nan)  # 45 Hz: failed
    change = np.zeros((1, f.size))
    change[0, 10] = 0.05  # 40 Hz: unsettled
    saturated = np.zeros((1, f.size), bool)
    saturated[0, 9] = True
    grid = np.unique(np.concatenate([np.geomspace(3.0, 70.0, 300), f]))  # as sweep() builds it
    res = SweepResult(scene="moved", study=None, frequencies_hz=f, amplitudes_rad=np.radians([1.0]), response=resp,
                      linear_response=lin, linear_grid_hz=grid, linear_grid_response=_second_order(grid, 30.0, 0.05),
                      settling_change=change, saturated=saturated, peak_current_A=np.ones((1, f.size)),
                      peak_voltage_V=np.ones((1, f.size)), errors=(None,) * 11 + ("non-finite at t = 1 s",),
                      reduced=False, left_out=(), options={}, plan=DwellPlan(), decay_rate=10.0)
    dp = res.phase_deg[0] - res.linear_phase_deg
    np.testing.assert_allclose(dp[:11], expected_dp[:11], atol=1e-9)
    table = res.table()
    rows = [line.split() for line in table.splitlines() if line[:9].strip().replace(".", "").isdigit()]
    phase = np.array([float(r[2]) for r in rows[:11]])
    assert np.all(np.abs(np.diff(phase)) < 90), phase
    assert all(abs(float(r[6])) < 270 for r in rows[:11])
    ok = np.ones(f.size, bool)
    ok[9:] = False
    gain_dev = np.abs(20 * np.log10(np.abs(resp[0] / lin)))
    dev = res.deviation()
    assert dev["max_gain_difference_dB"][0] == pytest.approx(gain_dev[ok].max(), rel=1e-9)
    assert dev["max_phase_difference_deg"][0] == pytest.approx(np.abs(expected_dp[ok]).max(), rel=1e-9)
    assert (dev["points_compared"], dev["points_saturated"], dev["points_unsettled"], dev["points_failed"]) == \
        ([9], [1], [1], [1])
    summary = table.splitlines()[-1]
    assert summary.startswith("largest difference from the linear loop, over the points that ran within the limits")
    assert (f"1 deg: {gain_dev[ok].max():.3f} dB / {np.abs(expected_dp[ok]).max():.2f} deg over 9 of 12 points "
            "(excluded: 1 saturated, 1 unsettled, 1 failed)") in summary
    assert "9 valid point(s), 1 saturated, 1 unsettled, 1 failed" in repr(res)
    assert res.to_dict()["points"][10]["unsettled"] is True


def test_multisine_phase_never_jumps_a_turn_and_its_summary_names_the_flags():
    """The same moved resonance as lines of a multisine run at two amplitudes, the larger
    saturated, plus a failed third: the phase difference is the closed form's unwrapped one
    (no 360 deg step between lines), and the summary names each amplitude's flag."""
    from servo_toolkit.studies.multisine import MultisineResult
    f = np.array([5, 10, 20, 24, 26, 27, 28, 29, 31, 35, 40.0])
    lin = _second_order(f, 30.0, 0.05)
    h = _second_order(f, 25.0, 0.05) * np.exp(-2j * np.pi * f * 0.006)
    resp = np.vstack([h, h, np.full(f.size, complex(math.nan, math.nan))])
    n = np.ones(3)
    res = MultisineResult(scene="moved", study=None, response_kind="closed_loop", frequency_hz=f,
                          amplitudes=np.radians([1.0, 2.0, 3.0]), response=resp, coherence=np.ones(resp.shape),
                          linear_response=lin, distortion_db=-60 * n, saturated=np.array([False, True, False]),
                          peak_current_A=n, peak_voltage_V=n, errors=(None, None, "non-finite at t = 1 s"),
                          logs=(None,) * 3, periods=4, settle=2, period_s=1.0, lines_asked=f.size)
    dp = res.phase_deg[0] - res.linear_phase_deg
    np.testing.assert_allclose(dp, np.degrees(np.unwrap(np.angle(h / lin))), atol=1e-9)
    assert np.all(np.abs(np.diff(res.phase_deg[0])) < 90)
    summary = res.table().splitlines()[-1]
    assert "1 deg: " in summary and "2 deg: " in summary and "(saturated: the current or voltage limit" in summary
    assert summary.endswith("3 deg: FAILED, no estimate")
    assert summary.count("saturated") == 1
