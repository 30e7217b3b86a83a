"""A position loop against static friction: hunting with integral action (amplitude and period
against an independent event-driven solution and the describing-function estimate), rest
inside the dead band without it, and the study that reports both."""

import json
import math
from dataclasses import replace

import control as ct
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from servo_toolkit.components.compliance import Load
from servo_toolkit.components.gear import GearTrain
from servo_toolkit.components.motor import DCMotor
from servo_toolkit.loop.controller import MOTION_INPUTS, MOTION_OUTPUTS, CascadeController
from servo_toolkit.scene.loader import Scene
from servo_toolkit.sim import ModelOptions, Reference, build_model, run
from servo_toolkit.studies.hunting import analyse, dead_band, rest_study

KT, R, N = 0.2, 0.5, 10.0
TC, TS, B = 0.02, 0.05, 1e-4          # Coulomb, breakaway (motor shaft, N*m), viscous
STEP = 0.01                            # output rad
W0, ZETA = 60.0, 0.5                   # the PD part: natural frequency (rad/s) and damping
OPTIONS = ModelOptions(friction="stick", controller_mode="continuous", quantization=False, efficiency=False)


def scene():
    motor = DCMotor(resistance=R, inductance=0.0, torque_constant=KT, back_emf_constant=KT, rotor_inertia=2e-4,
                    viscous_friction=B, coulomb_friction=TC, static_friction=TS, stribeck_speed=0.0,
                    voltage_limit=100.0, current_limit=50.0)
    return Scene("hunting", motor=motor, stages=(GearTrain("gear", ratio=N, inertias=(1e-5, 1e-3)),),
                 load=Load(inertia=0.05))


def gains(sc, integral):
    """PID on the output angle, its D part on the motor speed: i = kp e + ki int(e) - kd w_m.
    Returns (J at the motor, kp [A/rad], ki [A/(rad s)], kd [A s/rad])."""
    j = float(sc.drivetrain.inertia([0.0])[0][0]) / N**2
    kp = j * W0**2 * N / KT
    kd = (2 * ZETA * W0 * j - B) / KT
    return j, kp, integral * kp, kd


def controller(kp, ki, kd):
    motion = ct.ss([[0.0]], [[1.0, -1.0, 0.0]], [[ki]], [[kp, -kp, -kd]],
                   inputs=list(MOTION_INPUTS), outputs=list(MOTION_OUTPUTS))
    return CascadeController(motion=motion, current_kp=0.0, current_ki=0.0, sample_time=0.0)


def stick_slip(t_end, y0, applied, extra, inertia, tc, ts):
    """Event-driven solution of J x'' = a(t, y) - F on y = [x, v, *w], w' = extra(t, y), by
    pieces: sliding, F = Tc sign(v) until v = 0 (an event), where the node sticks if |a| <= Ts
    and slides on otherwise; stuck, x and v are frozen until |a| reaches Ts (an event).
    Returns the pieces (t_start, t_end, stuck, dense solution)."""
    pieces, t, y, s = [], 0.0, np.asarray(y0, float), 0.0
    while t < t_end:
        if s == 0.0 and abs(applied(t, y)) > ts:
            s = math.copysign(1.0, applied(t, y))
        if s == 0.0:
            def f(tt, yy):
                return np.concatenate([[0.0, 0.0], extra(tt, yy)])

            def up(tt, yy):
                return applied(tt, yy) - ts

            def down(tt, yy):
                return applied(tt, yy) + ts
            up.terminal = down.terminal = True
            up.direction, down.direction = 1.0, -1.0
            events = [up, down]
        else:
            def f(tt, yy, sign=s):
                return np.concatenate([[yy[1], (applied(tt, yy) - sign * tc) / inertia], extra(tt, yy)])

            def stop(tt, yy):
                return yy[1]
            stop.terminal, stop.direction = True, -s
            events = [stop]
        sol = solve_ivp(f, (t, t_end), y, method="DOP853", events=events, dense_output=True, rtol=1e-10, atol=1e-13)
        assert sol.status >= 0
        pieces.append((t, sol.t[-1], s == 0.0, sol.sol))
        if sol.status == 0:
            break
        t, y = sol.t[-1], sol.y[:, -1].copy()
        if s != 0.0:
            y[1] = 0.0
            a = applied(t, y)
            s = 0.0 if abs(a) <= ts else math.copysign(1.0, a)
        else:
            s = math.copysign(1.0, applied(t, y))
    return pieces


def sample(pieces, times):
    out = np.full((len(times), pieces[0][3](pieces[0][0]).size), np.nan)
    for a, b, _, sol in pieces:
        m = (times >= a) & (times <= b)
        if m.any():
            out[m] = sol(times[m]).T
    return out


def event_driven(sc, kp, ki, kd, t_end):
    """The loop of :func:`controller` on the rigid geared scene at the motor shaft: x the motor
    angle, z the integral of the output error."""
    j = gains(sc, 0.0)[0]

    def applied(t, y):
        return KT * (kp * (STEP - y[0] / N) + ki * y[2] - kd * y[1]) - B * y[1]
    return stick_slip(t_end, [0.0, 0.0, 0.0], applied, lambda t, y: [STEP - y[0] / N], j, TC, TS)


def describing_function_estimate(j, kp, ki, kd):
    """Harmonic balance G(jw) N(U) = -1 with G(s) = Kt ki / (N s) (the integral part, from
    the motor angle to the torque it applies) and N(U) the describing function of the rest of
    the loop from that torque to the motor angle: the shaft with static friction Ts, Coulomb
    friction Tc, the PD loop's stiffness K = Kt kp / N and damping c = B + Kt kd. Quasi-static
    (each slip short against the integral's change): the shaft sticks until the net moment
    U sin(wt) - K x reaches Ts and then slips like a mass on the spring K from rest under
    Ts - Tc, stopping at the first overshoot, the net moment down to
    h = Tc - (Ts - Tc) exp(-zeta pi / sqrt(1 - zeta^2)). The phase -90 deg that G asks of N
    is met at the onset, one jump per half period at the peak of U sin: x is then a square wave
    of amplitude x0 = (Ts - h) / (2 K) in quadrature with U sin, U = Ts - K x0, and
    |N| = 4 x0 / (pi U) = w / |G(jw)| w. Returns (amplitude at the output [rad], period [s])."""
    k, c = KT * kp / N, B + KT * kd
    zeta = c / (2 * math.sqrt(k * j))
    h = TC - (TS - TC) * math.exp(-zeta * math.pi / math.sqrt(1 - zeta**2))
    x0 = (TS - h) / (2 * k)
    u = TS - k * x0
    w = (KT * ki / N) * 4 * x0 / (math.pi * u)
    return x0 / N, 2 * math.pi / w


def reference_hunting(pieces, t_from):
    """Period (mean interval between breakaways in the same direction) and amplitude (half
    the output's peak-to-peak over the last period) of the event-driven solution."""
    breaks = [b for a, b, stuck, _ in pieces if stuck and a >= t_from and b < pieces[-1][1]]
    same = breaks[-1::-2][::-1]
    period = float(np.mean(np.diff(same)))
    t = np.linspace(same[-2], same[-1], 20001)
    return 0.5 * float(np.ptp(sample(pieces, t)[:, 0])) / N, period


@pytest.fixture(scope="module")
def hunting_runs():
    sc = scene()
    j, kp, ki, kd = gains(sc, integral=25.0)
    model = build_model(sc, controller(kp, ki, kd), OPTIONS)
    assert model.rigid
    res = run(model, Reference.step(STEP), 2.0, method="rk4", dt=1e-5, output_dt=1e-4)
    return sc, (j, kp, ki, kd), res, event_driven(sc, kp, ki, kd, 2.0)


def test_a_pid_position_loop_hunts_as_the_event_driven_solution_does(hunting_runs):
    """Integral action against Ts > Tc: the compiled model's limit cycle has the event-driven
    solution's amplitude and period to 1e-3 (the records are 0.1 ms apart)."""
    sc, _, res, pieces = hunting_runs
    found = analyse(res)
    assert found.hunting is not None and found.hunting.cycles >= 2
    amp, period = reference_hunting(pieces, 1.0)
    assert found.hunting.period == pytest.approx(period, rel=1e-3)
    assert found.hunting.amplitude == pytest.approx(amp, rel=1e-3)
    # the whole trace, not only its summary
    t = res.times
    ref = sample(pieces, t)[:, 0] / N
    assert np.max(np.abs(res.output_angle - ref)) < 1e-2 * amp
    # while hunting the output sticks on either side of the command, never on it
    assert abs(found.position_error_at_rest) == pytest.approx(amp, rel=2e-2)


def test_the_hunting_agrees_with_the_describing_function_estimate(hunting_runs):
    """The quasi-static describing function (harmonic balance of the integral part against the
    stick-slip of the rest of the loop) predicts amplitude and period to 25 % (here -14 % and +10 %): it leaves out
    the integral's change during each slip and the harmonics of the square-wave motion (a
    describing function is an estimate; Armstrong and Amin 1996 show how far it may miss)."""
    sc, (j, kp, ki, kd), res, _ = hunting_runs
    found = analyse(res).hunting
    amp, period = describing_function_estimate(j, kp, ki, kd)
    assert found.amplitude == pytest.approx(amp, rel=0.25)
    assert found.period == pytest.approx(period, rel=0.25)


def test_without_integral_action_the_loop_rests_inside_the_dead_band():
    """PD only: the output stops for good where Kt kp |e| <= Ts (the closed-form dead band,
    |e| <= Ts / (Kt kp) at the output) at the event-driven solution's rest error; no hunting."""
    sc = scene()
    j, kp, _, kd = gains(sc, integral=0.0)
    model = build_model(sc, controller(kp, 0.0, kd), OPTIONS)
    res = run(model, Reference.step(STEP), 0.5, method="rk4", dt=1e-5, output_dt=1e-4)
    found = analyse(res)
    assert found.hunting is None and found.at_rest
    assert np.all(res.motor_speed[res.times > 0.25] == 0.0)
    band = TS / (KT * kp)
    assert dead_band(sc, controller(kp, 0.0, kd)) == pytest.approx(band, rel=1e-9)
    assert 0.0 < abs(found.position_error_at_rest) <= band
    pieces = event_driven(sc, kp, 0.0, kd, 0.5)
    assert pieces[-1][2]  # the reference ends stuck too
    rest = STEP - sample(pieces, np.array([0.5]))[0, 0] / N
    assert found.position_error_at_rest == pytest.approx(rest, rel=1e-6)


def test_the_rest_study_reports_hunting_and_stick_phases(hunting_runs):
    """The study runs the step with friction that holds whatever options it is given and
    reports the error at rest, the hunting and the stick phases (JSON, repr, card)."""
    sc, (j, kp, ki, kd), _, _ = hunting_runs
    r = rest_study(sc, controller(kp, ki, kd), step=STEP, duration=1.0, dt=1e-5,
                   options=ModelOptions(friction="smooth", controller_mode="continuous", quantization=False,
                                        efficiency=False))
    assert r.hunting is not None and len(r.stick_phases) >= 4
    # the integral adds no stiffness at rest: the band is the proportional path's
    assert r.dead_band == pytest.approx(TS / (KT * kp), rel=1e-6)
    assert all(b > a for a, b in r.stick_phases)
    d = json.loads(json.dumps(r.to_dict()))
    assert d["hunting"]["period_s"] == pytest.approx(r.hunting.period)
    assert d["position_error_at_rest_deg"] == pytest.approx(math.degrees(r.position_error_at_rest))
    assert d["dead_band_deg"] == pytest.approx(math.degrees(r.dead_band))
    assert "hunting amplitude" in repr(r) and "<table>" in r._repr_html_()
    smooth = rest_study(sc, controller(kp, 0.0, kd), step=STEP, duration=0.5, dt=1e-5,
                        options=ModelOptions(controller_mode="continuous", quantization=False, efficiency=False))
    assert smooth.hunting is None and smooth.at_rest and "moving" not in repr(smooth)


def test_the_time_section_rows_say_the_rest_and_the_hunting(hunting_runs):
    """The report's rows: the error at rest in the shown unit (the largest while hunting) and
    the hunting's amplitude and period, or none."""
    from servo_toolkit.core.output_units import OutputUnit
    from servo_toolkit.report.sections_time import rest_rows
    _, _, res, _ = hunting_runs
    found = analyse(res)
    rows = dict(rest_rows(found, OutputUnit("rad")))
    hunt = rows["hunting (amplitude [deg], period [ms])"]
    assert f"period {found.hunting.period * 1e3:.4g} ms" in hunt
    assert f"amplitude {math.degrees(found.hunting.amplitude):.4g} deg" in hunt
    assert rows["position error at rest [deg]"].startswith(f"{math.degrees(found.position_error_at_rest):.4g}")
    assert "largest while hunting" in rows["position error at rest [deg]"]
    assert rows["dead band of the proportional path [deg]"] == "none (no proportional stiffness)"
    rows = dict(rest_rows(replace(found, dead_band=TS / (KT * 100.0)), OutputUnit("rad")))
    assert rows["dead band of the proportional path [deg]"] == f"+-{math.degrees(TS / (KT * 100.0)):.4g}"


def test_the_report_shades_the_stick_phases_and_the_design_says_what_the_plant_leaves_out():
    """The shipped EMA: the time section runs the step with friction that holds, tables its
    rest and hunting and shades each stick phase on the step plot; the design's notes say the
    linear plant keeps viscous friction only."""
    import re

    from servo_toolkit import load_scene
    from servo_toolkit.plant.linear import friction_note
    from servo_toolkit.report import run_section
    from servo_toolkit.report.context import Context
    from servo_toolkit.report.sections_time import time_responses

    from .conftest import SCENES
    ema = load_scene(SCENES / "ema_reference.toml")
    ctx = Context(ema, light=True)
    sec = run_section("time", "time", time_responses, ctx)
    assert sec.status == "info", sec.reason
    table = re.search(r'<table id="rest-table">(.*?)</table>', sec.html, re.S).group(1)
    cells = dict(re.findall(r"<tr><td>([^<]+)</td><td>([^<]+)</td></tr>", table))
    assert set(cells) == {"dead band of the proportional path [deg]", "position error at rest [deg]",
                          "hunting (amplitude [deg], period [ms])", "time stuck (speed exactly 0)"}
    assert cells["dead band of the proportional path [deg]"].startswith("+-")
    phases = int(re.search(r"\((\d+) stick phases\)", cells["time stuck (speed exactly 0)"]).group(1))
    step_axes = sec.figures[0].figure.axes[0]
    stuck = [p for p in step_axes.patches if p.get_facecolor()[:3] == (0.85, 0.85, 0.85)]
    assert phases >= 1 and len(stuck) == phases
    assert any(p.get_label() == "dead band (proportional path)" for p in step_axes.patches)
    assert any(n.startswith("linear plant: viscous friction only") for n in ctx.design().notes)
    assert "Coulomb friction 0.02 N*m" in friction_note(ema)[0]
    assert "static 0.05 N*m" in friction_note(scene())[0]
    bare = scene()
    bare = type(bare)("bare", motor=replace(bare.motor, coulomb_friction=0.0, static_friction=None),
                      stages=bare.stages, load=bare.load)
    assert friction_note(bare) == ()


def test_the_reference_solver_stops_on_the_same_events(hunting_runs):
    """The toolkit's stiff reference (solve_ivp restarted at each friction event, the
    continuous controller integrated with it) follows the event-driven solution through a
    reversal, a stick and a breakaway, with output records sparser than the events."""
    sc, (j, kp, ki, kd), _, pieces = hunting_runs
    model = build_model(sc, controller(kp, ki, kd), OPTIONS)
    ref = run(model, Reference.step(STEP), 0.3, "reference", output_dt=1e-3, rtol=1e-9, atol=1e-12)
    stuck = [(a, b) for a, b, s, _ in pieces if s and b < 0.3]
    assert len(stuck) >= 1 and np.any(ref.motor_speed == 0.0)
    q = sample(pieces, ref.times)[:, 0] / N
    assert np.max(np.abs(ref.output_angle - q)) < 1e-7 * STEP


def test_a_stick_slip_that_dies_out_is_rest_not_hunting(hunting_runs):
    """Cut the hunting run where a stick phase has lasted longer than a period (the last
    records held at the stuck state): the analysis calls that rest, at the stuck error."""
    from dataclasses import replace as dc_replace
    _, _, res, _ = hunting_runs
    found = analyse(res)
    period = found.hunting.period
    keep = res.times <= found.stick_phases[-2][1]  # ends inside the second-to-last stick phase
    n_hold = int(1.5 * period / (res.times[1] - res.times[0]))
    states = np.concatenate([res.states[keep], np.repeat(res.states[keep][-1:], n_hold, axis=0)])
    times = np.concatenate([res.times[keep], res.times[keep][-1] + (res.times[1] - res.times[0])
                            * np.arange(1, n_hold + 1)])
    cut = dc_replace(res, times=times, states=states,
                     reference_angle=np.full(times.size, res.reference_angle[-1]),
                     motor_speed=np.concatenate([res.motor_speed[keep], np.zeros(n_hold)]))
    rested = analyse(cut)
    assert rested.hunting is None and rested.at_rest
    assert rested.position_error_at_rest == pytest.approx(cut.reference_angle[-1] - cut.output_angle[-1])


def test_a_run_still_moving_at_its_end_shows_the_figure_check_judges(hunting_runs):
    """Where the output is not held by friction at the run's end, the report's rest row leads
    with check's ``position_error_at_rest`` figure of the same run (the largest error after
    the motion) and then says it still moves, instead of a bare "not at rest" beside a met row."""
    from servo_toolkit.core.output_units import OutputUnit
    from servo_toolkit.report.sections_time import rest_rows
    _, _, res, _ = hunting_runs
    moving = replace(analyse(res), position_error_at_rest=None, hunting=None)
    judged = (math.radians(6.6e-6), "largest over 750-1000 ms after the step")
    row = dict(rest_rows(moving, OutputUnit("rad"), judged))["position error at rest [deg]"]
    assert row.startswith("6.6e-6 (largest over 750-1000 ms after the step: the figure check judges); "), row
    assert f"the output still moves at {moving.times[-1] * 1e3:.4g} ms" in row
    assert "not at rest" not in row
    alone = dict(rest_rows(moving, OutputUnit("rad")))["position error at rest [deg]"]
    assert alone.startswith("the output still moves at ")
