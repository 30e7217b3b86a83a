"""Loop design of the reference EMA and the cam drive."""

import json
import math
import warnings

import control as ct
import numpy as np
import pytest

import servo_toolkit as st
from servo_toolkit.loop.controller import CascadeController
from servo_toolkit.loop import evaluate, linear_closed_loop
from servo_toolkit.loop.assembly import closed_loop_matrix, controller_matrices
from servo_toolkit.loop.structures import Motion
from servo_toolkit.plant.current_loop import current_controller
from servo_toolkit.plant.linear import plant_matrices

from .conftest import SCENES


@pytest.fixture(scope="module")
def ema():
    return st.load_scene()


@pytest.fixture(scope="module")
def ema_design(ema):
    return st.design(ema)


def test_reference_design_meets_its_requirements(ema_design):
    r = ema_design
    assert isinstance(r.controller, CascadeController)
    assert r.margins.closed_loop_stable
    assert r.passed, r.table()
    names = {c.name: c for c in r.requirements}
    assert names["bandwidth"].achieved >= 8.0 and names["bandwidth"].source == "scene"
    assert names["phase_margin"].achieved >= 45.0 and names["gain_margin"].achieved >= 6.0
    assert names["sensitivity_peak"].achieved <= 6.0
    assert names["phase_lag_at_bandwidth"].achieved <= 90.0
    assert r.motion.filter in ("notch", "lowpass", "none")


def test_reported_margins_agree_with_python_control(ema_design):
    r = ema_design
    gm, pm, _, wpc, wgc, _ = ct.stability_margins(r.loop, returnall=True)
    real = wpc > 1e-3
    # python-control's crossings are roots of polynomials in w whose coefficients carry rounding
    # (its 3.76 kHz crossing is 3e-5 deg off -180 deg): agreement to 1e-6, not to the last bit
    np.testing.assert_allclose(sorted(r.margins.gain_margins_db), sorted(20 * np.log10(gm[real])), rtol=1e-6)
    # each reported crossing, on the loop's own response: L real and negative, GM = -20 log10 |L|
    for f, g in zip(r.margins.phase_crossover_hz, r.margins.gain_margins_db):
        lw = complex(r.loop(2j * math.pi * f))
        assert lw.real < 0 and abs(lw.imag) <= 1e-9 * abs(lw), (f, lw)
        assert abs(g + 20 * math.log10(abs(lw))) < 1e-9 * abs(g), (f, g)
    np.testing.assert_allclose(r.margins.phase_margin_deg, np.min(pm), rtol=1e-9)
    gm1, pm1, *_ = ct.stability_margins(r.loop)
    np.testing.assert_allclose(r.margins.phase_margin_deg, pm1, rtol=1e-6)
    np.testing.assert_allclose(abs(r.margins.gain_margin_db), abs(20 * np.log10(gm1)), rtol=1e-6)
    np.testing.assert_allclose(r.margins.bandwidth_hz, ct.bandwidth(r.closed_loop) / (2 * math.pi), rtol=1e-9)
    # the loop broken at the error closes to the reported closed loop
    w = 2 * np.pi * np.array([0.5, 3.0, 8.0, 30.0])
    L = np.asarray(ct.frequency_response(r.loop, w).complex).reshape(-1)
    T = np.asarray(ct.frequency_response(r.closed_loop, w).complex).reshape(-1)
    np.testing.assert_allclose(T, L / (1 + L), rtol=1e-6)
    d = r.to_dict()
    for key in ("gain_margin_db", "phase_margin_deg", "delay_margin_s", "disk_margin", "sensitivity_peak_db",
                "bandwidth_hz", "phase_at_8hz_deg", "closed_loop_stable", "requirements"):
        assert key in d
    assert d["phase_at_8hz_deg"] == pytest.approx(r.margins.phase_at_freq_deg)


def test_plain_pi_position_loop_is_unstable(ema, ema_design):
    # PI on the position error, crossing over at the required 8 Hz, integral corner a decade below
    wc = 2 * math.pi * 8.0
    g = ema_design.plant
    cur = current_controller(ema_design.controller.current_kp, ema_design.controller.current_ki, ema.motor)
    p = ct.interconnect([g, cur], inplist=["i_cmd"], outlist=["theta"], check_unused=False)
    kc = 1.0 / abs(p(1j * wc) * (1 + 0.1 * wc / (1j * wc)))
    pi = Motion("pi", {"kc": kc, "wi": 0.1 * wc}, ratio=ema_design.parameters.N)
    ctrl = CascadeController(pi.state_space(), ema_design.controller.current_kp,
                             ema_design.controller.current_ki, ema.sensors.sample_time, "plain PI")
    r = evaluate(ema, ctrl)
    assert not r.margins.closed_loop_stable and not r.passed
    assert r.margins.max_closed_loop_pole_real > 0
    # the search finds no PI meeting the requirements either
    assert not st.design(ema, structure="pi").passed


def test_rigid_design_is_unstable_on_the_compliant_drivetrain(ema):
    # a cascade tuned on the rigid model ignores the ~30 Hz drivetrain mode
    rigid = st.design(ema, model="rigid")
    assert rigid.margins.closed_loop_stable
    real = evaluate(ema, rigid.controller)
    assert not real.margins.closed_loop_stable


def test_linear_closed_loop_matches_numpy_assembly(ema, ema_design):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cl = linear_closed_loop(ema, ema_design.controller)
    assert cl.input_labels == ["theta_ref", "tau_ext"] and "i" in cl.output_labels
    A, B, C, D, _ = plant_matrices(ema_design.parameters)
    acl = closed_loop_matrix(A, B[:, :1], C[:3], D[:3, :1], *controller_matrices(ema_design.controller, ema.motor))
    np.testing.assert_allclose(np.sort_complex(np.linalg.eigvals(acl)), np.sort_complex(cl.poles()), rtol=1e-6)
    np.testing.assert_allclose(ct.dcgain(cl["theta", "theta_ref"]), 1.0, rtol=1e-9)
    Ad, Bd, Cd, Dd = ema_design.controller.discrete_motion()
    assert np.all(np.abs(np.linalg.eigvals(Ad)) <= 1 + 1e-12)


def test_cam_drive_gets_a_loop_with_documented_defaults():
    cam = st.load_scene(SCENES / "cam_follower.toml")
    r = st.design(cam)
    assert r.parameters.rigid and r.margins.closed_loop_stable
    assert all(c.source == "default" for c in r.requirements if c.name != "stable_over_stroke")
    assert next(c for c in r.requirements if c.name == "stable_over_stroke").source == "always"
    assert any("default" in n for n in r.notes) and any("ideal current loop" in n for n in r.notes)
    assert r.passed


def test_robust_false_on_a_scene_with_robustness_is_the_nominal_design(ema_design):
    # [robustness] changes nothing in a nominal design; design(scene) without it stays nominal
    robust_scene = st.load_scene(SCENES / "ema_robust.toml")
    r = st.design(robust_scene, robust=False)
    assert ema_design.robustness is None and r.robustness is None
    assert r.motion == ema_design.motion
    assert r.margins.bandwidth_hz == pytest.approx(ema_design.margins.bandwidth_hz)


def test_robust_design_of_a_rigid_drive_stays_in_its_search_box():
    # a rigid, delay-free cascade gets better with every gain increase: the search is bounded
    from servo_toolkit.scene.loader import Robustness
    cam = st.load_scene(SCENES / "cam_follower.toml")
    r = st.design(cam, robust=Robustness(load_inertia=(0.0, 1e-4), stiffness=None, samples=100), progress=False)
    assert r.parameters.rigid and r.robustness.all_stable and r.passed, r.table()
    assert all(np.isfinite(v) and v < 1e4 for v in r.motion.gains.values())
    assert r.robustness.worst["phase_margin"]["load_inertia"] > 5e-5  # the heaviest variants are the worst


@pytest.mark.parametrize("out, kv", [("m", "A*s/m"), ("rad", "A*s/rad")])
def test_a_controller_line_gives_every_gain_its_unit(out, kv):
    """The line simulate and design print: each gain with its unit, the speed gain per output
    m/s for an output travel, per output rad/s for an angle; a notch's frequency in rad/s."""
    motion = Motion("cascade", {"kp": 84.0, "kv": 223.4, "wvi": 32.81}, "notch",
                    {"wn": 173.4, "zeta_zero": 0.14, "zeta_pole": 0.7})
    assert motion.describe(out) == (f"cascade (kp=84 1/s, kv=223.4 {kv}, wvi=32.81 rad/s) + notch wn=173.4 rad/s, "
                                    "zeta_zero=0.14, zeta_pole=0.7")


def test_a_designed_controller_names_its_gains_units_for_an_output_travel(capsys):
    from servo_toolkit.cli import main
    main(["simulate", str(SCENES / "emps.toml"), "--json"])
    controller = json.loads(capsys.readouterr().out)["controller"]
    assert controller.startswith("cascade (kp=") and " 1/s, kv=" in controller and " A*s/m, wvi=" in controller


def test_the_feedforward_line_gives_the_inertia_and_ratio_their_units():
    from servo_toolkit.loop.command_design import CommandDesign
    gains = {"velocity": 0.2108, "acceleration": 1.464, "inertia": 276.0, "ratio": 3142.0}
    (line,) = CommandDesign("s", gains, output_unit="m").lines()[:1]
    assert line.endswith("(J 276 kg, N 3142 rad/m)")
    (line,) = CommandDesign("s", gains, output_unit="rad").lines()[:1]
    assert line.endswith("(J 276 kg*m^2, N 3142 rad/rad)")


def test_the_summary_names_the_lag_at_a_required_bandwidth_other_than_its_headline_phase(ema):
    """The design summary's headline phase is at 8 Hz; a scene requiring 6 Hz is judged on its
    lag at 6 Hz, and the line says that figure beside it (the reference, at 8 Hz, needs no
    second figure)."""
    from servo_toolkit.loop import design
    six = design(ema, require={"bandwidth": 6.0})
    lag = next(c for c in six.requirements if c.name == "phase_lag_at_bandwidth")
    line = next(s for s in six.table().splitlines() if "closed loop stable: yes" in s)
    assert f"; phase lag at the required bandwidth 6 Hz {lag.achieved:.1f} deg" in line, line
    eight = design(ema)
    line = next(s for s in eight.table().splitlines() if "closed loop stable: yes" in s)
    assert "required bandwidth" not in line, line


def test_design_dict_is_strict_json_and_the_command_line_agrees(ema_design, capsys):
    """No gain reduction destabilizes the reference EMA's loop (lower gain margin -inf); its
    dict says so with None, as every result's dict does for a figure that is not finite, and
    ``design --json`` prints the same null; a rigid plant's infinite stiffness likewise."""
    from servo_toolkit.cli import main
    r = ema_design
    assert r.margins.lower_gain_margin_db == -math.inf and r.margins.closed_loop_stable
    d = r.to_dict()
    json.dumps(d, allow_nan=False)  # strict JSON: no -Infinity
    assert d["margins"]["lower_gain_margin_db"] is None
    assert d["margins"]["upper_gain_margin_db"] == pytest.approx(r.margins.upper_gain_margin_db)
    assert main(["design", str(SCENES / "ema_reference.toml"), "--json", "--linear-only"]) == 0
    cli = json.loads(capsys.readouterr().out)
    assert cli["margins"]["lower_gain_margin_db"] is None
    assert cli["margins"].keys() == d["margins"].keys()
    assert cli["gain_margin_db"] == pytest.approx(d["gain_margin_db"], rel=1e-9)
    rigid = st.design(st.load_scene(SCENES / "emps.toml"))
    assert rigid.parameters.K == math.inf
    dr = rigid.to_dict()
    json.dumps(dr, allow_nan=False)
    assert dr["plant"]["stiffness_n_per_m"] is None and dr["plant"]["resonance_hz"] is None


def test_an_operating_point_outside_the_stroke_is_refused(ema):
    """``q0`` is in rad: ``q0=10`` is 573 deg, far beyond the EMA's +-30 deg stroke, and was
    designed and reported "requirements met" on a ratio the actuator never has."""
    from servo_toolkit.errors import SceneError
    from servo_toolkit.loop.tuning import LoopTuning, tuned_design
    with pytest.raises(SceneError, match=r"q0: must lie within the drivetrain stroke \[-30 deg, 30 deg\] "
                                         r"\(got 10 rad = 572\.958 deg"):
        st.design(ema, q0=10.0, progress=False)
    with pytest.raises(SceneError, match=r"^tuning\.q0: must lie within"):
        tuned_design(ema, LoopTuning(q0=-1.0))
    with pytest.raises(SceneError, match="finite"):
        st.design(ema, q0=float("nan"), progress=False)


def test_a_design_is_exported_and_judged_only_with_its_own_scene(ema_design):
    """Another actuator's limits, sensors and stroke with this design's gains would mix both."""
    from servo_toolkit import load_scene
    from servo_toolkit.errors import SceneError
    from servo_toolkit.export import export
    from servo_toolkit.studies.actuator import actuator_check
    from .conftest import SCENES
    other = load_scene(SCENES / "linear_roller_screw_actuator.toml")
    with pytest.raises(SceneError, match=r"^design_result: was designed for the scene 'ema_reference'"):
        export(ema_design, other)
    with pytest.raises(SceneError, match=r"^design: was designed for the scene 'ema_reference'"):
        actuator_check(other, ema_design)
