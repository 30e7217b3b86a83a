"""The command options wherever the controller goes: ``design --json``, the design file
(saved and loaded), the export (JSON and C helpers, fixed point checked) and the tuner's
feedforward switch."""

from __future__ import annotations

import ctypes
import json
import math
import shutil
import subprocess
from dataclasses import replace

import numpy as np
import pytest

from servo_toolkit.errors import SceneError
from servo_toolkit.export import export
from servo_toolkit.loop import design
from servo_toolkit.loop.feedforward import feedforward_gains, with_command
from servo_toolkit.loop.tuning import LoopTuning, load_design, save_design, tuned_design
from servo_toolkit.scene.loader import load_scene

from .conftest import SCENES

CC = shutil.which("gcc") or shutil.which("cc")


@pytest.fixture(scope="module")
def ema():
    scene = load_scene(SCENES / "ema_reference.toml")
    d = design(scene, progress=False)
    ctrl = with_command(d.controller, scene, feedforward="gains", schedule=True, shaper="zv")
    return scene, d, replace(d, controller=ctrl)


def test_designed_gains_are_the_closed_form(ema):
    """Ka = J / (N Kt), Kv = (b N^2 + c_L) / (N Kt), from the drivetrain's own J and N."""
    scene, d, full = ema
    g = feedforward_gains(scene, d.q0)
    n = abs(scene.drivetrain.ratio([d.q0])[0][0])
    j = scene.drivetrain.inertia([d.q0])[0][0]
    m = scene.motor
    assert g["acceleration"] == pytest.approx(j / (n * m.torque_constant), rel=1e-12)
    assert g["velocity"] == pytest.approx((m.viscous_friction * n * n + scene.load.damping) / (n * m.torque_constant),
                                          rel=1e-12)
    ff = full.controller.feedforward
    assert (ff.velocity, ff.acceleration, ff.model) == (g["velocity"], g["acceleration"], False)
    # a torque check: Ka r'' through the ratio and Kt is the torque J r'' the output needs
    assert ff.acceleration * m.torque_constant * n == pytest.approx(j, rel=1e-12)


def test_design_file_round_trip(ema, tmp_path):
    scene, _, full = ema
    path = save_design(full, tmp_path / "d.json")
    data = json.loads(path.read_text())
    assert set(data) >= {"feedforward", "schedule", "shaper"}
    back = load_design(scene, path)
    c0, c1 = full.controller, back.controller
    assert c1.feedforward == c0.feedforward and c1.shaper.times == pytest.approx(c0.shaper.times)
    np.testing.assert_allclose(c1.schedule.error_factor, c0.schedule.error_factor, rtol=1e-15)
    assert back.stroke.scheduled  # the loaded design is checked along the stroke with its schedule
    data["schedule"]["error_factor"][2] = -1.0
    path.write_text(json.dumps(data))
    with pytest.raises(SceneError) as err:
        load_design(scene, path)
    assert err.value.key == "--design" and "schedule.error_factor[2]" in err.value.rule


def test_design_json_lists_the_command_options(capsys):
    from servo_toolkit.cli import main
    assert main(["design", str(SCENES / "ema_reference.toml"), "--json", "--linear-only"]) == 0
    out = json.loads(capsys.readouterr().out)
    cmd = out["command"]
    assert cmd["feedforward_gains"]["acceleration_A_per_unit_s2"] > 0
    assert cmd["schedule"]["points"] >= 2
    zv, zvd = cmd["shapers"]["zv"], cmd["shapers"]["zvd"]
    assert zv["delay_s"] == pytest.approx(0.5 / (zv["frequency_hz"] * math.sqrt(1 - zv["damping_ratio"] ** 2)))
    assert zvd["delay_s"] == pytest.approx(2 * zv["delay_s"]) and zv["mode"] == "closed_loop"
    spread = cmd["stroke_spread"]
    assert spread["scheduled_gains"]["crossover"] < spread["fixed_gains"]["crossover"]
    assert out["controller"]["feedforward"] is None  # the design itself runs none


@pytest.mark.parametrize("fmt", [None, "q15"])
def test_export_carries_the_command_options(ema, tmp_path, fmt):
    scene, _, full = ema
    res = export(full, scene, tmp_path, fixed_point=fmt)
    data = json.loads((tmp_path / "controller.json").read_text())["command"]
    c = full.controller
    g = data["feedforward"]
    tol = 0.0 if fmt is None else 2.0**-14
    assert g["velocity_gain"] == pytest.approx(c.feedforward.velocity, rel=tol, abs=1e-300)
    assert g["acceleration_gain"] == pytest.approx(c.feedforward.acceleration, rel=tol)
    assert data["shaper"]["delays_samples"][-1] == round(c.shaper.delay / c.sample_time)
    assert data["shaper"]["residual_vibration"] < 0.02  # the delay rounded to whole samples costs little
    # fixed point checked: the exported (rounded) schedule still keeps the crossover within 5 %
    assert data["schedule"]["crossover_deviation_from_q0"] <= 0.05
    if fmt is not None:
        assert 0 < res.command.rounding["schedule"]["relative_error"] <= 2.0**-13
    if CC is None:
        return
    lib = tmp_path / "libservo.so"
    subprocess.run([CC, "-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic", "-O1", "-shared", "-fPIC", "-o",
                    str(lib), str(tmp_path / "servo_controller.c")], check=True, capture_output=True, text=True)
    so = ctypes.CDLL(str(lib))
    so.servo_feedforward_current.restype = so.servo_feedforward_speed.restype = ctypes.c_double
    so.servo_feedforward_current.argtypes = so.servo_feedforward_speed.argtypes = [ctypes.c_double] * 2
    assert so.servo_feedforward_current(0.7, -30.0) == pytest.approx(
        g["velocity_gain"] * 0.7 - 30.0 * g["acceleration_gain"], rel=1e-14)
    ratio = data["feedforward"]["ratio_table"]
    q = 0.3 * ratio["q"][2] + 0.7 * ratio["q"][3]
    assert so.servo_feedforward_speed(q, 2.0) == pytest.approx(2.0 * np.interp(q, ratio["q"], ratio["ratio"]),
                                                               rel=1e-12)
    ge, gw = ctypes.c_double(), ctypes.c_double()
    sched = data["schedule"]
    for x in (sched["q_rad"][0] - 1.0, 0.37 * sched["q_rad"][5] + 0.63 * sched["q_rad"][6], 1e3):
        so.servo_schedule(ctypes.c_double(x), ctypes.byref(ge), ctypes.byref(gw))
        assert ge.value == pytest.approx(np.interp(x, sched["q_rad"], sched["error_factor"]), rel=1e-12)
        assert gw.value == pytest.approx(np.interp(x, sched["q_rad"], sched["speed_factor"]), rel=1e-12)
    # the shaper on the sample grid: a unit step comes out as the impulses' running sum
    sh = (ctypes.c_double * (3 * (data["shaper"]["delays_samples"][-1] + 1) + 2))()
    so.servo_shaper_init(sh, ctypes.c_double(0.0))
    out = (ctypes.c_double * 3)()
    got = []
    for _ in range(data["shaper"]["delays_samples"][-1] + 3):
        so.servo_shape(sh, ctypes.c_double(1.0), ctypes.c_double(0.0), ctypes.c_double(0.0), out)
        got.append(out[0])
    want = [sum(a for a, dly in zip(data["shaper"]["amplitudes"], data["shaper"]["delays_samples"]) if k >= dly)
            for k in range(len(got))]
    np.testing.assert_allclose(got, want, rtol=1e-14)


def test_tuner_feedforward_switch(ema):
    """The tuner's feedforward switch: the linear 8 Hz tracking error falls (the gains' current
    and the speed reference)."""
    from servo_toolkit.loop.tracking import sine_tracking
    scene, d, _ = ema
    on = tuned_design(scene, LoopTuning(feedforward="gains"), base=d)
    assert on.controller.feedforward is not None and any("feedforward off -> gains" in n for n in on.notes)
    amp = math.radians(2.0)
    off_err = sine_tracking(scene, d.controller, amp, 8.0, d.q0)
    on_err = sine_tracking(scene, on.controller, amp, 8.0, d.q0)
    assert on_err["steady_error"] < 0.2 * off_err["steady_error"]
    # the frequency response and the time run agree on the steady error
    assert off_err["peak_error"] == pytest.approx(off_err["steady_error"], rel=0.05)
    with pytest.raises(SceneError):
        LoopTuning(feedforward="torque").check()
