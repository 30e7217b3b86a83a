"""Multi-stage roller screw of seed 004: kinematics, joint friction, efficiency, dynamics, stage."""

import math
import tomllib

import numpy as np
import pytest

from servo_toolkit import SceneError, load_scene
from servo_toolkit.components.roller_screw.stages import RollerScrew, efficiency_eq35, steady_efficiency
from servo_toolkit.studies.mechanisms.dispatch import handles
from servo_toolkit.studies.run import run_study
from servo_toolkit.components.roller_screw.model import RollerScrewModel
from servo_toolkit.studies.mechanisms.roller_screw import carrier_step

from .conftest import SCENES, build


@pytest.fixture(scope="module")
def scene():
    return load_scene(SCENES / "roller_screw_two_stage.toml")


def test_kinematics_eq3_and_eq8(scene):
    m = RollerScrewModel.from_scene(scene)
    v = m.nut_speeds(100.0)
    assert v == pytest.approx([-100 * 0.01 / (2 * math.pi), -100 * 0.02 / (2 * math.pi)])
    for st, z in zip(scene.roller_screw, m.steady_carrier_ratios):
        # rolling on the fixed nut: roller centre speed = -spin * r_R  ->  eq 8's -(n_S - 1)
        spin = m.roller_spins([1.0, 1.0])[0]
        assert spin == pytest.approx(-(st.screw_radius + st.roller_radius) / st.roller_radius)
        # zero tangential slip at the steady ratio (eq 13, phi = 0)
        assert st.screw_radius - 2 * (st.screw_radius + st.roller_radius) * z == pytest.approx(0, abs=1e-15)
    helix = [math.degrees(math.atan(s.lead / (2 * math.pi * s.screw_radius))) for s in scene.roller_screw]
    assert helix == pytest.approx([9.27, 5.51], abs=0.01)


def test_joint_friction_eqs_4_5(scene):
    m = RollerScrewModel.from_scene(scene, mu_ss=0.1, mu_ns=0.05)
    assert m.spline_friction(1, 10.0, -0.3) == pytest.approx(0.1 * 10.0 / 12.25e-3)
    assert m.spline_friction(1, -10.0, 0.3) == pytest.approx(-0.1 * 10.0 / 12.25e-3)
    assert m.bearing_friction(1, 7000.0, 100.0) == pytest.approx(0.05 * 7000 * 21.75e-3)
    assert m.bearing_friction(1, -7000.0, -100.0) == pytest.approx(-0.05 * 7000 * 21.75e-3)


def test_joint_loads_use_the_eq_4_5_methods(scene):
    """forces() takes its joint friction from spline_friction / bearing_friction: switching
    either method off equals setting its coefficient to zero, and the nut load passed back
    is F_N1 = F_N2 + mu_SS |M_S2| / r_SS with M_S2 = (thread 2) + mu_NS F_N1 r_NS, solved by
    hand here (linear in F_N1)."""
    w, load, carriers = 100.0, 7000.0, np.array([12.0, 30.0])
    m = RollerScrewModel.from_scene(scene, mu_ss=0.15, mu_ns=0.05)

    class NoSpline(RollerScrewModel):
        def spline_friction(self, k, screw_torque, screw_axial_speed):
            return 0.0

    class NoBearing(RollerScrewModel):
        def bearing_friction(self, k, nut_load, screw_speed):
            return 0.0
    for cls, same in ((NoSpline, dict(mu_ss=0.0, mu_ns=0.05)), (NoBearing, dict(mu_ss=0.15, mu_ns=0.0))):
        off = cls(m.stages, m.mu_rs, m.mu_ss, m.mu_ns).forces(w, carriers, load)
        ref = RollerScrewModel.from_scene(scene, **same).forces(w, carriers, load)
        full = m.forces(w, carriers, load)
        assert off["screw_torque"] == pytest.approx(ref["screw_torque"], rel=1e-14)
        assert off["nut_loads"] == pytest.approx(ref["nut_loads"], rel=1e-14)
        assert abs(full["screw_torque"] - off["screw_torque"]) > 1e-3 * full["screw_torque"]
    st = scene.roller_screw[1]
    thread2 = m._contact(1, w, carriers[1], load)[1]
    f_n1 = (load + 0.15 * thread2 / st.screw_spline_radius) / (
        1 - 0.15 * 0.05 * st.nut_screw_joint_radius / st.screw_spline_radius)
    assert m.forces(w, carriers, load)["nut_loads"][0] == pytest.approx(f_n1, rel=1e-13)
    # self-locking joint friction is refused, naming the stage
    with pytest.raises(SceneError, match=r"stages\[1\].*lock"):
        RollerScrewModel.from_scene(scene, mu_ss=0.95, mu_ns=0.95).forces(w, carriers, load)


def test_eq35_printed_value_and_limit(scene):
    assert efficiency_eq35(scene.roller_screw, 0.1) == pytest.approx(0.9935, abs=5e-5)
    assert steady_efficiency(scene.roller_screw, 0.0, 0.1, 0.0) == pytest.approx(
        efficiency_eq35(scene.roller_screw, 0.1), rel=1e-12)
    assert steady_efficiency(scene.roller_screw, 0.0, 0.0, 0.0) == pytest.approx(1.0)


def test_efficiency_trends_fig9_fig10(scene):
    st = scene.roller_screw
    by_ss = [steady_efficiency(st, 0.05, ss, 0.005) for ss in (0.10, 0.15, 0.20)]
    by_ns = [steady_efficiency(st, 0.05, 0.10, ns) for ns in (0.005, 0.055, 0.105)]
    assert by_ss[0] > by_ss[1] > by_ss[2] and by_ss[0] - by_ss[2] < 0.01          # barely
    assert by_ns[0] > by_ns[1] > by_ns[2] and by_ns[0] - by_ns[2] > 0.2           # markedly


def test_power_balance_of_contact_model(scene):
    """M_S1 w = F v_out + contact losses + joint losses + carrier power, at any carrier speed."""
    m = RollerScrewModel.from_scene(scene, mu_ss=0.15, mu_ns=0.05)
    w, load = 100.0, 7000.0
    carriers = np.array([12.0, 30.0])
    out = m.forces(w, carriers, load)
    nuts = out["nut_loads"]
    v = -m.nut_speeds(w)
    st = scene.roller_screw[1]
    # joint losses: spline slides at v_N1, bearing turns at w
    thread1 = m._contact(0, w, carriers[0], nuts[0])[1]
    m_s2 = out["screw_torque"] - thread1
    spline_loss = 0.15 * abs(m_s2) / st.screw_spline_radius * v[0]
    bearing_loss = 0.05 * nuts[0] * st.nut_screw_joint_radius * w
    p_in = out["screw_torque"] * w
    p_out = load * v[1]
    p_carrier = float(out["carrier_drive"] @ carriers)
    assert p_in == pytest.approx(p_out + out["contact_loss"].sum() + spline_loss + bearing_loss + p_carrier,
                                 rel=1e-12)


def test_single_stage_carrier_step_matches_closed_form(scene):
    r = carrier_step(scene)
    assert r.ratio.shape[0] == 1
    assert r.ratio[0, 0] == 0 and r.ratio[0, -1] == pytest.approx(0.375, rel=1e-3)
    assert np.all(np.diff(r.ratio[0]) >= -1e-12)
    assert np.abs(r.closed_form - r.ratio).max() < 1e-6


def test_efficiency_study_steps_and_trends(scene):
    assert handles(scene, "efficiency") and handles(scene, "carrier_step") and not handles(scene, "ramp")
    r = run_study(scene, "efficiency")
    first = r.cases[0]
    assert first["efficiency"][0] == pytest.approx(0.60, abs=0.03)     # seed: ~0.60 at the start
    assert first["efficiency"][-1] == pytest.approx(first["steady"], rel=1e-4)
    # two steps: stage 1 settles before stage 2
    assert np.all(first["carrier_ratio"][0][20:] >= first["carrier_ratio"][1][20:] - 1e-9)
    assert r.eq35 == pytest.approx(0.9935, abs=5e-5)


def _actuator():
    return tomllib.loads((SCENES / "linear_roller_screw_actuator.toml").read_text())


def test_roller_screw_drivetrain_stage_reflects(scene):
    act = load_scene(SCENES / "linear_roller_screw_actuator.toml")
    rs = act.stages[-1]
    assert isinstance(rs, RollerScrew)
    dt = act.drivetrain
    n, _ = dt.ratio([0.0])
    gear = act.stages[0].ratio if len(act.stages) > 1 else 1.0
    assert n[0] == pytest.approx(gear * 2 * math.pi / 0.02)
    # inertia at the nut: independent hand sum at the first screw, times the screw ratio squared
    lam1, lam2 = 0.01 / (2 * math.pi), 0.02 / (2 * math.pi)
    total = 0.0
    for k, s in enumerate(rs.stages):
        z = s.screw_radius / (2 * (s.screw_radius + s.roller_radius))
        carrier = s.carrier_inertia + s.rollers * (s.roller_mass * (s.screw_radius + s.roller_radius) ** 2
                                                   + s.roller_inertia * (s.screw_starts - 1) ** 2)
        total += s.screw_inertia + z**2 * carrier + (s.nut_mass + s.rollers * s.roller_mass) * [lam1, lam2][k] ** 2
    total += rs.stages[1].screw_mass * lam1**2
    assert RollerScrewModel(rs.stages, 0.0).reflected_inertia() == pytest.approx(total, rel=1e-12)
    labels, masses, t, _ = dt.jacobians([0.0])
    screw_part = sum(mi * ti**2 for l, mi, ti in zip(labels, masses, t[:, 0]) if l.startswith(rs.name))
    assert screw_part == pytest.approx(total / lam2**2, rel=1e-12)
    assert rs.efficiency == pytest.approx(steady_efficiency(rs.stages, rs.roller_screw_friction,
                                                            rs.screw_screw_friction, rs.nut_screw_friction))
    assert 0.5 < dt.efficiency < 1


def test_roller_screw_stage_errors_name_keys():
    from servo_toolkit import SceneError
    data = _actuator()
    idx = [i for i, s in enumerate(data["drivetrain"]) if s["kind"] == "roller_screw"][0]
    data["drivetrain"][idx]["stages"][1]["nut_radius"] = "30 mm"
    with pytest.raises(SceneError) as info:
        build(data)
    assert info.value.key == f"drivetrain[{idx}].stages[1].nut_radius"
