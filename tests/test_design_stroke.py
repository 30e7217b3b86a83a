"""The designed loop along the stroke: default operating point and the stroke check."""

import json
import math
import warnings
import xml.etree.ElementTree as ET

import control as ct
import numpy as np
import pytest

import servo_toolkit as st
from servo_toolkit.cli import main
from servo_toolkit.cli.common import to_json
from servo_toolkit.errors import SceneError
from servo_toolkit.loop import open_loop
from servo_toolkit.loop.robustness import _controller_blocks
from servo_toolkit.loop.stroke import INERTIA_SPREAD_LIMIT, StrokeLoops, operating_point, stroke_check
from servo_toolkit.plant.linear import plant_parameters

from .conftest import SCENES

CAM = SCENES / "cam_follower.toml"
EMA = SCENES / "ema_reference.toml"
# seed 002's cam: rotor inertia, follower mass and profile constant A
JM, M_FOLLOWER, A = 4.41e-5, 0.4, 0.035


@pytest.fixture(scope="module")
def cam():
    return st.load_scene(CAM)


@pytest.fixture(scope="module")
def ema():
    return st.load_scene(EMA)


@pytest.fixture(scope="module")
def cam_design(cam):
    return st.design(cam)


@pytest.fixture(scope="module")
def ema_design(ema):
    return st.design(ema)


def _python_control(scene, controller, q):
    """(closed loop stable, smallest phase margin, smallest |gain margin| dB) from python-control,
    the plant rebuilt at ``q`` and the loop closed with ``feedback``."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        loop = open_loop(scene, controller, q)
        stable = bool(np.all(ct.poles(ct.feedback(loop, 1)).real < 0))
        gm, pm, _, wpc, _, _ = ct.stability_margins(loop, returnall=True)
    gm, pm, wpc = (np.atleast_1d(np.asarray(x, float)) for x in (gm, pm, wpc))
    keep = np.isfinite(gm) & (gm > 0) & (wpc > 1e-3)
    gm_db = np.abs(20 * np.log10(gm[keep]))
    return stable, float(pm.min()) if pm.size else math.inf, float(gm_db.min()) if gm_db.size else math.inf


def test_cam_is_designed_at_its_largest_inertia(cam, cam_design):
    r = cam_design
    # constant-velocity segments of the law: ds/dtheta = 2A, J = Jm + m (2A)^2 (seed 002)
    j_max = JM + M_FOLLOWER * (2 * A) ** 2
    assert r.parameters.rigid and r.parameters.J1 == pytest.approx(j_max, rel=1e-9)
    assert math.radians(45) <= r.q0 <= math.radians(135)
    assert math.degrees(r.q0) == pytest.approx(90.0)
    note = next(n for n in r.notes if n.startswith("operating point"))
    assert "largest" in note and f"{INERTIA_SPREAD_LIMIT:g}x" in note
    # an explicit q0 wins
    assert operating_point(cam, 0.3) == (0.3, None)
    assert st.design(cam, 0.3).q0 == 0.3


def test_cam_design_is_stable_at_every_cam_angle(cam, cam_design):
    r = cam_design
    assert r.passed, r.table()
    check = next(c for c in r.requirements if c.name == "stable_over_stroke")
    assert check.passed and check.achieved == 1.0
    assert r.stroke.all_stable and r.stroke.q.size >= 24
    # independently, python-control at angles off the stroke grid too (22.5 deg failed before)
    for deg in np.arange(0.0, 360.0, 22.5):
        stable, pm, _ = _python_control(cam, r.controller, math.radians(deg))
        assert stable and pm > 45.0, (deg, pm)
    # the grid figures agree with python-control where they meet
    for k in range(0, r.stroke.q.size, 3):
        _, pm, _ = _python_control(cam, r.controller, r.stroke.q[k])
        assert r.stroke.phase_margin_deg[k] == pytest.approx(pm, abs=1e-6)


def test_largest_inertia_is_the_stable_direction(cam_design):
    # designed at the largest inertia, every lighter point keeps at least the design's phase
    # margin: the speed-loop crossover kv Kt / J rises as J drops, away from the PI corner
    s = cam_design.stroke
    at_q0 = s.phase_margin_deg[np.argmin(np.abs(s.q - s.q0))]
    assert np.all(s.phase_margin_deg >= at_q0 - 1e-9)
    lightest = np.argmin(s.motor_inertia)
    assert s.phase_margin_deg[lightest] > at_q0 + 1.0


def test_mid_stroke_cam_design_fails_stable_over_stroke(cam):
    # designed on the dwell's plant alone: ds/dtheta = 0, the follower adds nothing
    r = st.design(cam, q0=math.pi, over_stroke=False)
    assert r.parameters.J1 == pytest.approx(JM, rel=1e-9)
    assert r.margins.closed_loop_stable and r.margins.phase_margin_deg > 45  # fine at q0 ...
    check = next(c for c in r.requirements if c.name == "stable_over_stroke")
    assert not check.passed and check.achieved < 1.0 and check.shortfall > 0  # ... not along the turn
    assert not r.passed and check in r.failures
    assert any("UNSTABLE" in n for n in r.notes)
    unstable = r.stroke.unstable_q
    assert np.any(np.isclose(unstable, math.radians(90)))
    # python-control agrees: the rise (largest inertia) is unstable with the dwell's gains
    assert not _python_control(cam, r.controller, math.radians(90))[0]
    assert not _python_control(cam, r.controller, math.radians(22.5))[0]
    assert _python_control(cam, r.controller, math.pi)[0]


def test_ema_reference_design_is_stable_over_its_stroke(ema, ema_design):
    r = ema_design
    assert r.q0 == 0.0 and not any(n.startswith("operating point") for n in r.notes)  # spread < 1.5x
    dt = ema.drivetrain
    j = dt.motor_inertia(np.linspace(*dt.stroke, 61))
    assert j.max() / j.min() < INERTIA_SPREAD_LIMIT
    assert r.stroke.all_stable and r.passed
    s = r.stroke
    assert math.degrees(s.q[0]) == pytest.approx(-30) and math.degrees(s.q[-1]) == pytest.approx(30)
    for k in (0, s.q.size // 4, s.q.size // 2, s.q.size - 1):
        stable, pm, gm = _python_control(ema, r.controller, s.q[k])
        assert stable == bool(s.stable[k])
        assert s.phase_margin_deg[k] == pytest.approx(pm, abs=1e-4)
        assert s.gain_margin_db[k] == pytest.approx(gm, abs=1e-4)
    # the worst case is where it is and reported as such
    w = s.worst()
    assert w["gain_margin_db"]["value"] == pytest.approx(s.gain_margin_db.min())
    assert w["gain_margin_db"]["q_deg"] == pytest.approx(math.degrees(s.q[np.argmin(s.gain_margin_db)]))


def test_closed_form_loop_matches_python_control_off_the_design_point(ema, ema_design):
    # the controller keeps the design's ratio for its speed feedback; the plant's ratio moves
    r = ema_design
    q = np.radians([-30.0, 17.0])
    params = tuple(plant_parameters(ema, qi) for qi in q)
    assert params[0].N != pytest.approx(r.parameters.N, rel=0.05)
    loops = StrokeLoops(params, (r.controller.current_kp, r.controller.current_ki), _controller_blocks(r.controller))
    w = 2 * np.pi * np.array([0.3, 3.0, 25.0, 31.0, 300.0])
    for k, qi in enumerate(q):
        ref = np.asarray(ct.frequency_response(open_loop(ema, r.controller, qi), w).complex).reshape(-1)
        np.testing.assert_allclose(loops(np.full(w.size, k), w), ref, rtol=1e-8)


def test_stroke_json_keys(cam_design):
    d = json.loads(to_json(cam_design.to_dict()))
    s = d["stroke"]
    n = len(s["q_deg"])
    for key in ("stable", "gain_margin_db", "phase_margin_deg", "sensitivity_peak_db", "bandwidth_hz",
                "motor_side_inertia_kg_m2", "ratio", "max_pole_real"):
        assert len(s[key]) == n
    assert s["all_stable"] is True and s["q0_deg"] == pytest.approx(90.0)
    assert {"phase_margin_deg", "gain_margin_db", "sensitivity_peak_db", "bandwidth_hz"} <= set(s["worst"])
    assert {"value", "q_deg"} <= set(s["worst"]["phase_margin_deg"])
    assert d["requirements"]["stable_over_stroke"]["passed"] is True
    assert d["q0_deg"] == pytest.approx(90.0)


def test_check_reports_the_stroke_row(tmp_path, capsys):
    junit = tmp_path / "loop.xml"
    assert main(["check", str(CAM), "--junit", str(junit)]) == 0
    out = capsys.readouterr().out
    line = next(l for l in out.splitlines() if l.strip().startswith("stable_over_stroke"))
    assert "ok" in line
    names = [c.get("name") for c in ET.parse(junit).getroot().iter("testcase")]
    assert "stable_over_stroke" in names


def test_stroke_check_validates_points(ema, ema_design):
    s = stroke_check(ema, ema_design.controller, ema_design.q0, points=37)
    assert s.q.size >= 37
    with pytest.raises(SceneError, match="stroke_points"):
        stroke_check(ema, ema_design.controller, 0.0, points=1)
    assert st.loop.evaluate(ema, ema_design.controller, stroke_points=0).stroke is None
