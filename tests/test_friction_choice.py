"""The friction model is chosen by need: a DC gearmotor whose carriage's Coulomb friction is
the largest force of its run keeps friction that holds in the default (reduced) run, which
then draws the current the full model draws."""

from __future__ import annotations

import math
import tomllib

import numpy as np
import pytest

from servo_toolkit.loop.design import design
from servo_toolkit.sim import Reference
from servo_toolkit.studies.reduce.estimates import FRICTION_EFFECT, loop_response, plan_reduction
from servo_toolkit.studies.time.run import simulate_study, sine_run_options

from .conftest import build

GEARMOTOR = """
name = "gearmotor_carriage"
[motor]
kind = "dc"
resistance = "1.2 ohm"
inductance = "1.5 mH"
torque_constant = "0.06 N*m/A"
back_emf_constant = "0.06 V*s/rad"
rotor_inertia = "3e-5 kg*m^2"
voltage_limit = "48 V"
current_limit = "10 A"
[[drivetrain]]
kind = "gear"
name = "planetary gearhead"
ratio = 50
torsional_stiffness = "2000 N*m/rad"
backlash = "0.5 deg"
efficiency = 0.8
[[drivetrain]]
kind = "ball_screw"
name = "ball screw"
lead = "10 mm"
axial_stiffness = "1.5e8 N/m"
backlash = "5 um"
efficiency = 0.9
[load]
inertia = "20 kg"
damping = "50 N*s/m"
coulomb_friction = "10 N"
[sensors]
motor_encoder_counts = 2048
sample_time = "0.2 ms"
[requirements]
bandwidth = "5 Hz"
min_gain_margin = "6 dB"
min_phase_margin = "45 deg"
max_sensitivity_peak = "6 dB"
[studies.move]
kind = "simulate"
amplitude = "0.5 mm"
frequency = "2 Hz"
"""


@pytest.fixture(scope="module")
def gearmotor():
    return build(tomllib.loads(GEARMOTOR))


def rms_current(result) -> float:
    """RMS motor current after the start's transient (A)."""
    keep = result.times > result.start_transient_s
    return float(np.sqrt(np.mean(result.motor_current[keep] ** 2)))


def test_the_load_s_friction_is_judged_against_the_force_its_motion_needs(gearmotor):
    """10 N of Coulomb friction against the carriage's own motion at 0.5 mm, 2 Hz: 20 kg at
    (4 pi)^2 0.5 mm = 1.58 N of inertia and 50 N*s/m at 4 pi 0.5 mm = 0.31 N of damping,
    |-1.58 + 0.31 j| = 1.61 N; the relay (4 / pi) 10 N = 12.7 N is about 8 times that (the
    closed loop's output amplitude is within 2 % of the command's). The estimate is the
    friction's, and the plan keeps the stick.

    The loop is designed with no current-ripple bound on its speed gain, so that its output
    follows the command at 2 Hz as the hand figure takes it: the default allowance (0.5 A rms
    against the 2048-count encoder's quantization) lowers the speed gain and the output's
    amplitude to 0.966 of the command's, and the estimate, read against the output's motion,
    rises with it to 7.91 / 0.966 = 8.19."""
    result = design(gearmotor, current_ripple=math.inf)
    controller = result.controller
    follows = abs(loop_response(result.parameters, controller, gearmotor.motor, np.array([4 * np.pi]))["theta"][0])
    assert follows == pytest.approx(1.0, abs=0.02)
    plan = plan_reduction(gearmotor, controller, [2.0], [0.5e-3],
                          base=sine_run_options(gearmotor, controller, Reference.sine(0.5e-3, 2.0), full=True)[0])
    effect = next(e for e in plan.effects if e.effect == FRICTION_EFFECT)
    (load,) = effect.parts
    hand = 4 / np.pi * 10.0 / abs(-20 * (4 * np.pi) ** 2 * 0.5e-3 + 1j * 50 * 4 * np.pi * 0.5e-3)
    assert load.label == "load" and not load.smoothed
    assert load.estimate == pytest.approx(hand, rel=0.03)
    assert not effect.omitted and effect.estimate == pytest.approx(load.estimate)
    assert plan.options.friction == "stick"
    limits = next(e for e in plan.effects if e.effect == "current and voltage limits")
    assert limits.estimate == 0 and limits.switch is None


def test_the_default_run_draws_the_current_of_the_full_model(gearmotor):
    """``simulate --study move`` (the reduced model) against ``--full --friction stick``
    (every mode; ``--full`` alone now holds too): rms current within a factor 2 (measured 2.07 A against 1.67 A after the
    start; the smooth model, which leaves the carriage's friction out, draws 4.7 A), and the
    notes say the load's friction holds, with its estimate."""
    default = simulate_study(gearmotor, "move")
    full = simulate_study(gearmotor, "move", full=True, friction="stick")
    ratio = rms_current(default) / rms_current(full)
    assert 0.5 < ratio < 2.0, (rms_current(default), rms_current(full))
    line = next(n for n in default.notes if n.startswith("friction that holds (stick) kept"))
    assert "load holds (estimate 8" in line
    options, notes = sine_run_options(gearmotor, None, None, full=True)
    assert options.friction == "stick" and "friction that holds" in notes[0]


def test_a_motor_held_below_breakaway_creeps_only_in_the_smooth_model_and_its_notes_say_so():
    """0.2 V on the stalled gearmotor (Kt V / R = 0.01 N*m, half its 0.02 N*m Coulomb level,
    a third of its 0.03 N*m breakaway): friction that holds keeps it still; the smooth model
    creeps at the speed where Tc tanh(w / 1 rad/s) = Kt (V - Ke w) / R (0.53 rad/s, a little
    below 1 rad/s * atanh(1/2) = 0.55 rad/s by the back-emf), and its notes say it creeps."""
    from scipy.optimize import brentq

    from servo_toolkit.sim import ModelOptions, simulate

    from .conftest import variant
    sc = build(variant(tomllib.loads(GEARMOTOR), motor__coulomb_friction="0.02 N*m",
                       motor__static_friction="0.03 N*m", load__coulomb_friction="0 N"))
    volts = 0.2
    runs = {f: simulate(sc, None, duration=2.0, voltage=volts, options=ModelOptions(friction=f, backlash=False))
            for f in ("stick", "smooth")}
    creep = brentq(lambda w: 0.02 * np.tanh(w) - 0.06 * (volts - 0.06 * w) / 1.2, 0.0, 5.0)
    assert np.max(np.abs(runs["stick"].motor_speed)) == 0.0
    assert runs["smooth"].motor_speed[-1] == pytest.approx(creep, rel=0.02)
    assert any("held below breakaway creeps" in n and "0.549 rad/s at half of Tc" in n for n in runs["smooth"].notes)
    assert not any("creeps" in n for n in runs["stick"].notes)


def test_a_sweep_without_stick_says_what_its_friction_costs(gearmotor):
    """A frequency sweep keeps friction that holds where the plan needs it (the carriage's
    friction, estimate over 8 at 0.2 mm); run on the smooth model given, its notes name the
    carriage's friction as left out, with that estimate over the budget, so the sweep's
    figures are not read as the actuator's."""
    from servo_toolkit.sim import ModelOptions
    from servo_toolkit.studies.sweep.compute import sweep
    assert sweep(gearmotor, frequencies=[2.0], amplitudes=[0.2e-3], progress=False).options["friction"] == "stick"
    res = sweep(gearmotor, frequencies=[2.0], amplitudes=[0.2e-3], progress=False,
                options=ModelOptions(friction="smooth"))
    line = next(n for n in res.notes if n.startswith("friction without stick"))
    est = float(line.split("load left out (estimate ")[1].split(")")[0])
    assert est > 8 and "over the budget 0.01" in line


def test_cli_reduce_shows_each_node_s_friction(capsys, tmp_path):
    """``reduce --estimate-only`` puts the friction's nodes under its row, one line each with
    its worst case in words; ``--json`` gives them as the effect's ``parts``."""
    import json

    from servo_toolkit.cli import main
    path = tmp_path / "gearmotor.toml"
    path.write_text(GEARMOTOR)
    assert main(["reduce", str(path), "--study", "move", "--estimate-only"]) == 0
    lines = capsys.readouterr().out.splitlines()
    row = next(i for i, x in enumerate(lines) if x.startswith(FRICTION_EFFECT))
    assert "kept" in lines[row] and lines[row + 1].strip().startswith("load breakaway 10 N at the output")
    assert lines[row + 2].strip().startswith("load: worst at 2 Hz, 0.5 mm") and "needs 8" in lines[row + 2]
    assert any(x.startswith("current and voltage limits") for x in lines)
    assert main(["reduce", str(path), "--study", "move", "--estimate-only", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    (fric,) = [e for e in out["effects"] if e["effect"] == FRICTION_EFFECT]
    assert [p["node"] for p in fric["parts"]] == ["load"] and fric["parts"][0]["without_stick"] == "left out"
