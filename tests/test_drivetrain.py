"""Drivetrain reflection checked against independent geometry, closed forms and seed 001."""

import math

import numpy as np
import pytest

from servo_toolkit import load_scene
from servo_toolkit.drivetrain.reflected import series
from servo_toolkit.studies.stiffness import stiffness_study

from .conftest import SCENES, build, variant

Q = np.radians(np.linspace(-30, 30, 13))


def geometry(phi, r=0.051, l=0.120, offset=0.0):
    """Independent evaluation of the DESIGN.md geometry: nut pin A and arm tip B."""
    h = r + offset
    b = np.stack([r * np.sin(phi), r * np.cos(phi)])
    xa = r * np.sin(phi) - np.sqrt(l**2 - (h - r * np.cos(phi)) ** 2)
    return np.stack([xa, np.full_like(phi, h)]), b


def fd(f, x, h=1e-6):
    return (f(x + h) - f(x - h)) / (2 * h)


@pytest.fixture(scope="module")
def ema():
    return load_scene(SCENES / "ema_reference.toml")


@pytest.mark.parametrize("parts, total", [
    ((1096623, 8256825, 1696.8, 1021.5), 637.21),
    ((1096628, 8256837, 1696.8, 1048.44), 647.59),
    ((1096632, 8256846, 1696.8, 1082.99), 660.61),
])
def test_seed001_table1_series_totals(ema_dict, parts, total):
    """Seed 001 table 1: the printed stage stiffnesses (N*m/deg at the output) in series."""
    data = variant(ema_dict)
    data["drivetrain"] = [{"kind": "compliance", "name": f"s{i}", "stiffness": f"{k} N*m/deg"}
                          for i, k in enumerate(parts)]
    result = stiffness_study(build(data), [10.0])
    assert result.total[0] * math.pi / 180 == pytest.approx(total, rel=1e-3)
    assert series(parts) == pytest.approx(total, rel=1e-3)
    assert result.shares.sum() == pytest.approx(1.0)
    # the gear stage's share is ~1e-4 (seed 001: front stages may be neglected)
    assert result.shares[0, 0] < 1e-3 and result.negligible[0]


def test_linkage_ratio_matches_geometry_finite_difference(ema):
    link = ema.stages[2]
    jet = link.map(Q)
    xa = lambda p: geometry(p)[0][0]
    assert jet.value == pytest.approx(xa(Q), abs=1e-12)
    assert jet.d1 == pytest.approx(fd(xa, Q), rel=1e-7)
    assert jet.d2 == pytest.approx(fd(lambda p: fd(xa, p, 1e-4), Q, 1e-4), rel=1e-5, abs=1e-8)
    # rod parallel to the screw at phi = 0 with zero offset: the ratio equals r
    assert float(link.map(0.0).d1) == pytest.approx(0.051)


def test_ball_screw_through_linkage_is_k_times_ratio_squared(ema):
    """The nut's axial stiffness at the output equals k (dx_A/dphi)^2 (finite difference)."""
    chain = ema.drivetrain.stiffness(Q)
    i = chain.names.index("ball screw")
    dx = fd(lambda p: geometry(p)[0][0], Q)
    assert chain.stage_stiffness[i] == pytest.approx(2.0e8 * dx**2, rel=1e-7)


def test_rod_stiffness_uses_stretch_at_fixed_nut(ema):
    def stretch_rate(phi, h=1e-6):
        a, _ = geometry(phi)
        stretch = lambda p: np.hypot(*(geometry(p)[1] - a))
        return (stretch(phi + h) - stretch(phi - h)) / (2 * h)
    chain = ema.drivetrain.stiffness(Q)
    i = chain.names.index("link rod and rocker arm")
    assert chain.stage_stiffness[i] == pytest.approx(2.24e7 * stretch_rate(Q) ** 2, rel=1e-6)
    # DESIGN: ~1021 N*m/deg near 0 deg
    assert chain.stage_stiffness[i][6] * math.pi / 180 == pytest.approx(1017, rel=0.01)


def test_gear_ratio_from_teeth_with_idler(ema):
    gear = ema.stages[0]
    assert gear.ratio == pytest.approx(52 / 24)  # the idler (40) cancels
    # the idler turns at 52/40 of the screw gear: its inertia reflects with that ratio squared
    elements = {e.label: e for e in gear.elements(np.array([0.0]))}
    assert elements["spur gear train: gear 2"].u.d1[0] == pytest.approx(52 / 40)


def test_overall_ratio_and_derivative(ema):
    dt = ema.drivetrain
    n, dn = dt.ratio(Q)
    motor_angle = lambda p: 52 / 24 * 2 * math.pi / 0.005 * geometry(p)[0][0]
    assert n == pytest.approx(fd(motor_angle, Q), rel=1e-7)
    assert dn == pytest.approx(fd(lambda p: dt.ratio(p)[0], Q, 1e-5), rel=1e-5, abs=1e-6)


R, L_ROD, LEAD, M_ROD = 0.051, 0.120, 0.005, 0.15


def motor_angle(p):
    return 52 / 24 * 2 * math.pi / LEAD * geometry(p)[0][0]


def rod_angle(p):
    a, b = geometry(p)
    return np.arctan2(*(b - a)[::-1])


#: element label -> (mass or inertia from the scene file, its coordinate from the geometry)
ELEMENTS = {
    "spur gear train: gear 1": (1e-5, motor_angle),
    "spur gear train: gear 2": (2.2e-5, lambda p: motor_angle(p) * 24 / 40),
    "spur gear train: gear 3": (3.5e-5, lambda p: motor_angle(p) * 24 / 52),
    "ball screw: screw": (1.3e-5, lambda p: 2 * math.pi / LEAD * geometry(p)[0][0]),
    "ball screw: nut": (0.6, lambda p: geometry(p)[0][0]),
    "link rod and rocker arm: output shaft": (1.2e-3, lambda p: p),
    "link rod and rocker arm: rod end at nut": (M_ROD / 2, lambda p: geometry(p)[0][0]),
    "link rod and rocker arm: rod end at arm": (M_ROD / 2, lambda p: R * p),  # arc on the circle r
    "link rod and rocker arm: rod rotation": (-M_ROD * L_ROD**2 / 6, rod_angle),
    "motor rotor": (2e-4, motor_angle),
    "load": (1.0, lambda p: p),
}


def kinetic_energy(phi, qdot=1.0, h=1e-6):
    """Kinetic energy from the bodies' own motion (uniform bar, nut, screw, gears, rotor)."""
    a0, b0 = geometry(phi - h)
    a1, b1 = geometry(phi + h)
    va, vb = (a1 - a0) / (2 * h) * qdot, (b1 - b0) / (2 * h) * qdot
    vc = 0.5 * (va + vb)
    omega_rod = fd(rod_angle, phi) * qdot
    bar = 0.5 * M_ROD * np.sum(vc**2, axis=0) + 0.5 * (M_ROD * L_ROD**2 / 12) * omega_rod**2
    nut = 0.5 * 0.6 * va[0] ** 2
    screw = 0.5 * 1.3e-5 * (fd(lambda p: 2 * math.pi / LEAD * geometry(p)[0][0], phi) * qdot) ** 2
    gears = sum(0.5 * j * (fd(motor_angle, phi) * 24 / z * qdot) ** 2
                for j, z in [(1e-5, 24), (2.2e-5, 40), (3.5e-5, 52)])
    rotor = 0.5 * 2e-4 * (fd(motor_angle, phi) * qdot) ** 2
    out = 0.5 * (1.2e-3 + 1.0) * qdot**2
    return bar + nut + screw + gears + rotor + out


def test_reflected_inertia_equals_kinetic_energy(ema):
    """J(q) qdot^2/2 equals the kinetic energy computed from the bodies' own motion."""
    dt = ema.drivetrain
    j, dj = dt.inertia(Q)
    assert 0.5 * j == pytest.approx(kinetic_energy(Q), rel=1e-6)
    assert dj == pytest.approx(fd(lambda p: dt.inertia(p)[0], Q, 1e-5), rel=1e-5, abs=1e-6)


def test_reflected_inertias_per_element_against_geometry(ema):
    """Each element: J_i = m_i (du_i/dq)^2 and its q-derivative, at the output and at the
    motor, from finite differences of the independent geometry (not the code's jets)."""
    r = ema.drivetrain.reflected_inertias(Q)
    assert set(r.labels) == set(ELEMENTS)
    n_of = lambda p: fd(motor_angle, p)
    for i, label in enumerate(r.labels):
        m, u = ELEMENTS[label]
        j_of = lambda p, m=m, u=u: m * fd(u, p) ** 2
        jm_of = lambda p, j_of=j_of: j_of(p) / n_of(p) ** 2
        dj, djm = fd(j_of, Q, 1e-4), fd(jm_of, Q, 1e-4)
        assert r.output[i] == pytest.approx(j_of(Q), rel=1e-6), label
        # finite-difference noise where a derivative vanishes: tolerance from the element's size
        tol = 1e-5 * max(np.max(np.abs(dj)), np.max(np.abs(j_of(Q))))
        assert r.output_dq[i] == pytest.approx(dj, rel=1e-4, abs=tol), label
        assert r.motor[i] == pytest.approx(jm_of(Q), rel=1e-6), label
        tol = 1e-5 * max(np.max(np.abs(djm)), np.max(np.abs(jm_of(Q))))
        assert r.motor_dq[i] == pytest.approx(djm, rel=1e-4, abs=tol), label


def test_reflected_inertias_sum_to_totals(ema):
    dt = ema.drivetrain
    r = dt.reflected_inertias(Q)
    j, dj = dt.inertia(Q)
    assert r.output.sum(axis=0) == pytest.approx(j, rel=1e-12)
    assert r.total_dq == pytest.approx(dj, rel=1e-12, abs=1e-12)
    assert r.motor_total == pytest.approx(dt.motor_inertia(Q), rel=1e-12)
    # the motor-side total's derivative against a finite difference of the geometry's energy
    jm = lambda p: 2 * kinetic_energy(p) / fd(motor_angle, p) ** 2
    assert r.motor_total_dq == pytest.approx(fd(jm, Q, 1e-4), rel=1e-4, abs=1e-10)
    # the rotor dominates the motor side; the load reflects as 1/N^2
    parts = r.by_label()
    assert parts["load"][2] == pytest.approx(1.0 / fd(motor_angle, Q) ** 2, rel=1e-6)


def test_motor_side_inertia_and_lash(ema):
    dt = ema.drivetrain
    # kinetic energy at unit motor speed, from the bodies' own motion
    omega_m = fd(motor_angle, Q)
    assert dt.motor_inertia(Q) == pytest.approx(2 * kinetic_energy(Q) / omega_m**2, rel=1e-6)
    # gear lash at the screw shaft -> divided by the screw's ratio; nut lash -> by dx/dphi
    dx = fd(lambda p: geometry(p)[0][0], Q)
    expected = math.radians(0.1) / (2 * math.pi / 0.005 * dx) + 1e-5 / dx
    assert dt.backlash(Q) == pytest.approx(expected, rel=1e-7)
    assert dt.efficiency == pytest.approx(0.97 * 0.90)


def test_stroke_and_operating_point(ema):
    assert ema.drivetrain.stroke == pytest.approx((-math.pi / 6, math.pi / 6))
    assert ema.drivetrain.mid_stroke == pytest.approx(0.0)


def stretch_rate(phi, h=1e-6):
    """d|AB|/dphi at fixed nut pin A, from the geometry."""
    a, _ = geometry(phi)
    stretch = lambda p: np.hypot(*(geometry(p)[1] - a))
    return (stretch(phi + h) - stretch(phi - h)) / (2 * h)


def test_seed001_criterion_on_the_reference_ema(ema):
    """Seed 001's two conditions: the gear train may be neglected, the rest may not.

    Own stiffnesses in N*m/rad: the gear mesh as given (screw shaft), the nut and the rod
    (N/m) through their ratio to the output at mid-stroke (both r = 51 mm at 0 deg)."""
    chain = ema.drivetrain.stiffness(Q)
    crit = chain.criterion()
    assert chain.names == ("spur gear train", "ball screw", "link rod and rocker arm", "housing")
    assert chain.native_units == ("N*m/rad", "N/m", "N/m", "N*m/rad")
    dx = fd(lambda p: geometry(p)[0][0], Q)
    lever_nut, lever_rod = float(fd(lambda p: geometry(p)[0][0], np.array([0.0]))[0]), float(stretch_rate(np.array([0.0]))[0])
    assert lever_nut == pytest.approx(R, rel=1e-7) and lever_rod == pytest.approx(R, rel=1e-7)
    own = [1.6e4, 2.0e8 * lever_nut**2, 2.24e7 * lever_rod**2, 1696.8 * 180 / math.pi]
    assert crit.own_stiffness == pytest.approx(own, rel=1e-6)
    ratio = [2 * math.pi / LEAD * dx, dx / lever_nut, stretch_rate(Q) / lever_rod, np.ones_like(Q)]
    assert crit.ratio == pytest.approx(np.array(ratio), rel=1e-6)
    # own stiffness times ratio squared is the stiffness at the output
    assert crit.own_stiffness[:, None] * crit.ratio**2 == pytest.approx(chain.stage_stiffness, rel=1e-12)
    # gear: ratio 54..64 to every later stage, 1.6e4 >= 5.8e4/10 (rod) -> negligible
    assert np.all(crit.later_ratio[0] > 50) and crit.ratio_large[0].all()
    assert crit.stiffness_to_later[0] == pytest.approx(1.6e4 / own[2], rel=1e-6)
    assert crit.stiffness_comparable[0] and crit.negligible[0]
    # ball screw, rod: the ratio to the later stages is ~1, not large; housing: no later stage
    assert not crit.ratio_large[1:].any() and not crit.negligible[1:].any()
    assert np.isnan(crit.stiffness_to_later[3]) and not crit.stiffness_comparable[3]
    # the bound the two conditions give: share_gear <= within / ratio^2 * share of the rod
    assert np.all(chain.shares[0] <= 10 / crit.later_ratio[0] ** 2 * chain.shares[2])
    assert np.all(chain.shares[0] < 1e-3) and chain.negligible()[0]


def test_seed001_criterion_both_outcomes_on_variants(ema_dict):
    """A soft gear mesh fails condition 2; stages all at the output fail condition 1 even
    with a tiny share (the share rule and the seed's rule differ there)."""
    soft = build(variant(ema_dict, drivetrain__0__torsional_stiffness="50 N*m/rad"))
    crit = soft.drivetrain.stiffness(Q).criterion()
    assert crit.ratio_large[0].all() and not crit.stiffness_comparable[0] and not crit.negligible[0]
    assert crit.stiffness_to_later[0] == pytest.approx(50 / (2.24e7 * R**2), rel=1e-4)
    data = variant(ema_dict)
    data["drivetrain"] = [{"kind": "compliance", "name": f"s{i}", "stiffness": f"{k} N*m/deg"}
                          for i, k in enumerate((1096623, 8256825, 1696.8, 1021.5))]
    chain = build(data).drivetrain.stiffness(Q)
    assert chain.negligible()[0] and not chain.criterion().negligible.any()
    assert chain.criterion().later_ratio[:3] == pytest.approx(np.ones((3, Q.size)))
    # a larger threshold turns the reference gear stage's verdict around (its ratio is < 100)
    assert not ema_drivetrain_negligible(min_ratio=100.0)


def ema_drivetrain_negligible(**kw):
    return bool(load_scene(SCENES / "ema_reference.toml").drivetrain.stiffness(Q).criterion(**kw).negligible[0])


def test_output_units_of_the_scenes():
    units = {p.stem: load_scene(p).drivetrain.output_unit for p in SCENES.glob("*.toml")
             if p.stem not in ("deflection_platform", "roller_screw_two_stage")}
    assert units == {"ema_reference": "rad", "ema_robust": "rad", "ema_sizing": "rad", "cam_follower": "rad",
                     "linear_roller_screw_actuator": "m", "emps": "m"}
    lin = load_scene(SCENES / "linear_roller_screw_actuator.toml").drivetrain
    assert lin.output_is_linear
    # motor rad per m of last-nut travel: gear 2 * screw 2 pi / (10 mm + 10 mm)
    assert lin.ratio([0.0])[0][0] == pytest.approx(2 * 2 * math.pi / 0.020)
    # the last nut (and its rollers) moves with the output: its reflected mass is its mass
    parts = lin.reflected_inertias([0.0]).by_label()
    assert parts["two-stage roller screw: nut and rollers 2"][0][0] == pytest.approx(20 + 7 * 0.039)
