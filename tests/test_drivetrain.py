"""Drivetrain reflection checked against independent geometry, closed forms and seed 001."""

import math

import numpy as np
import pytest

from servo_toolkit import load_scene
from servo_toolkit.drivetrain import series
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


def test_reflected_inertia_equals_kinetic_energy(ema):
    """J(q) qdot^2/2 equals the kinetic energy computed from the bodies' own motion."""
    dt = ema.drivetrain
    motor_angle = lambda p: 52 / 24 * 2 * math.pi / 0.005 * geometry(p)[0][0]
    screw_angle = lambda p: 2 * math.pi / 0.005 * geometry(p)[0][0]

    def kinetic_energy(phi, qdot=1.0, h=1e-6):
        a0, b0 = geometry(phi - h)
        a1, b1 = geometry(phi + h)
        va, vb = (a1 - a0) / (2 * h) * qdot, (b1 - b0) / (2 * h) * qdot
        vc = 0.5 * (va + vb)
        omega_rod = fd(lambda p: np.arctan2(*(geometry(p)[1] - geometry(p)[0])[::-1]), phi) * qdot
        bar = 0.5 * 0.15 * np.sum(vc**2, axis=0) + 0.5 * (0.15 * 0.12**2 / 12) * omega_rod**2
        nut = 0.5 * 0.6 * va[0] ** 2
        screw = 0.5 * 1.3e-5 * (fd(screw_angle, phi) * qdot) ** 2
        gears = sum(0.5 * j * (fd(motor_angle, phi) * 24 / z * qdot) ** 2
                    for j, z in [(1e-5, 24), (2.2e-5, 40), (3.5e-5, 52)])
        rotor = 0.5 * 2e-4 * (fd(motor_angle, phi) * qdot) ** 2
        out = 0.5 * (1.2e-3 + 1.0) * qdot**2
        return bar + nut + screw + gears + rotor + out

    j, dj = dt.inertia(Q)
    assert 0.5 * j == pytest.approx(kinetic_energy(Q), rel=1e-6)
    assert dj == pytest.approx(fd(lambda p: dt.inertia(p)[0], Q, 1e-5), rel=1e-5, abs=1e-6)


def test_motor_side_inertia_and_lash(ema):
    dt = ema.drivetrain
    n, _ = dt.ratio(Q)
    assert dt.motor_inertia(Q) == pytest.approx(dt.inertia(Q)[0] / n**2)
    # gear lash at the screw shaft -> divided by the screw's ratio; nut lash -> by dx/dphi
    dx = fd(lambda p: geometry(p)[0][0], Q)
    expected = math.radians(0.1) / (2 * math.pi / 0.005 * dx) + 1e-5 / dx
    assert dt.backlash(Q) == pytest.approx(expected, rel=1e-7)
    assert dt.efficiency == pytest.approx(0.97 * 0.90)


def test_stroke_and_operating_point(ema):
    assert ema.drivetrain.stroke == pytest.approx((-math.pi / 6, math.pi / 6))
    assert ema.drivetrain.mid_stroke == pytest.approx(0.0)
