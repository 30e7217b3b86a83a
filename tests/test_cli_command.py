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


def test_friction_option_on_simulate_and_montecarlo(monkeypatch):
    """``--friction stick`` reaches simulate's and the Monte Carlo's run options; the Monte
    Carlo's variants then run friction that holds (in its lanes), the reduced model keeping it
    and saying so."""
    from servo_toolkit.loop.default_controller import default_controller
    from servo_toolkit.scene import load_scene
    from servo_toolkit.studies import montecarlo as mc
    from servo_toolkit.studies.time import run as time_run

    class Asked(Exception):
        pass

    def stub(real):
        def asked(*args, **options):  # the warm-up of a cold kernel cache runs the real ones
            if "friction" not in options:
                return real(*args, **options)
            raise Asked(options["friction"])
        return asked
    monkeypatch.setattr(time_run, "simulate_study", stub(time_run.simulate_study))
    with pytest.raises(Asked, match="^stick$"):
        main(["simulate", EMA, "--friction", "stick"])
    real = mc.montecarlo
    monkeypatch.setattr(mc, "montecarlo", stub(real))
    with pytest.raises(Asked, match="^off$"):
        main(["montecarlo", EMA, "--friction", "off", "--samples", "2"])
    scene = load_scene(EMA)
    out = real(scene, {"load_inertia": (1.0, 1.3)}, samples=2, duration=0.05, friction="stick",
               controller=default_controller(scene), progress=False)
    assert "friction model stick (as asked)" in out.notes and not out.failed.any()


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
