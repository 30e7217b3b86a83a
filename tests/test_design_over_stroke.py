"""The nominal design held over the stroke: worst-case margins as requirements.

The reference EMA's rocker moves the drivetrain anti-resonance from 29.3 Hz (0 deg) to
25.9 Hz (-30 deg); a notch tuned at q0 alone leaves the end of the stroke with almost no
gain margin. The margins are recomputed here with python-control's ``stability_margins``
on loops assembled in the test from the plant built at each stroke point.
"""

import json
import math
import warnings

import control as ct
import numpy as np
import pytest

import servo_toolkit as st
from servo_toolkit.cli import main
from servo_toolkit.loop.closed_loop import DELAY_SAMPLES
from servo_toolkit.plant.current_loop import current_controller, sample_delay
from servo_toolkit.plant.linear import plant, plant_parameters

from .conftest import SCENES

EMA = SCENES / "ema_reference.toml"
LINEAR = SCENES / "linear_roller_screw_actuator.toml"
ROWS = {"gain_margin_over_stroke": "gain_margin", "phase_margin_over_stroke": "phase_margin",
        "sensitivity_peak_over_stroke": "sensitivity_peak"}


@pytest.fixture(scope="module")
def ema():
    return st.load_scene(EMA)


@pytest.fixture(scope="module")
def ema_design(ema):
    return st.design(ema)


@pytest.fixture(scope="module")
def single_point(ema):
    # margins only (no current-ripple bound on the speed gain): the gains a notch tuned at q0
    # alone would take, which the over-stroke rows must catch
    return st.design(ema, over_stroke=False, current_ripple=math.inf)


def _margins(scene, controller, q):
    """(stable, smallest |GM| dB, smallest PM deg, Ms dB) by python-control: the plant built
    at ``q``, current PI, Pade sampling delay and the motion controller interconnected here,
    the loop broken at the measured position."""
    g = plant(scene, q, inductance=True)
    cur = current_controller(controller.current_kp, controller.current_ki, scene.motor)
    dly = sample_delay(controller.sample_time, DELAY_SAMPLES)
    m = controller.motion
    cut = ct.ss(m.A, m.B, m.C, m.D, inputs=["theta_ref", "y", "omega_m"], outputs=["i_ref"])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sys = ct.interconnect([g, cur, dly, cut], inplist=["y"], outlist=["theta"], check_unused=False)
        loop = -sys  # L = -theta / y: negative unit feedback closes the position loop
        stable = bool(np.all(ct.poles(ct.feedback(loop, 1)).real < 0))
        gm, pm, sm, wpc, _, _ = ct.stability_margins(loop, returnall=True)
    gm, pm, sm, wpc = (np.atleast_1d(np.asarray(x, float)) for x in (gm, pm, sm, wpc))
    keep = np.isfinite(gm) & (gm > 0) & (wpc > 1e-3)
    gm_db = float(np.min(np.abs(20 * np.log10(gm[keep])))) if np.any(keep) else math.inf
    return stable, gm_db, float(pm.min()) if pm.size else math.inf, float(-20 * np.log10(sm.min()))


def _rows(result):
    return {c.name: c for c in result.requirements if c.name in ROWS}


def test_ema_design_meets_its_margins_at_every_stroke_point(ema, ema_design):
    r = ema_design
    rows = _rows(r)
    assert set(rows) == set(ROWS)
    required = {c.name: c for c in r.requirements}
    for name, point in ROWS.items():  # same required values as the point requirements
        assert rows[name].required == required[point].required and rows[name].sense == required[point].sense
    q = np.radians(np.linspace(-30.0, 30.0, 31))
    figs = np.array([_margins(ema, r.controller, qi) for qi in q])
    assert np.all(figs[:, 0] == 1.0)
    gm, pm, ms = figs[:, 1].min(), figs[:, 2].min(), figs[:, 3].max()
    assert gm >= 6.0 and pm >= 45.0 and ms <= 6.0, (gm, pm, ms)
    assert r.passed and all(c.passed for c in rows.values())
    # the rows are the worst over the stroke check's points (those include +-30 deg, 0 deg)
    assert rows["gain_margin_over_stroke"].achieved == pytest.approx(gm, abs=1e-3)
    assert rows["phase_margin_over_stroke"].achieved == pytest.approx(pm, abs=1e-2)
    assert rows["sensitivity_peak_over_stroke"].achieved == pytest.approx(ms, abs=1e-3)


def test_single_point_design_fails_the_over_stroke_rows(ema, single_point):
    r = single_point
    assert r.margins.closed_loop_stable and r.stroke.all_stable  # stable everywhere ...
    point = {c.name: c for c in r.requirements if c.name in ROWS.values()}
    assert all(c.passed for c in point.values())  # ... and fine at q0 ...
    rows = _rows(r)
    stable, gm, pm, ms = _margins(ema, r.controller, math.radians(-30.0))
    assert stable
    # ... but at the end of the stroke the walked-off mode leaves no margin (python-control)
    assert gm < 6.0 and pm < 45.0 and ms > 6.0
    assert rows["gain_margin_over_stroke"].achieved == pytest.approx(gm, abs=1e-3)
    assert rows["gain_margin_over_stroke"].shortfall == pytest.approx(6.0 - gm, abs=1e-3)
    assert rows["phase_margin_over_stroke"].shortfall == pytest.approx(45.0 - pm, abs=1e-2)
    assert rows["sensitivity_peak_over_stroke"].shortfall == pytest.approx(ms - 6.0, abs=1e-3)
    assert not any(c.passed for c in rows.values())
    assert not r.passed and set(ROWS) <= {c.name for c in r.failures}
    assert any("gain_margin_over_stroke" in n and "short by" in n and "-30 deg" in n for n in r.notes)
    # the same controller evaluated on its own gets the same rows
    again = _rows(st.loop.evaluate(ema, r.controller))
    assert again["gain_margin_over_stroke"].achieved == pytest.approx(gm, abs=1e-3)


def test_an_unstable_stroke_point_fails_every_margin_row():
    cam = st.load_scene(SCENES / "cam_follower.toml")
    r = st.design(cam, q0=math.pi, over_stroke=False)  # the dwell's gains: unstable on the rise
    assert not r.stroke.all_stable
    rows = _rows(r)
    for c in rows.values():  # no placeholder figure: each row fails with the reason
        assert not c.passed and math.isnan(c.achieved) and "unstable at" in c.reason
    fixed = st.design(cam, q0=math.pi)  # designed over the turn: stable at every cam angle
    assert fixed.stroke.all_stable and all(c.passed for c in _rows(fixed).values())


def test_rows_follow_overrides_and_reach_json_and_check(ema, tmp_path, capsys):
    r = st.design(ema, require={"gain_margin": 8.0})
    assert _rows(r)["gain_margin_over_stroke"].required == 8.0
    d = json.loads(json.dumps(st.design(ema).to_dict(), default=float))
    for name in ROWS:
        assert d["requirements"][name]["passed"] is True
    assert main(["check", str(EMA)]) == 0
    out = capsys.readouterr().out
    line = next(l for l in out.splitlines() if l.strip().startswith("gain_margin_over_stroke"))
    assert "ok" in line


def test_design_points_include_the_lowest_mode_and_the_ends(ema):
    from servo_toolkit.loop.stroke_design import design_points, stroke_filters
    q, params = design_points(ema, 0.0)
    assert q[0] == 0.0 and np.any(np.isclose(q, math.radians(-30))) and np.any(np.isclose(q, math.radians(30)))
    # the anti-resonance sqrt(K/J2)/(2 pi) of the two-mass plant, from its own eigenvalues:
    # with the motor side clamped, the load side alone rings at sqrt(K/J2)
    fa = []
    for qi in np.radians(np.linspace(-30, 30, 13)):
        p = plant_parameters(ema, qi)
        fa.append(math.sqrt(p.K / p.J2) / (2 * math.pi))
    lowest = min(p.antiresonance_hz for p in params)
    assert lowest == pytest.approx(min(fa), rel=1e-6)
    assert lowest < 0.9 * params[0].antiresonance_hz  # the mode walks > 10 % over the stroke
    notch = [fp for name, fp in stroke_filters(params) if name == "notch"]
    assert notch and all(lowest * 2 * math.pi < fp["wn"] < params[0].antiresonance_hz * 2 * math.pi for fp in notch)


def test_linear_output_points_are_in_mm():
    r = st.design(st.load_scene(LINEAR))
    note = next(n for n in r.notes if n.startswith("designed on"))
    assert "mm" in note and "deg" not in note.split("(")[0]
    assert "mm" in r.stroke.summary() and "deg" not in r.stroke.summary().split("kg")[0]


def test_a_travel_output_design_speaks_mm_kg_and_n_per_m(tmp_path):
    """A chain ending in a screw with a 20 kg, 500 N load (the [load] keys of a travel take
    a mass and forces): the load's mass adds to the plant's output-side mass, and q0, the
    masses and the stiffness are in mm, kg and N/m in the table and the JSON."""
    base = st.load_scene(LINEAR)
    scene_file = tmp_path / "linear.toml"
    scene_file.write_text(LINEAR.read_text() + '\n[load]\ninertia = "20 kg"\nhinge_moment = "500 N"\n'
                          'hinge_stiffness = "2 N/mm"\n')
    scene = st.load_scene(scene_file)
    assert scene.load.inertia == 20.0 and scene.load.hinge_moment == 500.0
    assert scene.load.hinge_stiffness == pytest.approx(2000.0)
    r = st.design(scene, over_stroke=False)
    j_base = st.design(base, over_stroke=False).parameters
    assert r.parameters.J1 + r.parameters.J2 == pytest.approx(j_base.J1 + j_base.J2 + 20.0, rel=1e-9)
    head = r.table().splitlines()[:2]
    assert head[0].endswith("at q0 = 0 mm") and " kg," in head[1] and "N/m" in head[1]
    assert "deg" not in head[0] and "kg*m^2" not in head[1]
    d = r.to_dict()
    assert d["q0_mm"] == 0.0 and "q0_deg" not in d
    assert d["plant"]["load_side_inertia_kg"] == r.parameters.J2 and "stiffness_n_per_m" in d["plant"]
    with pytest.raises(st.SceneError, match="load.inertia"):
        bad = tmp_path / "bad.toml"
        bad.write_text(LINEAR.read_text() + '\n[load]\ninertia = "2 kg*m^2"\n')
        st.load_scene(bad)




def test_a_worst_point_between_design_points_is_added_and_redesigned(ema, monkeypatch):
    import importlib
    design_module = importlib.import_module("servo_toolkit.loop.design")  # the module, not the function
    real = design_module.design_points

    def only_q0(scene, q0, model="auto", structural_damping=0.02, **kwargs):
        q, params = real(scene, q0, model, structural_damping, **kwargs)
        return q[:1], params[:1]  # as if the search saw q0 alone

    monkeypatch.setattr(design_module, "design_points", only_q0)
    r = st.design(ema)
    note = next(n for n in r.notes if n.startswith("designed on"))
    assert "worst points of the first search" in note and "-30 deg" in note
    assert r.passed and all(c.passed for c in _rows(r).values())
    stable, gm, pm, ms = _margins(ema, r.controller, math.radians(-30.0))
    assert stable and gm >= 6.0 and pm >= 45.0 and ms <= 6.0
