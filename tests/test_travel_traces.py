"""Traces carry the unit they hold: an output travel's traces are written and shown in
metres under names that say so (``output_travel_m``), never under ``output_angle_rad``."""

import json
import numpy as np
import pytest

from servo_toolkit.cli import main
from servo_toolkit.sim.result import shown_name

from .conftest import SCENES


@pytest.mark.parametrize("name, unit, shown", [
    ("output_angle_rad", "m", "output_travel_m"), ("reference_angle_rad", "m", "reference_travel_m"),
    ("motor_side_angle_rad", "m", "motor_side_travel_m"), ("output_rate_rad_s", "m", "output_rate_m_s"),
    ("play_state_rad", "m", "play_state_m"), ("node[2]_position", "m", "node[2]_position_m"),
    ("node[2]_rate", "m", "node[2]_rate_m_s"), ("current_A", "m", "current_A"),
    ("speed_estimator.angle_rad", "m", "speed_estimator.angle_rad"),  # the motor's own angle
    ("output_angle_rad", "rad", "output_angle_rad"), ("node[2]_position", "rad", "node[2]_position_rad"),
    ("node[2]_rate", "rad", "node[2]_rate_rad_s"),
])
def test_a_trace_name_carries_the_unit_it_holds(name, unit, shown):
    assert shown_name(name, unit) == shown


def carriage_text() -> str:
    """The reference EMA's motor, gear and ball screw driving a 20 kg carriage (an output
    travel), as a scene file's text."""
    text = (SCENES / "ema_reference.toml").read_text()
    head = text[:text.index("[[drivetrain]]\nkind = \"rocker_linkage\"")]
    return head + '\n[load]\ninertia = "20 kg"\n\n[sensors]\nsample_time = "0.1 ms"\n'


@pytest.fixture(scope="module")
def carriage(tmp_path_factory):
    path = tmp_path_factory.mktemp("carriage") / "carriage.toml"
    path.write_text(carriage_text())
    return path


def test_an_output_travel_is_written_and_shown_in_metres(carriage, tmp_path, capsys):
    trace = tmp_path / "trace.csv"
    code = main(["simulate", str(carriage), "--amplitude", "0.5 mm", "--frequency", "2", "-o", str(trace), "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == 0
    header = trace.read_text().splitlines()[0].split(",")
    assert {"output_travel_m", "reference_travel_m", "motor_side_travel_m", "output_rate_m_s"} <= set(header)
    assert not [c for c in header if c.startswith(("output_angle", "reference_angle", "motor_side_angle"))]
    cols = np.genfromtxt(trace, delimiter=",", names=True)
    ref = cols["reference_travel_m"] - cols["reference_travel_m"][0]
    assert np.max(np.abs(ref)) == pytest.approx(0.5e-3, rel=0.02)  # metres: a 0.5 mm sine
    assert "output_travel_m" in out["final_state"] and "output_angle_rad" not in out["final_state"]
    main(["simulate", str(carriage), "--amplitude", "0.5 mm", "--frequency", "2"])
    text = capsys.readouterr().out
    assert "output_travel_m = " in text and "output_angle_rad" not in text


def test_the_play_state_is_an_absolute_position_held_outside_the_paper_scheme(tmp_path, capsys):
    """The play state is the paper scheme's play-operator output, a position at the output:
    an RK4 run holds it at its start (the output's start travel, mid-stroke, not 0) and says
    so; the paper scheme moves it with the motor side and needs no such note."""
    carriage = tmp_path / "stroke.toml"
    carriage.write_text(carriage_text().replace('backlash = "10 um"', 'backlash = "10 um"\nstroke = ["0 mm", "200 mm"]'))
    trace = tmp_path / "trace.csv"
    assert main(["simulate", str(carriage), "--amplitude", "0.5 mm", "--frequency", "2", "-o", str(trace),
                 "--method", "rk4", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    cols = np.genfromtxt(trace, delimiter=",", names=True)
    assert np.all(cols["play_state_m"] == cols["play_state_m"][0])
    assert cols["play_state_m"][0] == pytest.approx(cols["output_travel_m"][0], abs=1e-9)
    start_mm = cols["play_state_m"][0] * 1e3
    assert abs(start_mm) > 1.0  # a mid-stroke start: an absolute position, no deflection
    held = [n for n in out["notes"] if n.startswith("play_state_m is")]
    assert held == [f"play_state_m is the paper scheme's play-operator output, a position at the output like "
                    f"output_travel_m (not a deflection): method 'rk4' holds it at its start, {start_mm:.4g} mm"]
    assert main(["simulate", str(carriage), "--amplitude", "0.5 mm", "--frequency", "2", "-o", str(trace),
                 "--method", "paper", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert not [n for n in out["notes"] if n.startswith("play_state_m is")]
    cols = np.genfromtxt(trace, delimiter=",", names=True)
    assert np.ptp(cols["play_state_m"]) > 0.5e-3  # it follows the 0.5 mm sine
