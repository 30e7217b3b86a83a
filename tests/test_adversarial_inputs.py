"""Inputs at the edge of what a command accepts end in one line naming the data or the key
(exit 2) or in a valid result, never in a traceback of a library underneath."""

import json

import numpy as np
import pytest

from servo_toolkit.cli import main

from .conftest import SCENES

EMA = str(SCENES / "ema_reference.toml")


def _frf_csv(path, gain_db):
    f = np.logspace(0, 2, 20)
    np.savetxt(path, np.column_stack([f, np.full(20, gain_db), np.full(20, -90.0)]), delimiter=",",
               header="frequency_hz,gain_db,phase_deg", comments="")
    return str(path)


def test_fit_refuses_a_response_with_an_impossible_gain_naming_the_row(tmp_path, capsys):
    data = _frf_csv(tmp_path / "huge.csv", 1e6)  # finite, but 10**(1e6/20) overflows
    assert main(["fit", EMA, data, "--response", "plant", "--param", "load.inertia"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "huge.csv: row 2: gain_db must lie within +-300 dB" in err[0]


def test_fit_takes_a_large_but_possible_gain(tmp_path, capsys):
    data = _frf_csv(tmp_path / "big.csv", 290.0)
    assert main(["fit", EMA, data, "--response", "plant", "--param", "load.inertia"]) == 0


def _log(path, u, y):
    t = np.arange(u.size) * 1e-3
    np.savetxt(path, np.column_stack([t, u, y]), delimiter=",", header="time_s,current_A,motor_angle_rad",
               comments="")
    return str(path)


@pytest.mark.parametrize("which", ["input", "output"])
def test_frf_refuses_a_constant_signal(tmp_path, capsys, which):
    rng = np.random.default_rng(0)
    moving = np.sin(2 * np.pi * 5 * np.arange(2000) * 1e-3) + rng.normal(0, 0.1, 2000)
    still = np.full(2000, 0.3)  # a constant whose mean removed leaves rounding, not zero
    u, y = (still, moving) if which == "input" else (moving, still)
    out = tmp_path / "frf.csv"
    assert main(["frf", _log(tmp_path / "log.csv", u, y), "--input", "current_A", "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"--{which}: the signal is constant" in err[0]
    assert not out.exists()


@pytest.fixture(scope="module")
def saved_design(tmp_path_factory):
    import servo_toolkit as st
    from servo_toolkit.loop import design
    from servo_toolkit.loop.tuning import save_design
    path = tmp_path_factory.mktemp("design") / "design.json"
    save_design(design(st.load_scene(EMA)), path)
    return json.loads(path.read_text())


def test_check_evaluates_a_design_with_a_vanishing_position_gain(saved_design, tmp_path, capsys):
    """kp = 1e-30 lies in the design file's range: the check gives its verdict (the margins
    of a loop that barely closes), not a NaN from the Nyquist count."""
    saved_design["gains"]["kp"] = 1e-30
    path = tmp_path / "tiny.json"
    path.write_text(json.dumps(saved_design))
    code = main(["check", EMA, "--design", str(path), "--nominal", "--linear-only", "--json"])
    captured = capsys.readouterr()
    assert code in (0, 1), captured.err
    assert "Traceback" not in captured.err and json.loads(captured.out)


def test_check_refuses_a_million_nonlinear_tolerance_variants_before_any_work(tmp_path, capsys):
    text = (SCENES / "examples" / "ema_tolerances.toml").read_text()
    text = text.replace("samples = 1024 ", 'samples = 1000000\nmax_tracking_error = "1 deg" ', 1)
    path = tmp_path / "million.toml"
    path.write_text(text)
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "tolerances.samples: the run is estimated at" in err[0] and "--force" in err[0]


def test_tolerances_refuses_hour_long_nonlinear_runs_naming_the_duration(capsys):
    code = main(["tolerances", str(SCENES / "examples" / "ema_tolerances.toml"), "--nonlinear", "--duration", "3600",
                 "--samples", "1024"])
    assert code == 2
    assert "--duration: the run is estimated at" in capsys.readouterr().err


def test_fit_refuses_a_closed_loop_log_too_long_to_fit_in_the_budget(tmp_path, capsys):
    """Each evaluation runs the nonlinear closed loop over the whole log: 120,000 rows and
    four parameters are beyond 10 min; refused before the fit starts."""
    n = 120_000
    t = np.arange(n) * 1e-3
    path = tmp_path / "long.csv"
    np.savetxt(path, np.column_stack([t, 1e-3 * np.sin(t), 1e-3 * np.sin(t), 0.1 * np.cos(t)]), delimiter=",",
               header="time_s,command_m,output_m,current_A", comments="", fmt="%.9g")
    keys = ["load.inertia", "load.damping", "motor.coulomb_friction", "load.hinge_moment"]
    code = main(["fit", str(SCENES / "emps.toml"), str(path), *[a for k in keys for a in ("--param", k)]])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1
    assert "DATA.csv: the run is estimated at" in err[0] and "120000 rows" in err[0] and "--force" in err[0]
