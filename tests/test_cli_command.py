"""The command options from the command line: simulate with the designed gains, the gain
schedule and a shaper; montecarlo with the feedforward; the friction model on both; a bad
option is one line, exit 2."""

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


def test_friction_option_on_simulate_and_montecarlo(capsys):
    """``--friction stick`` runs friction that holds (the reduced model keeps it and says so),
    in simulate and in the Monte Carlo's variants."""
    assert main(["simulate", EMA, "--friction", "stick", "--json"]) == 0
    stick = json.loads(capsys.readouterr().out)
    assert "friction model stick (as asked)" in stick["notes"]
    assert main(["montecarlo", EMA, "--friction", "stick", "--samples", "2", "--vary", "load_inertia=1:1.3",
                 "--duration", "0.3", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert "friction model stick (as asked)" in out["notes"] and out["failed_variants"] == 0


def test_a_friction_model_not_known_is_named():
    from servo_toolkit.errors import SceneError
    from servo_toolkit.scene import load_scene
    from servo_toolkit.studies.montecarlo import montecarlo
    with pytest.raises(SceneError, match="friction.*stick, smooth, off"):
        montecarlo(load_scene(EMA), samples=1, duration=1e-3, friction="sticky", progress=False)


def test_bad_command_options_exit_2(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["simulate", EMA, "--shaper", "zz"])
    assert exc.value.code == 2
    capsys.readouterr()
    with pytest.raises(SystemExit) as exc:
        main(["montecarlo", EMA, "--friction", "sticky"])
    assert exc.value.code == 2
    assert "--friction" in capsys.readouterr().err
