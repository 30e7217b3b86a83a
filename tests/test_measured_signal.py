"""Which signal a measured plant response is to: the ``# signal:`` line frf -o writes, the
option against it, and a response that reads as another signal's than the one named."""

from __future__ import annotations

import numpy as np
import pytest

from servo_toolkit.cli import main
from servo_toolkit.core.spectra import response_csv
from servo_toolkit.identify import read_data
from servo_toolkit.identify.frf import response_signal
from servo_toolkit.loop.measured import model_response

from .test_measured_plant import EMA, F, designed  # noqa: F401 (the module's design, shared)


def _csv(path, h, signal=None, f=F):
    head = "" if signal is None else f"# signal: {signal}\n"
    path.write_text(head + response_csv(f, 20 * np.log10(np.abs(h)), np.degrees(np.unwrap(np.angle(h))),
                                        np.ones_like(f), 8))
    return str(path)


def test_frf_names_the_signal_its_response_is_to():
    assert response_signal("motor_angle_rad", False) == "motor_angle_rad"
    assert response_signal("motor_angle_rad", True) == "motor_speed_rad_s"
    assert response_signal("output_travel_m", True) == "output_speed_m_s"
    assert response_signal("encoder_rad", True) == "d(encoder_rad)/dt"


def test_the_signal_line_is_read_with_the_response(tmp_path):
    path = _csv(tmp_path / "frf.csv", np.ones(F.size) * (1 + 1j), "motor_speed_rad_s")
    assert read_data(path).signal == "motor_speed_rad_s"
    assert read_data(_csv(tmp_path / "bare.csv", np.ones(F.size) * (1 + 1j))).signal is None


@pytest.mark.parametrize("model_signal, recorded, taken", [
    ("motor_speed_rad_s", "motor_speed_rad_s", "motor_speed_rad_s"),
    # frf --derivative of the output: the output speed's response, taken as the position's / (j w)
    ("output_speed", "output_speed_rad_s", "output_angle_rad"),
])
def test_a_check_takes_the_signal_the_file_records(designed, tmp_path, capsys, model_signal, recorded, taken):
    """A response that says what it measured is closed as that signal's: the model's own
    margins on the model's response."""
    import json
    _, r = designed
    w = 2 * np.pi * F
    h = (1j * w * model_response(r, w, "output_angle_rad") if model_signal == "output_speed"
         else model_response(r, w, model_signal))
    assert main(["check", EMA, "--linear-only", "--plant-frf", _csv(tmp_path / "frf.csv", h, recorded), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)["scenes"][0]["measured_plant"]
    assert out["signal"] == taken
    assert out["phase_margin_deg"] == pytest.approx(r.margins.phase_margin_deg, abs=0.5)


def test_an_option_against_the_files_signal_exits_2_before_any_design(tmp_path, capsys):
    path = _csv(tmp_path / "frf.csv", np.ones(F.size) * (1 + 1j), "motor_speed_rad_s")
    assert main(["check", EMA, "--linear-only", "--plant-frf", path, "--plant-frf-signal", "motor_angle_rad"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--plant-frf-signal" in err[0] and "motor_speed_rad_s" in err[0], err


@pytest.mark.parametrize("given, named", [("motor_speed_rad_s", None), ("motor_angle_rad", "motor_speed_rad_s"),
                                          ("output_angle_rad", "motor_angle_rad")])
def test_a_response_that_reads_as_another_signals_exits_2_naming_it(designed, tmp_path, capsys, given, named):
    """The speed's response read as the angle's (frf --derivative, the option left out) would
    close a loop 90 deg and a decade per decade off: the line names the signal it reads as."""
    _, r = designed
    path = _csv(tmp_path / "frf.csv", model_response(r, 2 * np.pi * F, given))
    args = ["check", EMA, "--linear-only", "--plant-frf", path] + (["--plant-frf-signal", named] if named else [])
    assert main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--plant-frf-signal" in err[0] and f"reads as the response to {given}" in err[0], err


def test_a_wrong_model_of_the_right_signal_is_not_taken_for_another_signal(designed, tmp_path, capsys):
    """A rig with a tenth more gain, a 0.2 ms delay the model lacks and a resonance of its
    own at 40 Hz (a lightly damped pole pair over a zero pair at 50 Hz): a model error,
    which the loop on the measurement shows; not a refusal."""
    _, r = designed
    s = 2j * np.pi * F
    wz, wp = 2 * np.pi * 50.0, 2 * np.pi * 40.0
    extra = (s ** 2 + 0.04 * wz * s + wz ** 2) / (s ** 2 + 0.04 * wp * s + wp ** 2) * wp ** 2 / wz ** 2
    h = 1.1 * model_response(r, 2 * np.pi * F, "motor_angle_rad") * np.exp(-s * 2e-4) * extra
    path = _csv(tmp_path / "frf.csv", h)
    assert main(["check", EMA, "--linear-only", "--plant-frf", path]) in (0, 1)
    assert "reads as the response" not in capsys.readouterr().err


@pytest.mark.parametrize("signal, response", [("motor_angle_rad", None), ("motor_speed_rad_s", "closed_loop")])
def test_fit_refuses_a_response_to_another_signal_than_it_compares(tmp_path, capsys, signal, response):
    """fit --response plant compares the motor speed's response, closed_loop the output's: a
    file recording another is one line naming DATA.csv and the way to the right one."""
    path = _csv(tmp_path / "frf.csv", np.ones(F.size) * (1 + 1j), signal)
    args = ["fit", EMA, path, "--param", "load.inertia"] + (["--response", response] if response else [])
    assert main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "DATA.csv" in err[0] and signal in err[0], err


def test_a_response_to_a_signal_the_loop_does_not_take_names_the_file(tmp_path, capsys):
    path = _csv(tmp_path / "frf.csv", np.ones(F.size) * (1 + 1j), "d(encoder_rad)/dt")
    assert main(["check", EMA, "--linear-only", "--plant-frf", path]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--plant-frf:" in err[0] and "d(encoder_rad)/dt" in err[0], err
