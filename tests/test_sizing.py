"""Sizing along a duty cycle, checked against closed forms: the RMS torque of a trapezoidal
move, the two-node thermal network under a constant loss, L10 of a hand-built spectrum, the
inertia-matching ratio of a pure inertia load; and bad duty-cycle input as one line, exit 2."""

from __future__ import annotations

import copy
import json
import math
import subprocess
import sys

import numpy as np
import pytest

from servo_toolkit.errors import SceneError
from servo_toolkit.scene.loader import scene_from_dict
from servo_toolkit.studies.sizing import size
from servo_toolkit.studies.sizing.life import equivalent_load, nut_life, part_life, rating_life
from servo_toolkit.studies.sizing.thermal import ThermalNetwork, cycle_temperatures, step_response

from .conftest import ROOT, SCENES

J_M, J_L, N = 2e-4, 0.5, 20.0


def inertia_scene(segments, motor=None, **duty) -> dict:
    """A motor, a lossless gear and a pure inertia load; no friction, no limits."""
    m = {"resistance": "0.5 ohm", "torque_constant": "0.2 N*m/A", "back_emf_constant": "0.2 V*s/rad",
         "rotor_inertia": J_M}
    m.update(motor or {})
    return {"name": "inertia", "motor": m,
            "drivetrain": [{"kind": "gear", "ratio": N, "efficiency": 1.0}],
            "load": {"inertia": J_L}, "duty_cycle": {"segments": segments, **duty}}


def trapezoid_cycle(distance="60 deg", duration="0.4 s", accel="0.1 s", dwell="0.2 s"):
    return [{"kind": "ramp", "to": distance, "duration": duration, "accel_time": accel},
            {"kind": "dwell", "duration": dwell},
            {"kind": "ramp", "to": "0 deg", "duration": duration, "accel_time": accel},
            {"kind": "dwell", "duration": dwell}]


def test_rms_of_a_trapezoidal_move_is_the_closed_form():
    scene = scene_from_dict(inertia_scene(trapezoid_cycle(), start="0 deg", sample_time="0.5 ms"))
    res = size(scene, sweep=False)
    d, t, ta, dwell = math.radians(60), 0.4, 0.1, 0.2
    accel = d / ((t - ta) * ta)                      # output rad/s^2 of the trapezoid
    torque = (J_M * N + J_L / N) * accel             # motor torque while accelerating
    rms = torque * math.sqrt(4 * ta / (2 * t + 2 * dwell))   # 4 accelerating intervals per cycle
    assert res.rms_torque == pytest.approx(rms, rel=1e-9)
    assert float(np.abs(res.motor_torque).max()) == pytest.approx(torque, rel=1e-9)
    assert float(np.abs(res.motor_speed).max()) == pytest.approx(N * d / (t - ta), rel=1e-6)


def test_peaks_of_a_short_move_in_a_long_cycle_are_the_closed_form():
    # a 50 ms triangular move in a 60 s cycle: the midpoint samples miss the top speed by half a
    # sample of acceleration (6 % here); the peaks are those of the exact motion
    d, rise = math.radians(30), 0.05
    cycle = [{"kind": "step", "to": "30 deg", "duration": "0.5 s", "rise_time": f"{rise} s"},
             {"kind": "step", "to": "0 deg", "duration": "0.5 s", "rise_time": f"{rise} s"},
             {"kind": "dwell", "duration": "59 s"}]
    res = size(scene_from_dict(inertia_scene(cycle, {"voltage_limit": "1000 V"}, start="0 deg")), sweep=False)
    accel = 4 * d / rise**2
    torque, speed = (J_M * N + J_L / N) * accel, N * accel * rise / 2
    assert float(np.abs(res.motor_speed).max()) == pytest.approx(speed, rel=1e-6)
    assert res.peak_power == pytest.approx(torque * speed, rel=1e-6)
    volt = next(m for m in res.margins if m.name == "peak voltage").value
    assert volt == pytest.approx(res.envelope.hot_resistance * torque / 0.2 + 0.2 * speed, rel=1e-6)
    # the samples at the kinks weigh nothing: the RMS torque is still the closed form
    assert res.rms_torque == pytest.approx(torque * math.sqrt(2 * rise / 60.0), rel=1e-9)


def test_a_sine_in_a_long_cycle_is_resolved_period_by_period():
    # 16 periods of an 8 Hz sine in a 992 s cycle: at the cycle's 4000 samples the sine would
    # get 16, one a period, all on the zero crossings of its acceleration
    amp, f, dwell = math.radians(2), 8.0, 990.0
    cycle = [{"kind": "sine", "amplitude": "2 deg", "frequency": "8 Hz", "cycles": 16},
             {"kind": "dwell", "duration": f"{dwell} s"}]
    res = size(scene_from_dict(inertia_scene(cycle, start="0 deg")), sweep=False)
    w = 2 * math.pi * f
    peak = (J_M * N + J_L / N) * amp * w**2                   # torque at the peak acceleration
    assert res.rms_torque == pytest.approx(peak / math.sqrt(2) * math.sqrt(2.0 / (2.0 + dwell)), rel=1e-9)
    assert float(np.abs(res.motor_torque).max()) == pytest.approx(peak, rel=1e-12)
    assert float(np.abs(res.motor_speed).max()) == pytest.approx(N * amp * w, rel=1e-12)


def test_a_sine_of_more_periods_than_the_samples_of_a_cycle_is_one_line(tmp_path):
    cycle = [{"kind": "sine", "amplitude": "1 deg", "frequency": "100 Hz", "cycles": 80000}]
    with pytest.raises(SceneError) as info:
        scene_from_dict(inertia_scene(cycle, start="0 deg"), str(tmp_path / "s.toml"))
    assert info.value.key == "duty_cycle.segments[0].cycles" and "32" in str(info.value)


def test_regenerated_energy_of_a_decelerating_inertia_is_the_closed_form():
    # each deceleration of the trapezoid returns Ke w I - R I^2 while the back-EMF outweighs
    # the copper loss; the winding cold (at the ambient, where R is given): the most returned
    scene = scene_from_dict(inertia_scene(trapezoid_cycle(), start="0 deg"))
    res = size(scene, sweep=False)
    d, t, ta, r, k = math.radians(60), 0.4, 0.1, 0.5, 0.2
    current = (J_M * N + J_L / N) * d / ((t - ta) * ta) / k
    top = N * d / (t - ta)
    until = ta * (1 - r * current / (k * top))        # back-EMF power = copper loss there
    energy = k * current * top * (until - until**2 / (2 * ta)) - r * current**2 * until
    assert res.regenerated_energy == pytest.approx(2 * energy, rel=1e-4)


def test_a_scene_without_limits_says_it_judged_nothing():
    res = size(scene_from_dict(inertia_scene(trapezoid_cycle(), start="0 deg")), sweep=False)
    assert res.margins == () and "no limit to size against" in res.table()


def test_rms_optimal_ratio_is_the_inertia_matching_ratio():
    scene = scene_from_dict(inertia_scene(trapezoid_cycle(), start="0 deg", ratio_range=[0.1, 10.0],
                                          ratio_points=201))
    sweep = size(scene).sweep
    assert sweep.rms_optimal_ratio[0] == pytest.approx(math.sqrt(J_L / J_M), rel=1e-9)
    best = sweep.ratio[np.argmin(sweep.rms_torque[0])]
    assert best == pytest.approx(math.sqrt(J_L / J_M), rel=0.03)   # the grid's spacing


def _network_closed_form(net: ThermalNetwork, power: float, t):
    """Winding rise of the two-node network under constant loss, by hand: x' = A x + b."""
    cw, ch = net.tau_w / net.r_wh, net.tau_h / net.r_ha
    a = np.array([[-1 / (net.r_wh * cw), 1 / (net.r_wh * cw)],
                  [1 / (net.r_wh * ch), -(1 / net.r_wh + 1 / net.r_ha) / ch]])
    lam, vec = np.linalg.eig(a)
    steady = np.array([power * (net.r_wh + net.r_ha), power * net.r_ha])
    coef = np.linalg.solve(vec, -steady)       # x(0) = 0
    return steady[0] + (vec[0] * coef * np.exp(np.outer(t, lam))).sum(axis=1), -1 / lam


def test_rms_optimal_ratio_under_a_load_torque_is_the_closed_form():
    # T = (J_L a + T_L) / n + J_m n a is smallest in RMS at n*^2 = rms(J_L a + T_L) / (J_m rms(a))
    segments = trapezoid_cycle()
    for seg, load in zip(segments, ("30 N*m", "30 N*m", "-30 N*m", "0 N*m")):
        seg["load"] = load
    res = size(scene_from_dict(inertia_scene(segments, start="0 deg", ratio_range=[0.1, 10.0], ratio_points=3)))
    m = res.motion
    d, t, ta, dwell = math.radians(60), 0.4, 0.1, 0.2
    a = d / ((t - ta) * ta)
    # mean square over the cycle of J_L a + T_L, piece by piece: (J_L a + T_L)^2 over each
    # acceleration (+a, -a on the way out under +30, -a, +a back under -30) and T_L^2 elsewhere
    total = 2 * t + 2 * dwell
    out = ta * ((J_L * a + 30) ** 2 + (J_L * a - 30) ** 2) + (t - 2 * ta) * 30**2 + dwell * 30**2
    back = ta * ((-J_L * a - 30) ** 2 + (J_L * a - 30) ** 2) + (t - 2 * ta) * 30**2
    ms_load, ms_accel = (out + back) / total, 4 * ta * a**2 / total
    assert res.sweep.rms_optimal_ratio[0] == pytest.approx((ms_load / (J_M**2 * ms_accel)) ** 0.25, rel=1e-9)
    assert m.mean(m.qdd**2) == pytest.approx(ms_accel, rel=1e-12)


def test_constant_loss_settles_at_p_times_r_th_with_the_networks_time_constants():
    net = ThermalNetwork(r_wh=0.2, r_ha=0.5, tau_w=40.0, tau_h=900.0, ambient=30.0)
    t = np.array([1.0, 10.0, 60.0, 600.0, 3000.0, 30000.0])
    expected, taus = _network_closed_form(net, 100.0, t)
    assert step_response(net, 100.0, t) - 30.0 == pytest.approx(expected, rel=1e-9)
    assert step_response(net, 100.0, [1e6])[0] == pytest.approx(30.0 + 100.0 * 0.7, rel=1e-12)
    assert sorted(taus)[1] > 900.0 > 40.0 > sorted(taus)[0]   # the coupled network's two time constants
    # a constant current over a cycle: the same steady state, no copper-coefficient
    res = cycle_temperatures(net, np.full(100, 10.0), np.full(100, 0.01))   # R = 1 ohm: 100 W
    assert res.peak_winding == pytest.approx(30.0 + 70.0, rel=1e-9)
    assert res.winding_at_cycle_end[-1] == pytest.approx(100.0, abs=0.1)


def test_resistance_rising_with_temperature_heats_more_and_can_run_away():
    base = dict(r_wh=0.2, r_ha=0.5, tau_w=40.0, tau_h=900.0, ambient=30.0, resistance_temperature=30.0)
    cold = cycle_temperatures(ThermalNetwork(**base), np.full(10, 10.0), np.full(10, 0.1)).peak_winding
    hot = ThermalNetwork(**base, alpha=0.004)
    warm = cycle_temperatures(hot, np.full(10, 10.0), np.full(10, 0.1)).peak_winding
    # steady state of P = I^2 R0 (1 + alpha x) with x = P R_th: x = I^2 R0 R_th / (1 - alpha I^2 R0 R_th)
    assert cold == pytest.approx(100.0, rel=1e-9)
    assert warm == pytest.approx(30.0 + 70.0 / (1 - 0.004 * 70.0), rel=1e-9)
    runaway = cycle_temperatures(hot, np.full(10, 20.0), np.full(10, 0.1))   # alpha I^2 R0 R_th = 1.12
    assert runaway.runaway and runaway.peak_winding == math.inf


def test_a_runaway_that_overflows_is_a_runaway_without_warnings():
    """A current so large that the winding's growth over one interval exceeds e^709 (a load
    damping at the end of its range along a duty cycle): the cycle map overflows; that is a
    runaway (alpha I^2 R0 > 1 / R_wh: the winding alone heats without bound), not an error."""
    import warnings

    from servo_toolkit.studies.sizing.thermal import periodic_peak
    base = dict(r_wh=0.2, r_ha=0.5, tau_w=40.0, tau_h=900.0, ambient=30.0, resistance_temperature=30.0)
    hot = ThermalNetwork(**base, alpha=0.004)
    current = 1e5  # alpha I^2 R0 R_wh = 8e6; growth rate (alpha I^2 R0 - 1/R_wh) / C_w = 4e6 1/s
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        res = cycle_temperatures(hot, np.full(10, current), np.full(10, 0.1))
        peaks = periodic_peak(hot, np.array([[1.0] * 8, [current] * 8]), 0.1)
    assert res.runaway and res.peak_winding == math.inf
    assert math.isfinite(peaks[0]) and peaks[1] == math.inf


def test_l10_of_a_hand_built_spectrum():
    forces, revs = [10e3, -5e3, 2e3], [1e5, 3e5, 6e5]
    fm = ((10e3**3 * 1e5 + 5e3**3 * 3e5 + 2e3**3 * 6e5) / 1e6) ** (1 / 3)
    assert equivalent_load(forces, revs) == pytest.approx(fm, rel=1e-12)
    assert rating_life(30e3, fm) == pytest.approx((30e3 / fm) ** 3 * 1e6, rel=1e-12)
    life = part_life("screw", 30e3, forces, revs, cycle_duration=3600.0)   # 1e6 revolutions per hour
    assert life.hours == pytest.approx((30e3 / fm) ** 3, rel=1e-12)
    roller = part_life("bearing", 30e3, forces, revs, 3600.0, exponent=10 / 3)
    fm_r = ((10e3 ** (10 / 3) * 1e5 + 5e3 ** (10 / 3) * 3e5 + 2e3 ** (10 / 3) * 6e5) / 1e6) ** 0.3
    assert roller.revolutions == pytest.approx((30e3 / fm_r) ** (10 / 3) * 1e6, rel=1e-12)


def test_a_single_nut_loaded_both_ways_lives_by_direction():
    """ISO 3408-5, a nut with backlash: each direction's F_m over every revolution of the cycle,
    its life, and the two combined as L = (L+^(-10/9) + L-^(-10/9))^(-9/10)."""
    forces, revs, c = [10e3, -5e3, 2e3], [1e5, 3e5, 6e5], 30e3
    f_plus = ((10e3**3 * 1e5 + 2e3**3 * 6e5) / 1e6) ** (1 / 3)
    f_minus = ((5e3**3 * 3e5) / 1e6) ** (1 / 3)
    l_plus, l_minus = (c / f_plus) ** 3 * 1e6, (c / f_minus) ** 3 * 1e6
    combined = (l_plus ** (-10 / 9) + l_minus ** (-10 / 9)) ** (-9 / 10)
    life = nut_life("nut", c, forces, revs, cycle_duration=3600.0)     # 1e6 revolutions per hour
    assert life.direction_loads == pytest.approx((f_plus, f_minus), rel=1e-12)
    assert life.revolutions == pytest.approx(combined, rel=1e-12)
    assert life.hours == pytest.approx(combined / 1e6, rel=1e-12)
    assert rating_life(c, life.equivalent_load) == pytest.approx(combined, rel=1e-12)
    # one direction only: the lumped spectrum's life; the same spectrum both ways: 2^(1/10) of it
    one = [10e3, 5e3, 2e3]
    assert nut_life("nut", c, one, revs, 3600.0).revolutions == pytest.approx(
        part_life("nut", c, one, revs, 3600.0).revolutions, rel=1e-12)
    both = nut_life("nut", c, [4e3, -4e3], [1e5, 1e5], 3600.0).revolutions
    assert both == pytest.approx(2 ** 0.1 * part_life("nut", c, [4e3, 4e3], [1e5, 1e5], 3600.0).revolutions,
                                 rel=1e-12)


def test_reference_ema_sizes_every_quantity_against_its_limit():
    res = size(SCENES / "ema_sizing.toml")
    names = [m.name for m in res.margins]
    assert names[:5] == ["peak torque", "RMS torque", "peak current", "peak voltage", "winding temperature"]
    assert any(n.startswith("L10") and "screw" in n for n in names) and any("bearing" in n for n in names)
    assert res.passed and res.regenerated_energy > 0
    # the winding stays between the ambient and the limit, and the dwell at the hinge moment holds a torque
    assert 40 < res.thermal.peak_winding - 273.15 < 155
    sweep = res.sweep
    lo, hi = sweep.feasible_range()
    assert lo < sweep.ratio[np.argmin(np.abs(sweep.factors - 1))] < hi   # the scene's ratio is feasible
    text = json.dumps(res.to_dict())
    assert "NaN" not in text and "Infinity" not in text
    assert repr(res).startswith("<SizingResult: ema_sizing: PASS") and "st-card" in res._repr_html_()


def test_points_from_a_csv_give_the_ramp_they_sample(tmp_path):
    from servo_toolkit.studies.sizing.cycle import trapezoid
    t = np.linspace(0.0, 0.4, 401)
    q, _, _ = trapezoid(math.radians(60), 0.4, 0.2, t)           # triangular: smooth enough to spline
    (tmp_path / "move.csv").write_text("t [ms], angle [deg]\n" + "".join(
        f"{a * 1e3:.6f}, {math.degrees(b):.9f}\n" for a, b in zip(t, q)))
    back = [{"kind": "ramp", "to": "0 deg", "duration": "0.4 s", "accel_time": "0.2 s"}]
    ramp = [{"kind": "ramp", "to": "60 deg", "duration": "0.4 s", "accel_time": "0.2 s"}] + back
    points = [{"kind": "points", "file": "move.csv"}] + back
    scene_file = tmp_path / "s.toml"
    a = size(scene_from_dict(inertia_scene(ramp, start="0 deg")), sweep=False)
    b = size(scene_from_dict(inertia_scene(points, start="0 deg"), str(scene_file)), sweep=False)
    assert b.motion.duration == pytest.approx(a.motion.duration)
    assert b.rms_torque == pytest.approx(a.rms_torque, rel=0.02)



def test_a_points_segment_lasts_the_span_of_its_times(tmp_path):
    """A points file whose times start at 2 s lasts its 0.4 s span (its first point starts
    the segment), as the scene reference says."""
    from servo_toolkit.scene.duty_cycle import duty_cycle_from_table
    (tmp_path / "move.csv").write_text("t [s], angle [deg]\n2.0, 0\n2.2, 5\n2.4, 0\n")
    cycle = duty_cycle_from_table({"segments": [{"kind": "points", "file": "move.csv"}]},
                                  source=str(tmp_path / "s.toml"))
    assert cycle.segments[0].duration == pytest.approx(0.4)


BAD = [
    ({"segments": [{"kind": "jump", "duration": "1 s"}]}, "duty_cycle.segments[0].kind"),
    ({"segments": [{"kind": "ramp", "duration": "1 s"}]}, "duty_cycle.segments[0].to"),
    ({"segments": [{"kind": "dwell", "duration": "1 s", "to": "3 deg"}]}, "duty_cycle.segments[0].to"),
    ({"segments": [{"kind": "dwell", "duration": "1 s", "lod": 3}]}, "duty_cycle.segments[0].lod"),
    ({"segments": [{"kind": "dwell", "duration": "-1 s"}]}, "duty_cycle.segments[0].duration"),
    ({"segments": [{"kind": "dwell", "duration": "1 m"}]}, "duty_cycle.segments[0].duration"),
    ({"segments": [{"kind": "ramp", "to": "10 deg", "duration": "1 s"}]}, "duty_cycle.segments[0]"),
    ({"segments": [{"kind": "ramp", "to": "400 deg", "duration": "1 s"},
                   {"kind": "ramp", "to": "0 deg", "duration": "1 s"}]}, "duty_cycle.segments[0].to"),
    ({"segments": [{"kind": "ramp", "to": "1 deg", "duration": "1 s", "accel_time": "0.8 s"}]},
     "duty_cycle.segments[0].accel_time"),
    ({"segments": [{"kind": "sine", "amplitude": "1 deg"}]}, "duty_cycle.segments[0].frequency"),
    ({"segments": [{"kind": "points", "file": "missing.csv"}]}, "duty_cycle.segments[0].file"),
    ({"segments": []}, "duty_cycle.segments"),
    ({"segments": [{"kind": "dwell", "duration": "1 s"}], "ratio_range": [2, 1]}, "duty_cycle.ratio_range"),
    ({"segments": [{"kind": "dwell", "duration": "1 s"}], "motors": [{"name": "m2"}]}, "duty_cycle.motors[0]"),
    ({"segments": [{"kind": "dwell", "duration": "1 s", "load": "3 N"}]}, "duty_cycle.segments[0].load"),
]


@pytest.mark.parametrize("duty, key", BAD)
def test_bad_duty_cycle_is_one_line_naming_the_key(duty, key, tmp_path):
    data = inertia_scene([])
    data["duty_cycle"] = copy.deepcopy(duty)
    with pytest.raises(SceneError) as info:
        scene_from_dict(data, str(tmp_path / "s.toml"))
    assert str(info.value.key).startswith(key), str(info.value)



def test_cli_size_exit_codes(tmp_path):
    env_cwd = dict(cwd=ROOT, capture_output=True, text=True, timeout=300)
    figure = tmp_path / "sweep.png"
    run = subprocess.run([sys.executable, "-m", "servo_toolkit", "size", "scenes/ema_sizing.toml", "--json",
                          "--sweep-plot", str(figure)], **env_cwd)
    assert run.returncode == 0, run.stderr
    payload = json.loads(run.stdout)
    assert payload["passed"] and payload["sweep"]["swept"] == "ratio of spur gear train"
    assert figure.read_bytes().startswith(b"\x89PNG")
    text = (SCENES / "ema_sizing.toml").read_text()
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace('kind = "ramp"\nto = "30 deg"', 'kind = "ramp"\nto = "30 deg"\nspeed = 3', 1))
    run = subprocess.run([sys.executable, "-m", "servo_toolkit", "size", str(bad)], **env_cwd)
    assert run.returncode == 2 and run.stdout == ""
    assert run.stderr.count("\n") == 1 and "duty_cycle.segments[0].speed" in run.stderr
    short = tmp_path / "short.toml"
    short.write_text(text.replace('required_life = "1000 h"', 'required_life = "1000000 h"'))
    run = subprocess.run([sys.executable, "-m", "servo_toolkit", "size", str(short), "--no-sweep"], **env_cwd)
    assert run.returncode == 1 and "EXCEEDED" in run.stdout
    run = subprocess.run([sys.executable, "-m", "servo_toolkit", "size", "scenes/ema_robust.toml"], **env_cwd)
    assert run.returncode == 2 and run.stderr.startswith("servo-toolkit: error: duty_cycle")


def test_cli_sweep_plot_needs_the_sweep(tmp_path, capsys):
    from servo_toolkit.cli import main
    figure = tmp_path / "sweep.png"
    assert main(["size", str(SCENES / "ema_sizing.toml"), "--no-sweep", "--sweep-plot", str(figure)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--sweep-plot" in err and not figure.exists()


def test_the_envelope_brakes_with_the_back_emf_on_the_supplys_side():
    # braking, |R i - Ke w| <= V allows Kt (V + Ke |w|) / R: at the no-load speed V / Ke the
    # motor still brakes with its peak torque, where motoring it has none left
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    motor = {"voltage_limit": "48 V", "current_limit": "20 A"}
    res = size(scene_from_dict(inertia_scene(trapezoid_cycle(), motor, start="0 deg")), sweep=False)
    env = res.envelope
    top = env.voltage_limit / env.back_emf_constant
    assert env.voltage_torque(top) == pytest.approx(0.0, abs=1e-12)
    assert env.braking_torque(top) == pytest.approx(0.2 * 2 * 48 / env.hot_resistance, rel=1e-12)
    fig, ax = plt.subplots()
    res.plot_torque_speed(ax)
    edges = [line for line in ax.lines if line.get_linestyle() == "-" and len(line.get_xdata()) > 2]
    ends = {(float(np.sign(line.get_xdata()[-1])), float(np.sign(line.get_ydata()[0]))): line.get_ydata()[-1]
            for line in edges}
    assert ends[(1.0, 1.0)] < 0.1 * env.peak_torque and ends[(-1.0, -1.0)] > -0.1 * env.peak_torque
    assert ends[(1.0, -1.0)] == pytest.approx(-env.peak_torque) and ends[(-1.0, 1.0)] == pytest.approx(env.peak_torque)
    plt.close(fig)
