"""No verdict is wrong: a figure that could not be produced is an error (exit 2), never a
FAIL or PASS row; what a command checks is what it says it checked."""

from __future__ import annotations

import json
import math
import xml.etree.ElementTree as ET
from types import SimpleNamespace

import numpy as np
import pytest

from servo_toolkit.cli import main
from servo_toolkit.errors import SceneError, SimulationError

from .conftest import SCENES

EMA = str(SCENES / "ema_reference.toml")


# -- 1. check's own nonlinear runs ---------------------------------------------------------

def test_check_whose_large_signal_run_cannot_run_exits_2_with_the_reason(monkeypatch, tmp_path, capsys):
    import servo_toolkit.sim as sim
    import servo_toolkit.studies.time.run  # noqa: F401 - binds the real simulate before the patch, not the stub

    def cannot(*args, **kwargs):
        raise SimulationError("1 s at a step of 1e-09 s is 1e+09 steps, more than the 3e+08 one run may take")
    monkeypatch.setattr(sim, "simulate", cannot)
    junit = tmp_path / "gate.xml"
    assert main(["check", EMA, "--junit", str(junit)]) == 2
    out, err = capsys.readouterr()
    assert "nan" not in out.lower() and "short by inf" not in out
    line, = err.strip().splitlines()
    # the first nonlinear run check makes (the actuator's step) names itself and the reason
    assert "nonlinear 1 deg step" in line and "could not be carried out" in line and "1e+09 steps" in line
    root = ET.parse(junit).getroot()
    assert not root.findall(".//failure") and root.findall(".//error")
    assert main(["check", EMA, "--json"]) == 2
    data = json.loads(capsys.readouterr().out)
    assert data["errors"] == 1 and data["scenes"][0]["key"] == "simulation"


def test_a_nan_figure_is_no_verdict():
    from servo_toolkit.studies.gate import LargeSignal
    from servo_toolkit.loop.requirements import Requirement, check
    with pytest.raises(SimulationError, match="phase_margin"):
        check([Requirement("phase_margin", ">=", 45.0, "deg", "scene")], {"phase_margin": math.nan})
    # infinities with a meaning are still judged: no phase crossover, an unstable loop
    ok, = check([Requirement("gain_margin", ">=", 6.0, "dB", "scene")], {"gain_margin": math.inf})
    assert ok.passed
    ls = LargeSignal(8.0, 0.03, math.nan, math.nan, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0)
    with pytest.raises(SimulationError, match="large_signal_gain"):
        ls.checks()


def test_monte_carlo_rows_with_a_failed_variant_are_no_verdict():
    from servo_toolkit.loop.requirements import Requirement
    from servo_toolkit.studies.montecarlo import result_checks
    result = SimpleNamespace(failed=np.array([False, True]), count=2,
                             reasons=("", "step 0.0001 s outside the RK4 stability region"),
                             values={"stiffness": np.array([1.0, 1e-6])},
                             error_display=np.array([0.1, np.nan]), peak_current=np.array([3.0, np.nan]))
    reqs = [Requirement("tracking_error", "<=", 0.5, "deg", "robustness")]
    with pytest.raises(SimulationError, match="1 of 2 variants.*stability region"):
        result_checks(reqs, result)
    result.failed = np.array([False, False])
    result.error_display = np.array([0.1, 0.2])
    c, = result_checks(reqs, result)
    assert c.passed and c.achieved == pytest.approx(0.2)


# -- 2. the fixed-point export checks the quantized loop against the requirements ----------

def test_fixed_point_export_of_a_design_that_misses_its_requirements_fails(tmp_path, capsys):
    code = main(["export", EMA, "-o", str(tmp_path / "pid"), "--fixed-point", "q31", "--structure", "pid",
                 "--json"])
    out, err = capsys.readouterr()
    data = json.loads(out)
    assert code == 1 and data["passed"] is False
    assert data["design"]["phase_margin_deg"] < 45
    failures = data["quantized"]["failures"]
    assert any(f.startswith("phase_margin:") and "already misses" in f for f in failures)
    assert "phase_margin:" in err and "within the requirements" not in out + err


# -- 3. wide ranges: log spacing and the corners -------------------------------------------

def test_a_range_over_24_decades_is_sampled_at_both_ends():
    from servo_toolkit.loop.robustness import sample_variants
    v = sample_variants({"stiffness": (1e-12, 1e12)}, 1000, False, 0)["stiffness"]
    assert v.min() == 1e-12 and v.max() == 1e12
    assert np.sum(v < 1.0) > 300 and np.sum(v > 1.0) > 300  # log-uniform: half below the middle
    grid = sample_variants({"stiffness": (1e-3, 1e3)}, 7, True, 0)["stiffness"]
    assert grid == pytest.approx(np.geomspace(1e-3, 1e3, 7))


def test_monte_carlo_samples_always_hold_the_corners():
    from servo_toolkit.loop.robustness import sample_variants
    v = sample_variants({"load_inertia": (0.0, 4.0), "stiffness": (0.7, 1.3)}, 1000, False, 0)
    pairs = set(zip(v["load_inertia"][:4], v["stiffness"][:4]))
    assert pairs == {(0.0, 0.7), (0.0, 1.3), (4.0, 0.7), (4.0, 1.3)}
    assert v["load_inertia"].size == 1000
    # narrow ranges keep linear draws (the same draws as before, past the corners)
    rng = np.random.default_rng(0)
    assert v["load_inertia"][4:] == pytest.approx(rng.uniform(0.0, 4.0, 1000)[4:])
    small = sample_variants({"load_inertia": (0.0, 4.0), "stiffness": (0.7, 1.3)}, 2, False, 0)
    assert small["stiffness"].size == 4  # grows to the corners


def test_check_vary_over_six_decades_sees_the_soft_end(capsys):
    """The widest stiffness range --vary accepts (the factors the model is conditioned for)."""
    assert main(["check", EMA, "--vary", "stiffness=1e-3:1e3", "--samples", "40", "--linear-only",
                 "--json"]) == 1
    data = json.loads(capsys.readouterr().out)["scenes"][0]
    rb = data["robustness"]
    assert rb["ranges"]["stiffness"] == [1e-3, 1e3]
    assert rb["worst"]["stable_fraction"]["passed"] is False


# -- 4. sine frequencies the run resolves --------------------------------------------------

@pytest.mark.parametrize("args, limit", [
    (["simulate", EMA, "--frequency", "1e5"], "at most 2500 Hz"),
    (["simulate", EMA, "--frequency", "0.5"], "at least 1 Hz"),
    (["sweep", EMA, "--frequency", "1e-6"], "at least 0.000267 Hz"),
    (["sweep", EMA, "--frequency", "8", "--frequency", "4000"], "at most 2500 Hz"),
    (["montecarlo", EMA, "--frequency", "6000", "--samples", "2"], "at most 2500 Hz"),
])
def test_frequencies_outside_what_the_run_resolves_are_one_line(args, limit, capsys):
    assert main(args) == 2
    out, err = capsys.readouterr()
    line, = err.strip().splitlines()
    assert line.startswith("servo-toolkit: error: --frequency: must be") and limit in line
    assert out == ""


def test_a_study_frequency_above_the_sample_rate_names_its_key(tmp_path, capsys):
    text = (SCENES / "ema_reference.toml").read_text()
    path = tmp_path / "fast.toml"
    path.write_text(text + '\n[studies.fast]\nkind = "simulate"\namplitude = "2 deg"\nfrequency = "6 kHz"\n'
                    'duration = "0.01 s"\n')
    assert main(["simulate", str(path), "--study", "fast"]) == 2
    err = capsys.readouterr().err
    assert "studies.fast.frequency: must be at most 2500 Hz" in err and len(err.strip().splitlines()) == 1


# -- 5. simulate --dt is honoured or refused -----------------------------------------------

def test_simulate_dt_without_a_method_runs_rk4_at_that_step(capsys):
    assert main(["simulate", EMA, "--dt", "5e-6", "--json"]) == 0
    out, err = capsys.readouterr()
    data = json.loads(out)
    assert data["requested_method"] == "rk4" and data["method"] == "rk4"
    assert data["dt_s"] == pytest.approx(5e-6)
    assert "ran method rk4 at step 5e-06 s" in err


@pytest.mark.parametrize("method", ["auto", "reference"])
def test_simulate_dt_with_a_method_that_ignores_it_is_refused(method, capsys):
    assert main(["simulate", EMA, "--dt", "1e-5", "--method", method]) == 2
    out, err = capsys.readouterr()
    line, = err.strip().splitlines()
    assert line.startswith("servo-toolkit: error: --dt: applies to the fixed-step methods") and out == ""


# -- 6. the contents of a design file ------------------------------------------------------

def _design_file(tmp_path, **edits):
    data = {"servo_toolkit_design": 1, "scene": "ema_reference", "q0_rad": 0.0, "structure": "cascade",
            "gains": {"kp": 60.0, "kv": 40.0, "wvi": 30.0}, "filter": "none", "filter_params": {},
            "ratio": 150.0, "current_kp_v_per_a": 2.0, "current_ki_v_per_a_s": 800.0, "sample_time_s": 1e-4}
    for key, value in edits.items():
        table, _, name = key.partition("__")
        if name:
            data[table][name] = value
        else:
            data[table] = value
    path = tmp_path / "d.json"
    path.write_text(json.dumps(data) if "raw" not in edits else edits["raw"])
    return path


@pytest.mark.parametrize("edits, expect", [
    ({"sample_time_s": -1e-4}, "sample_time_s: must lie in [0, 1]"),
    ({"sample_time_s": 1e-12}, "sample_time_s: must be 0 (a continuous controller) or within"),
    ({"q0_rad": 100.0}, "q0_rad: the operating point must lie within the scene's stroke"),
    ({"ratio": 0}, "ratio: must lie in"),
    ({"ratio": float("nan")}, "ratio: value is NaN"),
    ({"gains__kp": 1e300}, "gains.kp: must lie in (0, 1e+09]"),
    ({"gains__kv": 10 ** 400}, "gains.kv: must lie in (0, 1e+09] (got an integer of 401 digits)"),
    ({"gains__wvi": "fast"}, "gains.wvi: must be a number"),
    ({"gains__kd": 1.0}, "gains.kd: unknown for cascade"),
    ({"gains": {"kp": 1.0}}, "gains.kv: missing"),
    ({"current_kp_v_per_a": float("inf")}, "current_kp_v_per_a: must lie in [0, 1e+09]"),
    ({"filter": "notch", "filter_params": {"wn": 400.0, "zeta_zero": 0.05, "zeta_pole": -1}},
     "filter_params.zeta_pole: must lie in (0, 100]"),
    ({"structure": "fuzzy"}, "structure: must be one of"),
])
def test_design_file_contents_are_checked_field_by_field(tmp_path, capsys, edits, expect):
    path = _design_file(tmp_path, **edits)
    assert main(["design", EMA, "--design", str(path), "--linear-only"]) == 2
    out, err = capsys.readouterr()
    line, = err.strip().splitlines()
    assert line.startswith("servo-toolkit: error: --design: ") and expect in line, line
    assert out == ""


def test_a_huge_integer_gain_that_fits_is_converted():
    from servo_toolkit.loop.design_file import number
    assert number({"kp": 10 ** 6}, "gains.kp", 0.0, 1e9, lo_open=True) == 1e6


# -- 8. JUnit XML of a scene whose name holds control characters ---------------------------

def test_junit_of_a_scene_named_with_control_characters_parses(tmp_path, capsys):
    text = (SCENES / "ema_reference.toml").read_text().replace('name = "ema_reference"',
                                                               'name = "ema\\u001b[31m\\u0007\\u0000x"', 1)
    scene = tmp_path / "ctl.toml"
    scene.write_text(text)
    junit = tmp_path / "gate.xml"
    assert main(["check", str(scene), str(tmp_path / "missing.toml"), "--linear-only", "--junit", str(junit)]) == 2
    capsys.readouterr()
    root = ET.parse(junit).getroot()  # well-formed XML 1.0
    suites = root.findall("testsuite")
    assert suites[0].get("name") == "ema\\x1b[31m\\x07\\x00x"
    assert all(c.get("classname") == suites[0].get("name") for c in suites[0].findall("testcase"))


def test_xml_text_keeps_what_xml_allows():
    from servo_toolkit.cli.cmd_check import xml_text
    assert xml_text("tab\tnewline\n\u00e9\U0001f600") == "tab\tnewline\n\u00e9\U0001f600"
    assert xml_text("\x1b\ufffe") == "\\x1b\\ufffe"


def test_no_stable_variant_fails_the_robust_rows_on_the_unstable_loops_figures():
    from servo_toolkit.loop.requirements import Requirement
    from servo_toolkit.loop.robustness import worst_cases
    figs = {"stable": np.array([False, False]), "max_pole_real": np.array([1.0, 2.0]),
            "gain_margin_db": np.array([np.nan, np.nan])}
    reqs = [Requirement("stable_fraction", ">=", 1.0, "", "robustness"),
            Requirement("gain_margin", ">=", 6.0, "dB", "nominal")]
    checks, worst = worst_cases({"stiffness": np.array([1e-6, 1e-5])}, figs, reqs)
    assert [c.passed for c in checks] == [False, False] and checks[1].achieved == 0.0


def test_a_large_signal_run_into_the_end_stop_is_a_failed_row_not_bad_input():
    """An actuator that runs into its end stop on the requirement sine fails the gate (exit 1)
    on a finite row, the seconds it stayed within the stroke; only a run that cannot be
    carried out numerically is exit 2."""
    import math

    from servo_toolkit.studies.gate import LargeSignal
    ls = LargeSignal(frequency_hz=8.0, amplitude=0.035, gain_db=math.nan, phase_deg=math.nan, linear_gain_db=0.0,
                     linear_phase_deg=-70.0, time_at_voltage_limit_s=math.nan, time_at_current_limit_s=math.nan,
                     duration_s=1.0, peak_current_A=math.nan, peak_voltage_V=math.nan,
                     failure="stroke end reached at t = 0.7 s", stroke_end_s=0.7)
    (row,) = ls.checks()
    assert row.name == "large_signal_within_stroke" and not row.passed
    assert row.achieved == 0.7 and row.shortfall == pytest.approx(0.3)
    assert "stroke end reached" in ls.note(False)


# -- a figure printed beside its verdict reads as that verdict ------------------------------

@pytest.mark.parametrize("achieved, sense", [(5.9996, ">="), (6.0004, ">="), (5.99999, ">="), (6.0004, "<="),
                                             (5.9996, "<="), (8.0, ">="), (14.05, ">=")])
def test_the_achieved_figure_shown_agrees_with_the_verdict(achieved, sense):
    """The number printed in the text table, the JSON/JUnit row and the report compares with
    the requirement as the verdict does (5.9996 dB shown as "6 dB" beside FAIL did not)."""
    import re
    from servo_toolkit.loop.requirements import check, Requirement
    from servo_toolkit.loop.result import requirements_table
    from servo_toolkit.studies.gate import check_row
    c, = check([Requirement("gain_margin", sense, 6.0, "dB", "scene")], {"gain_margin": achieved})
    row = check_row(c)
    from servo_toolkit.display.cards import requirement_rows
    line = requirements_table([c]).splitlines()[1]
    for text in (row.achieved, re.search(r"dB\s+(\S+) dB", line).group(1), requirement_rows([c])[0][2]):
        shown = float(text.split()[0])
        assert (shown >= 6.0 if sense == ">=" else shown <= 6.0) == c.passed, (text, c)
