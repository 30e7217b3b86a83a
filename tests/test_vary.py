"""``--vary NAME=LO:HI`` (``check``, ``montecarlo``): bounded by the range the model is
conditioned for, refused at parse time with one line naming the option as typed
(``--vary NAME=LO:HI``); and a variant's parameters read with their units wherever they
are shown."""

from __future__ import annotations

import json

import numpy as np
import pytest

from servo_toolkit.cli import main
from servo_toolkit.display.units import DisplayUnits
from servo_toolkit.errors import SceneError
from servo_toolkit.loop.vary import VARY_RANGES, parse_vary, ranges_text, variant_text

from .conftest import SCENES

EMA = str(SCENES / "ema_reference.toml")
#: every form of --vary with the number a user may type into it
FORMS = ("load_inertia=0:{x}", "load_inertia={x}:1", "stiffness={x}:1.2", "stiffness=0.8:{x}")
EXTREMES = ("1e-300", "-1e-300", "1e300", "-1e300", "inf", "-inf", "nan", "1e-13", "1e7", "1e-4", "1e4")


def _accepted(text) -> bool:
    try:
        parse_vary(text)
    except SceneError:
        return False
    return True


@pytest.mark.parametrize("form", FORMS)
def test_every_form_at_every_extreme_is_refused_or_within_the_conditioned_range(form):
    for x in EXTREMES:
        text = form.format(x=x)
        name = text.split("=")[0]
        try:
            _, (lo, hi) = parse_vary(text)
        except SceneError as exc:
            assert exc.key == f"--vary {text}" and "\n" not in str(exc), (text, str(exc))
            continue
        low, high = VARY_RANGES[name]
        assert all(v == 0 or low <= v <= high for v in (lo, hi)), text
    # the reported cases: a stiffness factor of 1e-300, a load inertia up to 1e300
    for text in ("stiffness=1e-300:1.2", "load_inertia=0:1e300"):
        with pytest.raises(SceneError, match="conditioned for"):
            parse_vary(text)
    assert parse_vary("load_inertia=0:1e6") == ("load_inertia", (0.0, 1e6))
    assert parse_vary("stiffness=1e-3:1e3") == ("stiffness", (1e-3, 1e3))


@pytest.mark.parametrize("command", ["check", "montecarlo"])
def test_the_command_line_refuses_before_any_work(command, capsys):
    """One stderr line, exit 2, nothing on stdout, for every form and extreme the parser
    refuses (the refusal comes before the scene is designed: this test runs no design)."""
    refused = [f.format(x=x) for f in FORMS for x in EXTREMES if not _accepted(f.format(x=x))]
    assert len(refused) >= 30
    for text in refused:
        assert main([command, EMA, "--vary", text, "--samples", "2"]) == 2, text
        out, err = capsys.readouterr()
        line, = err.strip().splitlines()
        assert line.startswith(f"servo-toolkit: error: --vary {text}:") and out == "", (text, err)


def test_montecarlo_at_the_ends_of_the_conditioned_ranges_runs_cleanly(capsys):
    """The widest accepted ranges (a load inertia up to 1e6 kg*m^2, a stiffness factor of
    1e-3 .. 1e3) run: every variant a result or a failed variant with its reason, never a
    traceback (an empty list of modes used to raise IndexError). At a stiffness factor of
    1e-3 the drivetrain cannot carry the 700 N*m hinge moment within the stroke: those
    variants fail with that reason and no figures, the study goes on."""
    code = main(["montecarlo", EMA, "--vary", "load_inertia=0:1e6", "--vary", "stiffness=1e-3:1e3",
                 "--samples", "4", "--duration", "0.01", "--json"])
    out, err = capsys.readouterr()
    assert code == 0 and "Traceback" not in err, err
    soft = [v for v in json.loads(out)["variants"] if v["stiffness"] == pytest.approx(1e-3)]
    assert soft and all(v["failed"] and v["reason"].startswith("no start:") and "outside the stroke" in v["reason"]
                        and v["peak_current_A"] is None for v in soft)


def test_a_variant_reads_with_its_units():
    values = {"load_inertia": np.array([0.0, 3.99]), "stiffness": np.array([0.7, 1.3])}
    assert variant_text(values, index=1) == "load_inertia = 3.99 kg*m^2, stiffness = 1.3 x nominal"
    cm = DisplayUnits(inertia="kg*cm^2")  # 1 kg*m^2 = 1e4 kg*cm^2, independently
    assert variant_text({"load_inertia": 3.99}, cm) == f"load_inertia = {3.99e4 / 1e3:g}e3 kg*cm^2"
    assert variant_text({"load_inertia": 1.5}, linear=True) == "load_inertia = 1.5 kg"
    assert ranges_text(values, cm) == "load_inertia 0..39.9e3 kg*cm^2, stiffness 0.7..1.3 x nominal"


def test_report_and_gate_rows_name_the_variant_with_units():
    """The robustness and Monte Carlo rows (check, JUnit, the report) and the report's
    sections write a variant with its units, not raw SI numbers."""
    from servo_toolkit.loop.robustness import RobustnessResult
    from servo_toolkit.loop.requirements import Check
    from servo_toolkit.studies.gate import montecarlo_rows, robust_rows
    from servo_toolkit.studies.montecarlo import MonteCarloResult
    values = {"load_inertia": np.array([0.0, 4.0]), "stiffness": np.array([0.7, 1.3])}
    cm = DisplayUnits(inertia="kg*cm^2")
    check = Check("gain_margin", 6.0, 5.0, False, "dB", ">=", "robustness", 1.0)
    robust = RobustnessResult("x", values, {"stable": np.array([True, True])}, [check],
                              {"gain_margin": {"load_inertia": 4.0, "stiffness": 0.7}}, display=cm)
    row, = robust_rows(robust)
    assert "at load_inertia = 40e3 kg*cm^2, stiffness = 0.7 x nominal" in row.detail
    mc = MonteCarloResult("x", values, np.array([1e-3, 2e-3]), np.array([1.0, 2.0]), np.array([False, False]),
                          np.array([False, False]), ("", ""), np.array([0.1, 0.1]), 0.1, 1e-4, 10, 1.0, display=cm)
    row, = montecarlo_rows([Check("tracking_error", 1e-3, 2e-3, False, "deg", "<=", "robustness", 1e-3)], mc)
    assert row.detail.endswith("at load_inertia = 40e3 kg*cm^2, stiffness = 1.3 x nominal")


def test_a_variant_that_changes_the_models_form_is_one_line(tmp_path, capsys):
    """A rod of 1e6 kg (in its range) behind a rocker: with no load inertia the variant's
    drivetrain has another form (fewer nodes), which the batch cannot run beside the others."""
    text = (SCENES / "ema_sizing.toml").read_text()
    assert 'rod_mass = "' in text
    import re
    path = tmp_path / "heavy_rod.toml"
    path.write_text(re.sub(r'(?m)^rod_mass = .*$', 'rod_mass = "1e6 kg"', text))
    code = main(["montecarlo", str(path), "--samples", "4", "--duration", "0.02"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and err[-1].startswith("servo-toolkit: error: vary.load_inertia: a variant changes the model's")
    assert not any("Traceback" in line for line in err)
