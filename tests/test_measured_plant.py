"""check --plant-frf: the designed loop closed on a measured plant response."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from servo_toolkit.cli import main
from servo_toolkit.core.spectra import response_csv
from servo_toolkit.loop.crossings import response_of
from servo_toolkit.loop.measured import loop_on, measured_loop, model_response, sampled_crossings
from servo_toolkit.studies.gate import measured_rows

from .conftest import SCENES

EMA = str(SCENES / "ema_reference.toml")
#: 100 points per decade from 0.5 to 500 Hz (2.3 % between neighbours)
F = np.geomspace(0.5, 500.0, 301)


@pytest.fixture(scope="module")
def designed(memo):
    from servo_toolkit.loop import design
    from servo_toolkit.scene.loader import load_scene
    scene = load_scene(EMA)
    return scene, design(scene, progress=False)


def _csv(path, f, h, coherence):
    path.write_text(response_csv(f, 20 * np.log10(np.abs(h)), np.degrees(np.unwrap(np.angle(h))), coherence, 8))
    return str(path)


def test_the_loop_on_the_models_own_response_is_the_models_loop(designed):
    scene, r = designed
    w = 2 * np.pi * F
    for signal in ("motor_angle_rad", "motor_speed_rad_s", "output_angle_rad"):
        loop, closed = loop_on(r, scene.motor, w, model_response(r, w, signal), signal)
        np.testing.assert_allclose(loop, response_of(r.loop)(1j * w), rtol=1e-8)
        np.testing.assert_allclose(closed, response_of(r.closed_loop)(1j * w), rtol=1e-8)


def test_crossings_between_points_match_a_closed_form():
    """L = 2 / (jw + 1)^3: phase crossing at w = sqrt(3), |L| = 1/4 there (GM 12.04 dB);
    gain crossing at w = sqrt(2^(2/3) - 1), PM = 180 - 3 atan(w)."""
    w = np.geomspace(0.05, 50, 301)
    gains, phases = sampled_crossings(w / (2 * np.pi), 2 / (1j * w + 1) ** 3, np.ones_like(w))
    wgc = math.sqrt(2 ** (2 / 3) - 1)
    assert len(gains) == 1 and len(phases) == 1
    assert gains[0].margin == pytest.approx(180 - 3 * math.degrees(math.atan(wgc)), abs=0.5)
    assert gains[0].low_hz <= wgc / (2 * math.pi) <= gains[0].high_hz
    assert phases[0].margin == pytest.approx(20 * math.log10(4), abs=0.1)
    assert phases[0].low_hz <= math.sqrt(3) / (2 * math.pi) <= phases[0].high_hz


def test_margins_on_a_noise_free_model_response_equal_the_models(designed):
    scene, r = designed
    m = measured_loop(r, scene.motor, F, model_response(r, 2 * np.pi * F, "motor_angle_rad"), np.ones_like(F),
                      required_bandwidth_hz=8.0)
    mg = r.margins
    assert m.phase_margin_deg == pytest.approx(mg.phase_margin_deg, abs=0.5)
    assert m.gain_margin_db == pytest.approx(mg.gain_margin_db, abs=0.1)
    assert m.sensitivity_peak[0] == pytest.approx(mg.sensitivity_peak_db, abs=0.1)
    bw, poor, _ = m.bandwidth
    assert not poor and bw == pytest.approx(mg.bandwidth_hz, rel=0.025)
    assert m.closed_loop_rhp_poles == 0
    assert all(b[4] < 1e-6 and b[6] < 1e-6 for b in m.bands)  # no mismatch with itself
    rows = measured_rows(m, r.requirements)
    assert {x.id for x in rows} >= {"measured_closed_loop_stable", "measured_gain_margin", "measured_phase_margin",
                                    "measured_sensitivity_peak", "measured_bandwidth"}
    assert all(x.passed for x in rows)


def _noisy(r, coherence, averages=8, seed=3):
    """The model's response with the random error of an H1 estimate at ``coherence`` from
    ``averages`` spectra (relative sd sqrt((1 - coh) / (2 n coh)) in gain and phase)."""
    from servo_toolkit.identify.noise import coherence_sd
    h = model_response(r, 2 * np.pi * F, "motor_angle_rad")
    sd = coherence_sd(coherence, averages)
    rng = np.random.default_rng(seed)
    return h * np.exp(sd * rng.standard_normal(F.size) + 1j * sd * rng.standard_normal(F.size))


def test_poor_coherence_far_from_the_crossover_is_marked_and_decides_nothing(designed):
    scene, r = designed
    coh = np.where(F > 100, 0.2, 0.999)
    m = measured_loop(r, scene.motor, F, _noisy(r, coh), coh, required_bandwidth_hz=8.0)
    assert int(m.poor.sum()) == int((F > 100).sum())
    rows = measured_rows(m, r.requirements)
    assert all(x.passed for x in rows), [x.message() for x in rows if not x.passed]
    assert m.to_dict()["poor_points"] == int((F > 100).sum())


def test_poor_coherence_at_the_crossover_leaves_the_margin_without_a_verdict(designed):
    scene, r = designed
    wgc = r.margins.gain_crossover_hz[0]
    coh = np.where(np.abs(np.log10(F / wgc)) < 0.1, 0.3, 0.999)
    m = measured_loop(r, scene.motor, F, _noisy(r, coh), coh, required_bandwidth_hz=8.0)
    assert all(c.poor for c in m.gain_crossings)
    pm = next(x for x in measured_rows(m, r.requirements) if x.id == "measured_phase_margin")
    assert pm.status == "unavailable" and not pm.passed and "poor coherence" in pm.detail


def test_a_spurious_peak_at_poor_coherence_does_not_fail_ms(designed):
    scene, r = designed
    h = model_response(r, 2 * np.pi * F, "motor_angle_rad")
    coh = np.ones_like(F)
    j = int(np.argmin(np.abs(F - 200)))
    # L is a bilinear function of the response, 1/L = p/x + q: the x putting L at -0.95 (|S| 26 dB)
    x = h[j] * np.array([1.0, 2.0])
    inv = 1 / loop_on(r, scene.motor, 2 * np.pi * F[[j, j]], x, "motor_angle_rad")[0]
    p = (inv[0] - inv[1]) / (1 / x[0] - 1 / x[1])
    h[j] = p / (1 / -0.95 - (inv[0] - p / x[0]))
    coh[j] = 0.1
    m = measured_loop(r, scene.motor, F, h, coh, required_bandwidth_hz=8.0)
    ms = next(x for x in measured_rows(m, r.requirements) if x.id == "measured_sensitivity_peak")
    assert ms.status == "unavailable" and "poor coherence" in ms.detail
    coh[j] = 1.0
    m = measured_loop(r, scene.motor, F, h, coh, required_bandwidth_hz=8.0)
    ms = next(x for x in measured_rows(m, r.requirements) if x.id == "measured_sensitivity_peak")
    assert ms.status == "fail"


def test_check_json_carries_the_measured_rows(designed, tmp_path, capsys):
    _, r = designed
    path = _csv(tmp_path / "frf.csv", F, model_response(r, 2 * np.pi * F, "motor_angle_rad"), np.ones_like(F))
    assert main(["check", EMA, "--linear-only", "--plant-frf", path, "--json"]) == 0
    out = json.loads(capsys.readouterr().out)["scenes"][0]
    ids = [x["id"] for x in out["rows"]]
    assert "measured_phase_margin" in ids and "phase_margin" in ids
    assert out["measured_plant"]["phase_margin_deg"] == pytest.approx(r.margins.phase_margin_deg, abs=0.5)
    assert len(out["measured_plant"]["points_detail"]) == F.size


@pytest.mark.parametrize("case", ["missing", "time", "header"])
def test_bad_files_exit_2_with_one_line_before_any_design(case, tmp_path, capsys):
    path = tmp_path / "frf.csv"
    if case == "time":
        path.write_text("time_s,voltage_V,current_A,motor_angle_rad,output_angle_rad\n0,0,0,0,0\n0.1,0,0,0,0\n")
    elif case == "header":
        path.write_text("frequency_hz,gain,phase_deg\n1,0,0\n2,0,0\n")
    assert main(["check", EMA, "--linear-only", "--plant-frf", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--plant-frf" in err[0]


def test_a_response_short_of_the_crossover_exits_2_naming_the_rule(designed, tmp_path, capsys):
    _, r = designed
    f = np.geomspace(50, 500, 50)
    path = _csv(tmp_path / "frf.csv", f, model_response(r, 2 * np.pi * f, "motor_angle_rad"), np.ones_like(f))
    assert main(["check", EMA, "--linear-only", "--plant-frf", path]) == 2
    err = capsys.readouterr().err
    assert "--plant-frf" in err and "gain crossover" in err


@pytest.mark.parametrize("header", ["time_s,current_excitation_A,current_A,voltage_V,motor_angle_rad",
                                    "t_s,reference_angle_rad,output_angle_rad",
                                    "time_s,voltage_V,current_A,motor_angle_rad,output_angle_rad"])
def test_a_time_log_given_for_the_response_is_named_a_time_log(header, tmp_path, capsys):
    """A rig's log (what excite -o writes, what frf reads) or a trace is not a frequency
    response: the line says so and names frf, not a column rule of another kind of file."""
    path = tmp_path / "log.csv"
    n = len(header.split(","))
    path.write_text("# servo-toolkit excite: a log\n# period_samples: 2\n" + header + "\n"
                    + "".join(",".join([f"{k * 1e-3:g}"] + ["0"] * (n - 1)) + "\n" for k in range(4)))
    assert main(["check", EMA, "--linear-only", "--plant-frf", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--plant-frf: is a drive's time log" in err[0] and "frf LOG -o" in err[0], err


def test_a_check_on_a_measured_plant_imports_no_python_control(designed, tmp_path):
    """``check --plant-frf`` closes the loop on the toolkit's own blocks (the plant, the
    sampling delay, the design's loop): a new process running it loads neither
    python-control nor matplotlib, and reading the measurement loads none of the fit's
    machinery (scipy.signal)."""
    import subprocess
    import sys

    from .conftest import ROOT
    from .test_first_run import _FIRST_IMPORTER
    _, r = designed
    path = _csv(tmp_path / "frf.csv", F, model_response(r, 2 * np.pi * F, "motor_angle_rad"), np.ones_like(F))
    proc = subprocess.run([sys.executable, "-c", _FIRST_IMPORTER, "check", EMA, "--linear-only", "--plant-frf", path],
                          capture_output=True, text=True, timeout=600, cwd=ROOT)
    got = json.loads(proc.stdout.strip().splitlines()[-1])
    assert got["code"] == 0 and got["importer"] is None
    assert got["libraries"] == []  # neither python-control, matplotlib nor scipy.signal
