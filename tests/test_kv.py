"""Kv dynamic-load studies (seed 000) and the ``kv`` command."""

import json
import math

import numpy as np
import pytest

from servo_toolkit.cli import main
from servo_toolkit.errors import SceneError
from servo_toolkit.scene.loader import load_scene
from servo_toolkit.studies.kv.study import kv_studies, kv_study

from .conftest import SCENES, build, variant

EMA = str(SCENES / "ema_reference.toml")
SEED_KV_MOTOR = [1.0, 1.11, 1.25, 1.34]        # seed 000 table 2, inertias 0, 1, 2, 4 kg*m^2
SEED_KV_SCREW = [1.0, 1.13, 1.33, 1.55]        # seed 000 table 3


@pytest.fixture(scope="module")
def ema():
    return load_scene(EMA)


@pytest.fixture(scope="module")
def stroke(ema):
    return kv_study(ema, "kv_stroke", samples_per_period=800, progress=False)


def test_kv_is_one_at_zero_inertia_and_rises_with_inertia(stroke):
    cases = stroke.cases
    assert [c.load_inertia for c in cases] == [0.0, 1.0, 2.0, 4.0]
    assert cases[0].kv_motor == 1.0 and cases[0].kv_screw == 1.0 and cases[0].kv_rod == 1.0
    for a, b in zip(cases, cases[1:]):
        assert b.kv_motor > a.kv_motor and b.kv_screw > a.kv_screw
        assert b.peak_motor_torque > a.peak_motor_torque


def test_trend_matches_the_seed_tables(stroke):
    """Seed tables 2-3: both factors rise, the screw's faster than the motor's (the motor's
    zero-inertia peak already carries the rotor and gear inertias). Values differ: the seed's
    geometry and static load are not printed."""
    for c, seed_m, seed_s in zip(stroke.cases[1:], SEED_KV_MOTOR[1:], SEED_KV_SCREW[1:]):
        assert (c.kv_screw > c.kv_motor) == (seed_s > seed_m)
    assert all(1.0 < c.kv_motor < 2.0 for c in stroke.cases[1:])


def test_8hz_study_rises_with_amplitude_and_reads_output_amplitudes(ema):
    r = kv_study(ema, "kv_8hz", samples_per_period=400, progress=False)
    assert [round(math.degrees(a), 9) for a in r.amplitudes] == [2.0, 3.0, 4.0]
    loaded = [c for c in r.cases if c.load_inertia == 2.3]
    assert len(loaded) == 3 and all(c.kv_motor > 1 for c in loaded)
    assert loaded[0].kv_motor < loaded[1].kv_motor < loaded[2].kv_motor    # seed table 4 trend
    seed_reading = r.kv_against_first()
    assert seed_reading[0] == 1.0 and seed_reading[-1] > loaded[-1].kv_motor


def test_literal_motor_gear_reading_gives_no_dynamic_effect(ema_dict):
    """2 deg at the motor gear is ~0.015 deg at the output: Kv stays within 0.5 % of 1,
    far from the seed's 1.05 - the reason the default reads the amplitude at the output."""
    data = variant(ema_dict, studies__kv_8hz__amplitude_at="motor")
    r = kv_study(build(data), "kv_8hz", samples_per_period=400, progress=False)
    assert all(abs(c.kv_motor - 1) < 5e-3 for c in r.cases)
    assert math.degrees(r.cases[0].amplitude) == pytest.approx(2 / 138.858, rel=1e-3)


def test_motor_gear_amplitudes_reach_simulations_divided_by_the_ratio(ema_dict):
    """A kv study read at the motor gear moves the output by A / N: the time runs of the
    study (simulate, accuracy via run_spec; reduce via time_points) command that, not A."""
    from servo_toolkit.studies.reduce import time_points
    from servo_toolkit.studies.time.reference import run_spec
    scene = build(variant(ema_dict, studies__kv_8hz__amplitude_at="motor"))
    n0 = float(scene.drivetrain.ratio([scene.drivetrain.mid_stroke])[0][0])
    expected = [math.radians(a) / n0 for a in (2.0, 3.0, 4.0)]
    assert run_spec(scene, "kv_8hz")[0].amplitude == pytest.approx(expected[0], rel=1e-12)
    freqs, amps = time_points(scene.study("kv_8hz"), scene)
    assert list(freqs) == [8.0] and amps == pytest.approx(expected, rel=1e-12)
    plain = build(ema_dict)  # read at the output (the default): unchanged
    assert run_spec(plain, "kv_8hz")[0].amplitude == pytest.approx(math.radians(2.0), rel=1e-12)


LINEAR_THREE_STAGE = """
name = "linear_three_stage"
[motor]
kind = "dc"
resistance = "0.5 ohm"
torque_constant = "0.2 N*m/A"
back_emf_constant = "0.2 V*s/rad"
rotor_inertia = "2.0e-4 kg*m^2"
voltage_limit = "270 V"
current_limit = "60 A"
[[drivetrain]]
kind = "gear"
ratio = 3.0
[[drivetrain]]
kind = "gear"
ratio = 2.0
[[drivetrain]]
kind = "ball_screw"
lead = "5 mm"
screw_inertia = "1.3e-5 kg*m^2"
nut_mass = "0.6 kg"
[load]
inertia = "10 kg"
hinge_moment = "500 N"
[sensors]
sample_time = "0.1 ms"
motor_encoder_counts = 4096
output_scale_resolution = "1 um"
[studies.lin]
kind = "kv"
amplitude = "2 mm"
frequency = "5 Hz"
load_inertias = ["0 kg", "10 kg", "40 kg"]
"""


def test_constant_ratio_kv_matches_the_hand_computation(tmp_path):
    """Lossless constant-ratio chain, sine x = A sin(w t) against a constant force F: the
    peak motor torque is (M A w^2 + F) / N with M = J_m N^2 + J_s N_s^2 + m_nut + m_load,
    the peak screw thrust (m_nut + m_load) A w^2 + F (Kv = ratio to m_load = 0)."""
    path = tmp_path / "lin.toml"
    path.write_text(LINEAR_THREE_STAGE)
    r = kv_study(load_scene(path), "lin", losses="none", samples_per_period=400, progress=False)
    n_s = 2 * math.pi / 5e-3
    n = 6 * n_s
    aw2 = 2e-3 * (2 * math.pi * 5) ** 2
    torque = [((2e-4 * n ** 2 + 1.3e-5 * n_s ** 2 + 0.6 + m) * aw2 + 500) / n for m in (0, 10, 40)]
    thrust = [(0.6 + m) * aw2 + 500 for m in (0, 10, 40)]
    assert [c.peak_motor_torque for c in r.cases] == pytest.approx(torque, rel=1e-9)
    assert [c.peak_screw_thrust for c in r.cases] == pytest.approx(thrust, rel=1e-9)
    assert [c.kv_screw for c in r.cases] == pytest.approx([t / thrust[0] for t in thrust], rel=1e-9)


def test_a_motor_gear_amplitude_is_an_angle_also_for_an_output_travel(tmp_path):
    """Read at the motor gear, the amplitude is the gear's angle: 2 deg on the linear chain
    (N = 6 * 2 pi / 5 mm rad/m) moves the nut 2 deg / N = 4.63 um; a length there is refused
    naming the key, and the stroke message is in mm."""
    path = tmp_path / "lin.toml"
    path.write_text(LINEAR_THREE_STAGE.replace('amplitude = "2 mm"', 'amplitude = "2 deg"\namplitude_at = "motor"'))
    r = kv_study(load_scene(path), "lin", losses="none", samples_per_period=40, progress=False)
    assert r.cases[0].amplitude == pytest.approx(math.radians(2) / (6 * 2 * math.pi / 5e-3), rel=1e-12)
    path.write_text(LINEAR_THREE_STAGE.replace('amplitude = "2 mm"', 'amplitude = "2 mm"\namplitude_at = "motor"'))
    with pytest.raises(SceneError, match=r"studies\.lin\.amplitude: .*rad"):
        load_scene(path)
    path.write_text(LINEAR_THREE_STAGE.replace('amplitude = "2 mm"', 'amplitude = "900 rad"\namplitude_at = "motor"'))
    with pytest.raises(SceneError, match=r"studies\.lin\.amplitude: the motion -119.36\d* mm\.\.119.36\d* mm leaves "
                                         r"the stroke -50 mm\.\.50 mm"):
        kv_study(load_scene(path), "lin", losses="none", samples_per_period=40, progress=False)


def test_a_motion_near_or_above_the_mode_is_flagged(tmp_path):
    """With the two gear stages compliant (1000 and 5000 N*m/rad on their output shafts) the
    chain is a two-mass system at the nut: rotor 2e-4 kg*m^2 * N^2 against the screw and
    the masses, spring 1/(1/(k1 (2 N_s)^2) + 1/(k2 N_s^2)): its mode sqrt(K (1/J1 + 1/J2))
    is 1.69 kHz. A motion above it, or within a factor 2, gets a warning that the rigid Kv
    does not hold; one far below it does not."""
    from servo_toolkit.studies.kv.study import default_kv_study
    text = LINEAR_THREE_STAGE.replace('ratio = 3.0', 'ratio = 3.0\ntorsional_stiffness = "1000 N*m/rad"')
    path = tmp_path / "lin.toml"
    path.write_text(text.replace('ratio = 2.0', 'ratio = 2.0\ntorsional_stiffness = "5000 N*m/rad"'))
    scene = load_scene(path)
    n_s = 2 * math.pi / 5e-3
    k = 1 / (1 / (1000 * (2 * n_s) ** 2) + 1 / (5000 * n_s ** 2))
    f_n = math.sqrt(k * (1 / (2e-4 * (6 * n_s) ** 2) + 1 / (1.3e-5 * n_s ** 2 + 10.6))) / (2 * math.pi)
    assert f_n == pytest.approx(1693, rel=1e-3)

    def warnings(f):
        r = kv_study(scene, default_kv_study(scene, 1e-6, f), losses="none", samples_per_period=40, progress=False)
        return [n for n in r.notes if n.startswith("warning")]
    assert not warnings(0.4 * f_n)
    assert "within a factor 2 of the drivetrain's lowest mode (1.69e+03 Hz)" in warnings(0.6 * f_n)[0]
    assert "above the drivetrain's lowest mode" in warnings(2.0 * f_n)[0]


def test_zero_reference_is_added_and_bad_studies_name_their_key(ema_dict):
    data = variant(ema_dict, studies__kv_stroke__load_inertias=["2 kg*m^2"])
    r = kv_study(build(data), "kv_stroke", samples_per_period=400, progress=False)
    assert [c.load_inertia for c in r.cases] == [0.0, 2.0]
    assert any("added" in n for n in r.notes)
    with pytest.raises(SceneError, match="studies.kv_stroke.trajectory"):
        kv_study(build(variant(ema_dict, studies__kv_stroke__trajectory="ramp")), "kv_stroke")
    with pytest.raises(SceneError, match="studies.kv_stroke.amplitude.*stroke"):
        kv_study(build(variant(ema_dict, studies__kv_stroke__amplitude="40 deg")), "kv_stroke")
    with pytest.raises(SceneError, match="studies.sweep.kind"):
        kv_study(build(ema_dict), "sweep")


def test_every_kv_study_runs(ema):
    assert [r.study for r in kv_studies(ema, samples_per_period=200, progress=False)] == ["kv_stroke", "kv_8hz"]


def test_result_table_dict_and_plot(stroke):
    import matplotlib
    matplotlib.use("Agg")
    d = stroke.to_dict()
    assert json.loads(json.dumps(d))["cases"][3]["load_inertia_kg_m2"] == 4.0
    assert "Kv motor" in stroke.table() and "screw thrust" in stroke.table()
    assert stroke.plot().get_ylabel() == "Kv"


def test_cli_json_cases(capsys):
    assert main(["kv", EMA, "--study", "kv_stroke", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    keys = {"load_inertia_kg_m2", "amplitude_deg", "peak_motor_torque_Nm", "peak_screw_thrust_N",
            "kv_motor", "kv_screw"}
    assert len(out["cases"]) == 4 and all(keys <= set(c) for c in out["cases"])
    assert out["cases"][0]["kv_motor"] == 1.0 and out["cases"][0]["amplitude_deg"] == pytest.approx(30)


def test_cli_loss_model_option(capsys):
    peaks = {}
    for losses in ("directional", "none"):
        assert main(["kv", EMA, "--study", "kv_stroke", "--losses", losses, "--json"]) == 0
        peaks[losses] = [c["peak_motor_torque_Nm"] for c in json.loads(capsys.readouterr().out)["cases"]]
    assert all(a > b for a, b in zip(peaks["directional"], peaks["none"]))


def test_cli_text_and_errors(capsys):
    assert main(["kv", EMA]) == 0
    text = capsys.readouterr().out
    assert "kv_stroke" in text and "kv_8hz" in text and "Kv motor" in text
    # a scene without a kv study runs seed 000's 8 Hz, 2 deg sine at the design's operating point
    assert main(["kv", str(SCENES / "cam_follower.toml"), "--json"]) == 0
    case = json.loads(capsys.readouterr().out)["cases"][0]
    assert case["amplitude_deg"] == pytest.approx(2.0) and case["frequency_hz"] == 8.0
    assert main(["kv", EMA, "--study", "kv_8hz", "--amplitude", "1 deg"]) == 2
    assert "--study" in capsys.readouterr().err
    assert main(["kv", EMA, "--study", "nope"]) == 2
    assert "studies.nope" in capsys.readouterr().err


def test_cli_dispatches_to_a_mechanism_module(monkeypatch, capsys):
    import servo_toolkit.studies.run as run
    monkeypatch.setattr(run, "handles", lambda scene, study: getattr(study, "name", study) == "sweep")
    monkeypatch.setattr(run, "run_mechanism", lambda scene, study, **options: {"cases": [{"from": "mechanisms"}]})
    assert main(["kv", EMA, "--study", "sweep", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["cases"] == [{"from": "mechanisms", "study": "sweep"}]


def test_notes_name_the_rigid_model_and_what_the_compliance_would_change(ema, capsys):
    """The loads come from rigid inverse dynamics; the note says so, and its number is the
    change of the inertial motor torque that the drivetrain compliance would make. Checked
    against the undamped two-mass equations solved here for a prescribed output sine:
    -w^2 J1 P = T - K (P - Q), -w^2 J2 Q = K (P - Q)."""
    from servo_toolkit.plant.linear import plant_parameters
    r = kv_study(ema, "kv_8hz", samples_per_period=200, progress=False)
    note = next(n for n in r.notes if n.startswith("model:"))
    for word in ("rigid inverse dynamics", "compliance", "backlash", "inductance", "Hz"):
        assert word in note
    w = 2 * math.pi * 8.0
    effects = []
    for j in (0.0, 2.3):
        p = plant_parameters(ema).with_variation(load_inertia_delta=j - ema.load.inertia)
        J1, J2, K = p.J1, p.J2, p.K
        # unknowns P (motor-side angle) and T (torque at the output) for Q = 1
        a = [[-w**2 * J1 + K, -1.0], [K, 0.0]]
        P, T = np.linalg.solve(a, [K * 1.0, (K - w**2 * J2) * 1.0])
        effects.append(1 - abs(T) / (w**2 * (J1 + J2)))
    assert r.compliance_effect == pytest.approx(max(effects), rel=1e-9)
    assert 0.05 < r.compliance_effect < 0.2      # 8 Hz against a ~24 Hz mode: not negligible
    assert r.to_dict()["compliance_effect_relative"] == r.compliance_effect
    assert main(["kv", EMA, "--study", "kv_8hz", "--json"]) == 0
    notes = json.loads(capsys.readouterr().out)["studies"][0]["notes"]
    assert any("rigid inverse dynamics" in n for n in notes)
    assert main(["kv", EMA, "--study", "kv_8hz"]) == 0
    assert "note: model: rigid inverse dynamics" in capsys.readouterr().out


def test_cli_runs_the_built_in_roller_screw_studies(capsys):
    """``kv --study efficiency`` on a roller-screw scene (no [studies] table) runs the
    built-in study instead of 'no such study'; an unknown name lists the built-in ones."""
    scene = str(SCENES / "roller_screw_two_stage.toml")
    for name in ("efficiency", "carrier_step"):
        assert main(["kv", scene, "--study", name, "--json"]) == 0, capsys.readouterr().err
        assert json.loads(capsys.readouterr().out)["studies"]
    assert main(["kv", scene, "--study", "nope"]) == 2
    err = capsys.readouterr().err
    assert "studies.nope" in err and "efficiency" in err and "carrier_step" in err
