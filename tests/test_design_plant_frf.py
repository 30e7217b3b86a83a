"""design --plant-frf: the drivetrain mode of a measured response places the notch, and the
loop on the measured plant is shown beside the model's."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from servo_toolkit.cli import main
from servo_toolkit.core.spectra import response_csv
from servo_toolkit.loop.measured import measured_loop, model_response
from servo_toolkit.loop.measured_mode import MIN_SHIFT, find_mode, plant_system, stiffened

from .conftest import SCENES

GEARED = str(SCENES.parent / "tests" / "scenes" / "geared_rotary.toml")
#: 100 points per decade from 0.5 to 500 Hz: neighbours 2.3 % apart, the grid's resolution
F = np.geomspace(0.5, 500.0, 301)
STEP = F[1] / F[0] - 1
#: the rig's drivetrain mode 15 % above the model's: its stiffness 1.15^2 times the scene's
SHIFT = 1.15


@pytest.fixture(scope="module")
def geared(memo):
    from servo_toolkit.loop import design
    from servo_toolkit.scene.loader import load_scene
    scene = load_scene(GEARED)
    return scene, design(scene, progress=False)


def _rig(r, shift=SHIFT, signal="motor_angle_rad"):
    """The noise-free response of the scene's plant with its stiffness times ``shift^2`` (the
    damping ratio kept) and its undamped anti-resonance (Hz)."""
    true = stiffened(r.parameters, shift ** 2)
    return model_response(replace(r, plant=plant_system(true)), 2 * np.pi * F, signal), true.antiresonance_hz


def _csv(path, h, coherence=None):
    coherence = np.ones_like(F) if coherence is None else coherence
    path.write_text(response_csv(F, 20 * np.log10(np.abs(h)), np.degrees(np.unwrap(np.angle(h))), coherence, 8))
    return str(path)


def test_the_mode_read_off_a_shifted_response_is_shifted_by_the_stiffness_ratio(geared):
    """A two-mass drivetrain's anti-resonance sqrt(K / J2) and resonance sqrt(K (1/J1 + 1/J2))
    both scale with sqrt(K): read alike off both responses, their ratio is the shift."""
    _, r = geared
    p = r.parameters
    for signal in ("motor_angle_rad", "motor_speed_rad_s", "output_angle_rad"):
        h, fa = _rig(r, signal=signal)
        mode = find_mode(F, h, np.ones_like(F), signal)
        assert mode.ratio_to(mode.model_reading(p)) == pytest.approx(SHIFT, rel=0.1 * STEP)
        assert mode.resonance_hz == pytest.approx(SHIFT * p.resonance_hz, rel=STEP)
        if signal.startswith("motor_"):
            assert mode.antiresonance_hz == pytest.approx(fa, rel=STEP)
        else:
            assert mode.antiresonance_hz is None  # the output shows the peak only


def test_a_flat_response_has_no_mode():
    h = 1 / (2j * np.pi * F) ** 2
    assert find_mode(F, h, np.ones_like(F), "motor_angle_rad") is None


def test_the_notch_lands_on_the_measured_anti_resonance(geared):
    scene, r = geared
    from servo_toolkit.loop import design
    assert r.motion.filter == "notch"
    assert r.motion.filter_params["wn"] / (2 * np.pi) == pytest.approx(r.parameters.antiresonance_hz, rel=1e-9)
    h, fa = _rig(r)
    got = design(scene, progress=False, measured_mode=find_mode(F, h, np.ones_like(F), "motor_angle_rad"))
    assert got.motion.filter == "notch"
    assert got.motion.filter_params["wn"] / (2 * np.pi) == pytest.approx(fa, rel=0.1 * STEP)
    note = next(n for n in got.notes if n.startswith("measured anti-resonance"))
    wn_hz = got.motion.filter_params["wn"] / (2 * np.pi)
    assert f"the notch on {wn_hz:.4g} Hz instead of {r.parameters.antiresonance_hz:.4g} Hz" in note
    # the model's own figures: the scene model, not the shifted one
    assert got.parameters == r.parameters


def test_an_explicit_filter_keeps_the_models_placement(geared):
    scene, r = geared
    from servo_toolkit.loop import design
    h, _ = _rig(r)
    got = design(scene, progress=False, resonance_filter="notch",
                 measured_mode=find_mode(F, h, np.ones_like(F), "motor_angle_rad"))
    assert got.motion.filter_params["wn"] / (2 * np.pi) == pytest.approx(r.parameters.antiresonance_hz, rel=1e-9)
    assert any("--filter notch keeps the model's placement" in n for n in got.notes)


def test_the_loop_on_a_shifted_response_is_the_true_plants_loop(geared, tmp_path):
    """The output's transmission, which a motor-side measurement does not see, follows the
    measured mode: the loop on the shifted plant's response has that plant's margins."""
    from servo_toolkit.loop.design import evaluate
    from servo_toolkit.scene.loader import load_scene
    scene, r = geared
    stiff = tmp_path / "stiff.toml"
    stiff.write_text(open(GEARED).read().replace('"1.5e4 N*m/rad"', f'"{1.5e4 * SHIFT ** 2!r} N*m/rad"'))
    truth = evaluate(load_scene(stiff), r.controller, stroke_points=0).margins
    h, _ = _rig(r)
    m = measured_loop(r, scene.motor, F, h, np.ones_like(F))
    assert m.transmission_ratio == pytest.approx(SHIFT, rel=0.1 * STEP)
    assert m.gain_margin_db == pytest.approx(truth.gain_margin_db, abs=0.2)
    assert m.phase_margin_deg == pytest.approx(truth.phase_margin_deg, abs=0.5)
    assert any("moved alike" in n for n in m.notes())


def test_design_prints_the_measured_margins_beside_the_models(geared, tmp_path, capsys):
    scene, r = geared
    h, fa = _rig(r)
    path = _csv(tmp_path / "frf.csv", h)
    assert main(["design", GEARED, "--linear-only", "--plant-frf", path]) in (0, 1)
    out = capsys.readouterr().out
    assert "measured plant" in out and "gain margin [dB]" in out and "phase margin [deg]" in out
    assert "measured anti-resonance" in out and "verdict: the model's" in out
    assert main(["design", GEARED, "--linear-only", "--plant-frf", path, "--json"]) in (0, 1)
    d = json.loads(capsys.readouterr().out)
    mp = d["measured_plant"]
    assert mp["mode"]["antiresonance_hz"] == pytest.approx(fa, rel=STEP)
    assert {"phase_margin_deg", "gain_margin_db", "model"} <= set(mp)


def test_design_margins_on_the_models_own_response_equal_the_models(geared, tmp_path, capsys):
    _, r = geared
    path = _csv(tmp_path / "frf.csv", model_response(r, 2 * np.pi * F, "motor_angle_rad"))
    assert main(["design", GEARED, "--linear-only", "--plant-frf", path, "--json"]) in (0, 1)
    d = json.loads(capsys.readouterr().out)
    mp = d["measured_plant"]
    assert d["margins"]["gain_margin_db"] == pytest.approx(r.margins.gain_margin_db, abs=1e-9)  # the model's design
    assert mp["gain_margin_db"] == pytest.approx(r.margins.gain_margin_db, abs=0.1)
    assert mp["phase_margin_deg"] == pytest.approx(r.margins.phase_margin_deg, abs=0.5)
    assert mp["transmission_ratio"] == pytest.approx(1.0, abs=1e-6)  # the file rounds to 8 digits
    assert any(f"within {100 * MIN_SHIFT:g} %" in n for n in d["notes"])


def test_design_refuses_a_bad_file_before_designing(tmp_path, capsys):
    path = tmp_path / "frf.csv"
    path.write_text("frequency_hz,gain,phase_deg\n1,0,0\n2,0,0\n")
    assert main(["design", GEARED, "--linear-only", "--plant-frf", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--plant-frf" in err[0]


def test_a_reversed_sign_is_named_in_one_note_and_decides_no_stability(geared):
    from servo_toolkit.studies.gate import measured_rows
    scene, r = geared
    w = 2 * np.pi * F
    shifted, _ = _rig(r)
    cases = ((shifted, "motor_angle_rad", False),  # 15 % off: the phase differs about the mode only
             (model_response(r, w, "motor_angle_rad"), "motor_angle_rad", False),
             (-shifted, "motor_angle_rad", True),
             (-model_response(r, w, "motor_speed_rad_s"), "motor_speed_rad_s", True))
    for response, signal, reversed_ in cases:
        m = measured_loop(r, scene.motor, F, response, np.ones_like(F), signal=signal)
        sign = [n for n in m.notes() if n.startswith("SIGN")]
        assert m.sign_reversed is reversed_ and len(sign) == int(reversed_), signal
        if reversed_:
            assert "reversed sensor or drive sign" in sign[0] and "180 deg" in sign[0]
            stable = next(x for x in measured_rows(m, r.requirements) if x.id == "measured_closed_loop_stable")
            assert stable.status == "unavailable" and "sign" in stable.detail


@pytest.mark.parametrize("command", ["check", "design"])
def test_check_and_design_print_the_reversed_sign_once(geared, tmp_path, capsys, command):
    _, r = geared
    h, _ = _rig(r)
    path = _csv(tmp_path / "frf.csv", -h)
    main([command, GEARED, "--linear-only", "--plant-frf", path])
    out = capsys.readouterr().out
    assert sum(line.strip().startswith("note: SIGN:") for line in out.splitlines()) == 1
