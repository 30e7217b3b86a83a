"""No text beside a verdict contradicts it: a robust design's note claims only the rows it
judged, the variant counts agree with the rows, ``design`` names the requirements it leaves
to ``check`` and computes its large-signal rows as ``check`` does, and check's row lines
keep their columns for long row IDs."""

from __future__ import annotations

import json
from dataclasses import replace
from types import SimpleNamespace

import pytest

import servo_toolkit as st
from servo_toolkit.cli import main

from .carriage_scene import carriage_scene
from .conftest import SCENES

#: the carriage with lash, the motor's and the carriage's friction, and time requirements set
LINEAR_EMA = carriage_scene("linear_ema", lash=True, load_friction=True, motor_friction=True, requirements='''
bandwidth = "15 Hz"
step_amplitude = "1 mm"
max_overshoot = "10 %"
max_settling_time = "150 ms"
sine_amplitude = "0.5 mm"
max_tracking_error = "0.25 mm"
''')


@pytest.fixture(scope="module")
def linear_ema(tmp_path_factory):
    path = tmp_path_factory.mktemp("linear_ema") / "linear_ema.toml"
    path.write_text(LINEAR_EMA)
    return path


def test_a_robust_design_note_claims_only_the_rows_it_judged():
    """The note of a robust design that misses nothing names its linear-loop and robustness
    rows, never "every requirement": check's large-signal, time and sizing rows come later."""
    from servo_toolkit.loop.design import _failure_notes
    met = SimpleNamespace(name="bandwidth", passed=True, reason="")
    result = SimpleNamespace(requirements=[met, replace_name(met, "gain_margin")],
                             robustness=SimpleNamespace(failures=[], worst={}, count=196,
                                                        requirements=[met, met, met, met]))
    (note,) = _failure_notes(result)
    assert "every requirement" not in note
    assert "2 linear-loop requirements" in note and "4 robustness requirements" in note
    assert "196 variants" in note and "judged apart" in note


def replace_name(ns, name):
    return SimpleNamespace(**{**vars(ns), "name": name})


def test_grid_count_in_words_is_the_count_sampled():
    from servo_toolkit.loop.sampling import sample_variants, variant_count_text
    ranges = {"load_inertia": (0.02, 0.1), "stiffness": (0.7, 1.3)}
    assert variant_count_text(ranges, 200, True) == "196 grid variants (14 x 14, the grid nearest the 200 asked)"
    assert sample_variants(ranges, 200, grid=True)["stiffness"].size == 196
    assert variant_count_text(ranges, 225, True) == "225 grid variants"
    assert variant_count_text(ranges, 1000, False) == "1000 monte carlo variants"
    # a Monte Carlo sample smaller than the corners grows to them, and says so
    assert sample_variants(ranges, 3)["stiffness"].size == 4
    assert variant_count_text(ranges, 3, False).startswith("4 monte carlo variants (the corners")


def test_robust_design_note_counts_the_variants_the_rows_count():
    """[robustness] samples = 8 on a grid over two ranges is 3 x 3 = 9 variants: the design's
    note says 9 (and why), as the robustness rows do."""
    scene = st.load_scene(SCENES / "ema_robust.toml")
    scene = replace(scene, robustness=replace(scene.robustness, samples=8, method="grid"))
    r = st.design(scene, progress=False, structure="pid")  # nominal pid, evaluated over the variants: fast
    assert r.robustness.count == 9
    (header,) = [n for n in r.notes if n.startswith("robust design over")]
    assert "(9 grid variants (3 x 3, the grid nearest the 8 asked) at q0)" in header


def test_design_names_what_it_leaves_to_check(linear_ema, capsys):
    """design judges the loop's rows; the scene's time requirements are check's, and a note
    says so naming each by its row and key."""
    main(["design", str(linear_ema), "--json"])
    d = json.loads(capsys.readouterr().out)
    assert set(d["requirements"]).isdisjoint({"tracking_error", "step_overshoot", "step_settling_time"})
    (note,) = [n for n in d["notes"] if n.startswith("not judged here")]
    for words in ("step_overshoot", "step_settling_time", "tracking_error", "max_overshoot", "max_settling_time",
                  "max_tracking_error", "servo-toolkit check"):
        assert words in note
    assert "large_signal" not in note  # design judges those


def test_left_to_check_names_the_sizing_yield_and_monte_carlo_rows():
    from servo_toolkit.studies.gate import left_to_check
    note = left_to_check(st.load_scene(SCENES / "ema_sizing.toml"), linear_only=True)
    assert "[duty_cycle]" in note and "large_signal_gain" in note
    assert "the scene's" not in note  # it sets no time requirement: the defaults are named
    assert "at their defaults" in note


def test_design_and_check_judge_the_same_large_signal_run(linear_ema):
    """design runs the requirement sine alone, check judges the actuator's sine: the same
    command through the same model (full, friction that holds), so the same figures."""
    from servo_toolkit.studies.actuator import actuator_check
    from servo_toolkit.studies.gate import with_large_signal
    scene = st.load_scene(linear_ema)
    result = st.design(scene, progress=False)
    _, alone = with_large_signal(scene, result)                                 # design's
    _, judged = with_large_signal(scene, result, actuator_check(scene, result))  # check's
    assert (alone.frequency_hz, alone.amplitude) == (judged.frequency_hz, judged.amplitude)
    assert alone.gain_db == judged.gain_db and alone.phase_deg == judged.phase_deg
    assert "full model, friction that holds" in alone.note(True)


def test_check_row_lines_fit_the_longest_id():
    from servo_toolkit.cli.cmd_check import row_lines
    from servo_toolkit.studies.gate import RequirementRow
    rows = [RequirementRow("tracking_error", "peak tracking error", "<= 1 deg", "0.5 deg", "", "pass"),
            RequirementRow("life_ball_screw_8x2_bearing", "L10 life", ">= 500 h", "4870 h", "", "pass"),
            RequirementRow("life_ball_screw_8x2_screw", "L10 life", ">= 500 h", "20 h", "480 h", "fail")]
    lines = row_lines(rows)
    columns = {line.index(" ok  " if r.passed else " FAIL  ") for line, r in zip(lines, rows)}
    assert len(columns) == 1  # the verdicts in one column
    for line, r in zip(lines, rows):
        assert line.startswith(f"  {r.id}  ")  # an ID never runs into its verdict
