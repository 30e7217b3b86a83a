"""The command options from the command line: simulate with the designed gains, the gain
schedule and a shaper; montecarlo with the feedforward; a bad option is one line, exit 2."""

from __future__ import annotations

import json

import pytest

from servo_toolkit.cli import main

from .conftest import SCENES

EMA = str(SCENES / "ema_reference.toml")


def test_simulate_with_gains_schedule_and_shaper(capsys):
    assert main(["simulate", EMA, "--feedforward", "gains", "--schedule", "--shaper", "zv", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    notes = " ".join(out["notes"])
    assert "velocity" in notes and "gain schedule" in notes and "ZV shaper" in notes and "delay" in notes
    assert out["max_abs_tracking_error_after_start_deg"] < 0.5


def test_montecarlo_feedforward_option(capsys):
    assert main(["montecarlo", EMA, "--feedforward", "model", "--samples", "2", "--vary", "load_inertia=1:1.3",
                 "--duration", "0.3", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["feedforward"]["model"] is True
    assert out["feedforward"]["load_inertia"] == pytest.approx(1.0)


def test_bad_command_options_exit_2(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["simulate", EMA, "--shaper", "zz"])
    assert exc.value.code == 2
    capsys.readouterr()
