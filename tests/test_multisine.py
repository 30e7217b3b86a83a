"""The multisine sweep: a periodic Schroeder multisine through the compiled closed loop,
estimated period by period as frf estimates a rig's log; a loop whose nonlinearities are
taken out gives its linear model's response (closed loop and plant), and frf on the run's log
gives the sweep's own estimate."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from servo_toolkit import load_scene
from servo_toolkit.cli import main
from servo_toolkit.identify import read_data
from servo_toolkit.plant.linear import DEFAULT_STRUCTURAL_DAMPING
from servo_toolkit.sim import ModelOptions
from servo_toolkit.studies.multisine import MultisinePlan, multisine_sweep, schroeder

from .conftest import SCENES, closed_tags

EMA = SCENES / "ema_reference.toml"
BAND = (2.0, 50.0)


def linear_ema(path):
    """The reference EMA without what makes it nonlinear at small amplitude: lossless gears
    and screw (the loss switches with the power flow), no lash, no Coulomb friction, no hinge
    moment (with N(q) varying, a load moment adds a current proportional to the angle)."""
    text = EMA.read_text()
    for old, new in (("efficiency = 0.97", "efficiency = 1.0"), ("efficiency = 0.90", "efficiency = 1.0"),
                     ('backlash = "0.10 deg"', 'backlash = "0 deg"'), ('backlash = "10 um"', 'backlash = "0 um"'),
                     ('coulomb_friction = "0.02 N*m"', 'coulomb_friction = "0 N*m"'),
                     ('hinge_moment = "700 N*m"', 'hinge_moment = "0 N*m"')):
        assert old in text
        text = text.replace(old, new)
    path.write_text(text)
    return load_scene(path)


def test_schroeder_phases_keep_the_crest_factor_low():
    """24 equal lines: in phase their peak is 24 times a line's amplitude (a crest factor of
    24 / sqrt(12) = 6.9); Schroeder's phases bring it under 2, and the period's DFT holds
    the lines alone, all equal."""
    k = np.arange(1, 25)
    x = schroeder(k, 512)
    assert np.max(np.abs(x)) == pytest.approx(1.0)
    assert np.max(np.abs(x)) / np.sqrt(np.mean(x ** 2)) < 2.0
    spectrum = np.abs(np.fft.rfft(x))
    np.testing.assert_allclose(spectrum[k], spectrum[k].mean(), rtol=1e-12)
    others = np.setdiff1d(np.arange(spectrum.size), k)
    assert np.max(spectrum[others]) < 1e-12 * spectrum[k].mean()
    plan = MultisinePlan((2.0, 50.0), 12)
    assert plan.line_multiples()[0] == 1 and plan.line_multiples()[-1] == 25


@pytest.mark.parametrize("response", ["closed_loop", "plant"])
def test_a_linear_loop_gives_its_linear_response(tmp_path, response):
    """1 deg peak, 12 lines 2-50 Hz, encoder quantization off: within 0.2 dB and 2 deg of
    the linear closed loop (the design's, whose sample delay is a Pade approximation) and of
    the linear plant, on every line (coherence 1: the run is periodic)."""
    scene = linear_ema(tmp_path / "linear.toml")
    options = ModelOptions(damping_ratio=DEFAULT_STRUCTURAL_DAMPING, quantization=False, chain="two_mass")
    r = multisine_sweep(scene, band=BAND, lines=12, amplitudes=[math.radians(1.0)], periods=2, response=response,
                        options=options, progress=False)
    assert r.errors == (None,) and r.frequency_hz.size == 10 and not r.saturated[0]
    assert (r.coherence > 0.99).all()
    dev = r.deviation()
    assert dev["max_gain_difference_dB"][0] < 0.2 and dev["max_phase_difference_deg"][0] < 2.0, r.table()
    assert r.distortion_db[0] < -80
    d = r.to_dict()
    assert d["method"] == "multisine" and d["response"] == response and len(d["runs"][0]["points"]) == 10


def test_the_result_shows_itself_in_one_line_a_card_a_figure_and_json(ema):
    """A multisine result's views: a one-line repr naming the lines and the largest gain
    difference, a closed HTML card with its figure, the figure's gain, phase and coherence
    axes, and a JSON-ready dict."""
    import matplotlib
    matplotlib.use("Agg")
    scene, controller = ema
    r = multisine_sweep(scene, band=(2.0, 16.0), lines=4, amplitudes=[math.radians(1.0)], periods=1, settle=1,
                        controller=controller, progress=False)
    text = repr(r)
    assert text.startswith("<MultisineResult: ema_reference: multisine closed_loop, 4 lines 2-16 Hz")
    assert "\n" not in text and len(text) < 300 and "largest |dG|" in text
    html = r._repr_html_()
    assert html.count("<svg") == 1 and closed_tags(html)
    axes = r.plot()
    assert len(axes) == 3 and axes[0].get_xscale() == "log"
    d = json.loads(json.dumps(r.to_dict()))
    assert d["lines"] == 4 and len(d["runs"][0]["points"]) == 4


def test_the_sweep_and_frf_estimate_the_same_log_alike(tmp_path, capsys):
    """The sweep writes its response (the CSV fit reads) and its run's log; frf on that log
    finds the period, leaves the settling period out and gives the same response."""
    scene_path = tmp_path / "linear.toml"
    linear_ema(scene_path)
    out, log, plot = tmp_path / "frf.csv", tmp_path / "log.csv", tmp_path / "bode.png"
    args = ["sweep", str(scene_path), "--method", "multisine", "--band", "2:50", "--lines", "12", "--periods", "2",
            "--amplitude", "1 deg", "--response", "plant", "-o", str(out), "--log", str(log), "--plot", str(plot)]
    assert main(args + ["--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["settle_periods"] == 1 and d["periods"] == 2 and d["window"] == "periodic"
    swept = read_data(out)
    assert swept.averages == 2 and swept.points == d["lines"] and plot.stat().st_size > 0
    again = tmp_path / "again.csv"
    assert main(["frf", str(log), "--input", "current_A", "--output", "motor_speed_rad_s", "-o", str(again)]) == 0
    assert "rectangular window on each of 2 periods" in capsys.readouterr().out
    logged = read_data(again)
    np.testing.assert_allclose(logged.frequency_hz, swept.frequency_hz)
    np.testing.assert_allclose(logged.gain_db, swept.gain_db, atol=1e-6)
    np.testing.assert_allclose(logged.phase_deg, swept.phase_deg, atol=1e-6)


@pytest.mark.parametrize("args, where", [
    (["--band", "2:50"], "--band"),
    (["--method", "multisine"], "--band"),
    (["--method", "multisine", "--band", "50:2"], "--band"),
    (["--method", "multisine", "--band", "0.3333:10"], "--band"),
    (["--method", "multisine", "--band", "2:2000"], "--band"),
    (["--method", "multisine", "--band", "2:50", "--amplitude", "1 deg", "--amplitude", "2 deg", "-o", "x.csv"], "-o"),
    (["--method", "multisine", "--band", "2:50", "--log", "x.txt"], "--log"),
    (["--method", "multisine", "--band", "2:50", "--log", "x.csv", "-o", "x.csv"], "--log"),
])
def test_bad_multisine_options_are_one_line(tmp_path, capsys, monkeypatch, args, where):
    monkeypatch.chdir(tmp_path)
    scene = tmp_path / "scene.toml"
    scene.write_text(EMA.read_text().replace('frequencies = { start = "0.5 Hz", stop = "40 Hz", points = 30, '
                                             'spacing = "log" }', 'frequency = "8 Hz"'))
    assert main(["sweep", str(scene), *args]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and where in err, err
    assert not (tmp_path / "x.csv").exists()


def test_a_band_given_alone_gets_ten_lines_a_decade(tmp_path):
    """``--band 2:50`` without ``--lines`` on a scene whose sweep study has fewer frequencies:
    ten log-spaced lines per decade of the band (15 asked over 2-50 Hz, 12 distinct harmonics of 2 Hz),
    where the study's count gave a two-line multisine; a band from the study keeps its count,
    and ``lines`` given is taken as it is."""
    from servo_toolkit.studies.multisine.run import LINES_PER_DECADE, multisine_spec
    text = EMA.read_text(encoding="utf-8").replace(
        'frequencies = { start = "0.5 Hz", stop = "40 Hz", points = 30, spacing = "log" }',
        'frequencies = ["1 Hz", "8 Hz", "20 Hz"]')
    assert '"20 Hz"]' in text
    path = tmp_path / "three_lines.toml"
    path.write_text(text, encoding="utf-8")
    scene = load_scene(path)
    spec = multisine_spec(scene, "sweep", band=(2.0, 50.0))
    assert spec.plan.lines == math.ceil(LINES_PER_DECADE * math.log10(25.0)) + 1 == 15
    multiples = spec.plan.line_multiples()
    # the 15 asked for, merged where 2 Hz's harmonics are fewer (12 distinct, 2-50 Hz)
    assert multiples.size == 12 and multiples[0] == 1 and multiples[-1] == 25
    assert multisine_spec(scene, "sweep", band=(2.0, 50.0), lines=4).plan.lines == 4
    assert multisine_spec(scene, "sweep").plan.lines == 3  # the study's own band keeps its count
