"""The report's closed-loop poles, sampled loops, disturbance step and dynamic stiffness along
the stroke, each against an independent computation; and its units and number format."""

from __future__ import annotations

import math
import warnings

import control as ct
import numpy as np
import pytest

from servo_toolkit import load_scene
from servo_toolkit.display.html import fmt
from servo_toolkit.loop import design
from servo_toolkit.plant.current_loop import current_controller, sample_delay
from servo_toolkit.plant.linear import plant
from servo_toolkit.report import run_section
from servo_toolkit.report import sections_disturbance as sd
from servo_toolkit.report import sections_poles as sp
from servo_toolkit.report.context import Context
from servo_toolkit.report.sections_closed import dynamic_stiffness

from .conftest import SCENES


@pytest.fixture(scope="module")
def ema():
    return load_scene(SCENES / "ema_reference.toml")


@pytest.fixture(scope="module")
def designed(ema):
    return design(ema, progress=False)


# ---------------------------------------------------------------- number format and units

@pytest.mark.parametrize("value, digits, text", [
    (804520.0, 4, "804.5e3"), (1.14698e6, 4, "1.147e6"), (0.14, 4, "0.14"), (1696.8, 4, "1697"),
    (1234.5678, 3, "1230"), (12.5e-6, 3, "12.5e-6"), (-3.2e-4, 4, "-320e-6"), (999.96e3, 4, "1e6"),
    (0.0, 4, "0"), (float("nan"), 4, "n/a"), (float("inf"), 4, "inf"), (7, 4, "7")])
def test_one_number_format_with_engineering_notation(value, digits, text):
    assert fmt(value, digits) == text


def test_formatted_numbers_read_back():
    rng = np.random.default_rng(1)
    for x in rng.standard_normal(300) * 10.0 ** rng.integers(-12, 12, 300):
        back = float(fmt(x, 6))
        assert back == pytest.approx(x, rel=1e-5), (x, fmt(x, 6))
        exp = fmt(x, 6).partition("e")[2]
        assert not exp or int(exp) % 3 == 0


def test_stiffness_in_n_m_per_rad_and_inertia_in_kg_m2(ema):
    """The report shows the stiffness chain in N*m/rad (as `design` and its JSON do), the
    reflected inertia at the motor in kg*m^2, and no unit cell for a dimensionless value."""
    from servo_toolkit.report.sections_drivetrain import ratio_and_inertia, stiffness_chain
    ctx = Context(ema)
    stiff = run_section("stiffness", "stiffness", stiffness_chain, ctx)
    assert "N*m/rad" in stiff.html and "N*m/deg" not in stiff.html
    q = np.array([0.0])
    total = ema.drivetrain.stiffness(q).total[0]  # SI, N*m/rad
    assert f"<td>{fmt(total, 6)}</td>" in stiff.html
    labels = [ax.get_ylabel() for fs in stiff.figures for ax in fs.figure.axes]
    assert any("[N*m/rad]" in label for label in labels)
    inertia = run_section("inertia", "inertia", ratio_and_inertia, ctx)
    labels = [ax.get_ylabel() for fs in inertia.figures for ax in fs.figure.axes]
    assert "J at the motor [kg*m^2]" in labels and not any("kg*cm" in label for label in labels)
    assert "<td>-</td>" not in inertia.html
    motor_j = [ln for fs in inertia.figures for ax in fs.figure.axes for ln in ax.get_lines()
               if ln.get_label() == "J / N^2 at the motor"][0].get_ydata()
    qs = np.asarray(ema.drivetrain.stroke)
    n, _ = ema.drivetrain.ratio(qs)
    j, _ = ema.drivetrain.inertia(qs)
    assert motor_j.min() == pytest.approx(min(j / n**2), rel=0.05)


def test_one_label_style():
    from servo_toolkit.display.units import inertia_unit, label, stiffness_unit
    assert label("gain", "dB") == "gain [dB]" and label("damping ratio") == "damping ratio"
    assert (stiffness_unit(), stiffness_unit(True)) == ("N*m/rad", "N/m")
    assert (inertia_unit(), inertia_unit(True)) == ("kg*m^2", "kg")


def test_scene_tables_of_dimensionless_values_have_no_unit():
    from servo_toolkit.components.compliance import Compliance
    from servo_toolkit.report.units_table import rows
    row = dict((name, (value, unit)) for name, value, unit in rows(Compliance(name="c", stiffness=1000.0)))
    assert row["stiffness"] == ("1000", "N*m/rad")


@pytest.mark.parametrize("name", ["ema_sizing", "cam_follower", "linear_roller_screw_actuator"])
def test_every_scene_parameter_in_the_report_has_a_unit(name):
    """Each row of the scene summary carries a physical unit, never the placeholder "SI";
    temperatures (K inside) are shown in degC: 155 degC is 428.15 K."""
    from servo_toolkit.report.units_table import LINEAR_LOAD, rows
    scene = load_scene(SCENES / f"{name}.toml")
    linear = scene.drivetrain.output_is_linear
    parts = [scene.motor, *scene.stages, scene.sensors, scene.requirements]
    table = [r for part in parts for r in rows(part)] + rows(scene.load, LINEAR_LOAD if linear else None)
    assert [r for r in table if r[2] == "SI" or "(" in r[1]] == []
    motor = {n: (v, u) for n, v, u in rows(scene.motor)}
    assert motor["ambient_temperature"][1] == "degC" and motor["stribeck_speed"][1] == "rad/s"
    if name == "ema_sizing":
        assert motor["max_winding_temperature"] == ("155", "degC")
        assert motor["thermal_resistance_winding"] == ("0.1", "K/W")
    if linear:
        load = {n: u for n, _, u in rows(scene.load, LINEAR_LOAD)}
        assert load["coulomb_friction"] == "N" and load["stribeck_speed"] == "m/s"


# ---------------------------------------------------------------- poles

def test_closed_loop_poles_are_those_of_the_loop_closed_by_hand(designed):
    """Independent: the eigenvalues (numpy) of the open loop's A matrix closed by unity
    negative feedback, A - B C / (1 + D)."""
    pt = sp.pole_table(designed.closed_loop)
    L = designed.loop
    a = np.asarray(L.A) - np.asarray(L.B) @ np.asarray(L.C) / (1.0 + float(np.asarray(L.D).item()))
    eig = np.linalg.eigvals(a)
    upper = eig[eig.imag >= -1e-9 * np.maximum(1.0, np.abs(eig))]
    assert len(pt.poles) == len(upper)
    for p in upper:
        assert np.min(np.abs(pt.poles - p)) <= 1e-6 * max(1.0, abs(p)), p
    assert np.allclose(pt.frequency_hz, np.abs(pt.poles) / (2 * np.pi))
    assert np.allclose(pt.damping, -pt.poles.real / np.abs(pt.poles))
    assert np.all(pt.damping > 0)  # the designed loop is stable


def test_sampled_loops_agree_with_the_continuous_design_below_nyquist(designed, ema):
    """The design's 1.5-sample Pade delay against the exact zero-order hold plus one period of
    computation delay: the same loop far below the Nyquist frequency and near the crossover."""
    ls, lz, ts = sp.motion_loop_pair(designed, ema.motor)
    assert ts == designed.controller.sample_time and lz.dt == ts
    f = np.logspace(-1, math.log10(0.5 / ts), 3000)[:-1]
    rs, rz = sp.loop_response(ls, f), sp.loop_response(lz, f)
    low = f < 0.01 / ts
    assert np.allclose(rz[low], rs[low], rtol=0.02)
    fc, pm, gm = sp.crossings(f, rs)
    assert fc == pytest.approx(designed.margins.gain_crossover_hz[-1], rel=0.01)
    assert pm == pytest.approx(designed.margins.phase_margin_deg, abs=0.5)
    fcz, pmz, _ = sp.crossings(f, rz)
    assert abs(pmz - pm) < 5.0 and fcz == pytest.approx(fc, rel=0.05)
    # the sampled loop closed by unity feedback is stable (its margin is positive)
    a = np.asarray(lz.A) - np.asarray(lz.B) @ np.asarray(lz.C) / (1.0 + float(np.asarray(lz.D).item()))
    assert np.max(np.abs(np.linalg.eigvals(a))) < 1.0
    cs, cz, tsi = sp.current_loop_pair(designed, ema.motor)
    assert 0 < tsi <= ts and cz.dt == tsi
    # the current loop of a pole-cancelling PI crosses near kp / (2 pi L)
    fi = np.logspace(0, math.log10(0.5 / tsi), 3000)[:-1]
    fci, _, _ = sp.crossings(fi, sp.loop_response(cs, fi))
    kp = designed.controller.current_kp
    assert fci == pytest.approx(kp / (2 * np.pi * ema.motor.inductance), rel=0.1)


def test_crossings_of_a_known_loop():
    """L = w_c / s e^{-s tau}: crossover at w_c, phase margin 90 - w_c tau (deg)."""
    wc, tau = 2 * np.pi * 10.0, 0.005
    f = np.logspace(-1, 3, 20000)
    s = 2j * np.pi * f
    fc, pm, gm = sp.crossings(f, wc / s * np.exp(-s * tau))
    assert fc == pytest.approx(10.0, rel=1e-4)
    assert pm == pytest.approx(90.0 - np.degrees(wc * tau), abs=0.05)
    # phase crossing at w tau = pi/2: gain there w_c / w
    assert gm == pytest.approx(-20 * np.log10(wc / (np.pi / 2 / tau)), abs=0.05)


# ---------------------------------------------------------------- disturbance and dynamic stiffness

def _numpy_static_gain(sys):
    a, b, c, d = (np.asarray(m, float) for m in (sys.A, sys.B, sys.C, sys.D))
    return float((d - c @ np.linalg.solve(a, b)).item())


def test_disturbance_step_settles_at_the_static_gain(ema):
    """A loop without integral action (lead-lag) yields under a constant load: the step's
    final value is the amplitude times the static gain D - C A^-1 B (numpy)."""
    d = design(ema, structure="lead_lag", progress=False)
    sys = d.closed_loop_full["theta", "tau_ext"]
    expected = _numpy_static_gain(sys)
    step = sd.disturbance_step(d, 100.0, t_end=20.0)
    assert step.static == pytest.approx(100.0 * expected, rel=1e-9)
    assert step.deflection[-1] == pytest.approx(100.0 * expected, rel=1e-3)
    assert expected != 0.0


def test_disturbance_step_with_integral_action_returns_to_zero(designed, ema):
    step = sd.disturbance_step(designed, sd.step_amplitude(ema), t_end=5.0)
    assert abs(step.static) < 1e-9 * step.peak
    assert abs(step.deflection[-1]) < 1e-3 * step.peak
    assert step.amplitude == abs(ema.load.hinge_moment) > 0
    assert 0 < step.recovery_time() < 5.0


def test_dynamic_stiffness_along_the_stroke_by_hand(designed, ema):
    """Independent: theta / tau_ext = P_tau S, with P_tau the load-to-output response with the
    position measurement cut and S = 1 / (1 + L) of the loop at the same point."""
    from servo_toolkit.loop import open_loop
    f = np.logspace(-1, 3, 200)
    model = "rigid" if designed.parameters.rigid else "two_mass"
    q = float(ema.drivetrain.stroke[0])
    c = designed.controller
    g = plant(ema, q, inductance=True, model=model)
    cur = current_controller(c.current_kp, c.current_ki, ema.motor)
    dly = sample_delay(c.sample_time, 1.5)
    m = c.motion
    cut = ct.ss(m.A, m.B, m.C, m.D, inputs=["theta_ref", "theta_meas", "omega_m"], outputs=["i_ref"])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        p_tau = ct.interconnect([g, cur, dly, cut], inplist=["tau_ext"], outlist=["theta"], check_unused=False)
    L = open_loop(ema, c, q, model=model)
    w = 2 * np.pi * f
    compliance = sp.loop_response(p_tau, f) / (1 + sp.loop_response(L, f))
    assert np.allclose(sd.dynamic_stiffness_at(ema, designed, q, f), 1 / np.abs(compliance), rtol=1e-6)
    # at q0 the curve is the closed-loop section's
    assert np.allclose(sd.dynamic_stiffness_at(ema, designed, designed.q0, f), dynamic_stiffness(designed, f),
                       rtol=1e-6)
    assert w.size == f.size


def test_report_sections_of_the_reference_ema(ema, designed):
    ctx = Context(ema)
    ctx.use_design(designed)
    poles = run_section("poles", "poles", sp.poles_and_sampling, ctx)
    assert poles.status == "info", poles.reason
    assert 'id="poles-table"' in poles.html and 'id="sampled-table"' in poles.html and len(poles.figures) == 2
    pt = sp.pole_table(designed.closed_loop)
    least = int(np.argmin(pt.damping))
    assert f"damping ratio of {fmt(pt.damping[least], 3)} at {fmt(pt.frequency_hz[least])} Hz" in poles.html
    dist = run_section("disturbance", "disturbance", sd.disturbance, ctx)
    assert dist.status == "info", dist.reason
    assert "integral action holds the output" in dist.html and "N*m/rad" in dist.html
    assert dist.html.count("(q0)") == 1 and len(dist.figures) == 2


def test_sections_do_not_apply_without_a_drivetrain():
    ctx = Context(load_scene(SCENES / "deflection_platform.toml"))
    for key, builder in (("poles", sp.poles_and_sampling), ("disturbance", sd.disturbance)):
        assert run_section(key, key, builder, ctx).status == "n/a"
