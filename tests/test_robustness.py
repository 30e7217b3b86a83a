"""Robustness over load inertia and stiffness: vectorized figures against python-control."""

from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

import servo_toolkit as st
from servo_toolkit.loop.robustness import reference_margins, robustness


@pytest.fixture(scope="module")
def case():
    scene = st.load_scene()
    return scene, st.design(scene, resonance_filter="none")


def test_nominal_variant_reproduces_the_design(case):
    scene, r = case
    rb = robustness(scene, r, {"load_inertia": [scene.load.inertia], "stiffness": [1.0]}, progress=False)
    assert rb.figures["stable"][0]
    # crossings and bandwidth are solved for on both sides (python-control: polynomial roots
    # and bisection); the nominal Ms of the design is sampled on a 2000-point grid
    np.testing.assert_allclose(rb.figures["phase_margin_deg"][0], r.margins.phase_margin_deg, atol=1e-2)
    np.testing.assert_allclose(rb.figures["gain_margin_db"][0], abs(r.margins.gain_margin_db), atol=1e-3)
    np.testing.assert_allclose(rb.figures["bandwidth_hz"][0], r.margins.bandwidth_hz, rtol=1e-9)
    assert 0 <= rb.figures["sensitivity_peak_db"][0] - r.margins.sensitivity_peak_db < 0.01


@pytest.mark.parametrize("load,k", [(0.0, 0.7), (2.5, 1.3), (4.0, 0.7)])
def test_vectorized_figures_match_python_control(case, load, k):
    scene, r = case
    rb = robustness(scene, r, {"load_inertia": [load], "stiffness": [k]}, progress=False, exact=False)
    (gm, pm, *_), loop = reference_margins(scene, r, load, k)
    assert rb.figures["stable"][0] == bool(np.all(np.real(__import__("control").poles(
        __import__("control").feedback(loop, 1))) < 0))
    np.testing.assert_allclose(rb.figures["phase_margin_deg"][0], pm, atol=1e-2)
    np.testing.assert_allclose(rb.figures["gain_margin_db"][0], abs(20 * np.log10(gm)), atol=1e-3)


def test_worst_case_and_executor(case):
    scene, r = case
    a = robustness(scene, r, samples=300, seed=3, progress=False)
    with ThreadPoolExecutor(2) as pool:
        b = robustness(scene, r, samples=300, seed=3, executor=pool, chunk_size=100, progress=False)
    for key in a.figures:
        np.testing.assert_array_equal(a.figures[key], b.figures[key])
    pm = a.requirements[[c.name for c in a.requirements].index("phase_margin")]
    stable = a.figures["stable"]
    assert pm.achieved == pytest.approx(np.min(a.figures["phase_margin_deg"][stable]))
    assert 0 <= a.worst["phase_margin"]["load_inertia"] <= 4
    assert "robustness over 300 variants" in a.table()
    grid = robustness(scene, r, samples=16, grid=True, progress=False)
    assert grid.count == 16 and set(np.round(grid.values["stiffness"], 6)) == {0.7, 0.9, 1.1, 1.3}


# --- [robustness] table -------------------------------------------------------------------

import math  # noqa: E402
import warnings  # noqa: E402

import control as ct  # noqa: E402

from servo_toolkit import SceneError  # noqa: E402
from servo_toolkit.loop import mode_range, robust_requirements  # noqa: E402
from servo_toolkit.scene.loader import Robustness  # noqa: E402

from .conftest import SCENES, build, variant  # noqa: E402

TABLE = {"load_inertia": ["0 kg*m^2", "4 kg*m^2"], "stiffness": [0.7, 1.3], "samples": 200, "method": "grid",
         "seed": 3, "min_stable_fraction": 0.9, "min_gain_margin": "4 dB", "min_phase_margin": "30 deg",
         "max_sensitivity_peak": "8 dB", "min_bandwidth": "2 Hz"}


def test_robustness_table_in_si(ema_dict):
    r = build(variant(ema_dict, robustness=TABLE)).robustness
    assert r == Robustness(load_inertia=(0.0, 4.0), stiffness=(0.7, 1.3), samples=200, method="grid", seed=3,
                           min_stable_fraction=0.9, min_gain_margin=4.0, min_phase_margin=pytest.approx(math.pi / 6),
                           max_sensitivity_peak=8.0, min_bandwidth=2.0)
    only = build(variant(ema_dict, robustness={"stiffness": ["0.8", 1.2]})).robustness
    assert only.ranges == {"stiffness": (0.8, 1.2)} and (only.samples, only.method, only.seed) == (1000, "monte_carlo", 0)
    assert only.min_stable_fraction == 1.0 and only.min_gain_margin is None
    assert st.load_scene().robustness is None  # the reference scenes state none


@pytest.mark.parametrize("key,value,rule", [
    ("load_inertia", ["1 kg*m^2"], "expected [lo, hi]"),
    ("load_inertia", ["0 kg*m^2", "1 kg*m^2", "2 kg*m^2"], "expected [lo, hi]"),
    ("load_inertia", ["3 kg*m^2", "1 kg*m^2"], "lo must not exceed hi"),
    ("load_inertia", ["-1 kg*m^2", "1 kg*m^2"], "must not be negative"),
    ("load_inertia", ["0 kg", "1 kg"], "dimension mismatch"),
    ("load_inertia", "4 kg*m^2", "expected a list"),
    ("stiffness", [0.0, 1.3], "must be positive"),
    ("stiffness", [0.7, float("inf")], "must be finite"),
    ("samples", 0, "at least 1"),
    ("samples", 2_000_000, "at most 1000000"),
    ("samples", "100", "expected an integer"),
    ("method", "latin_hypercube", "must be one of"),
    ("seed", -1, "at least 0"),
    ("min_stable_fraction", 1.5, "fraction of the variants"),
    ("min_stable_fraction", -0.1, "must not be negative"),
    ("min_gain_margin", "-1 dB", "must not be negative"),
    ("min_phase_margin", "200 deg", "below 180 deg"),
    ("min_phase_margin", "0 deg", "must be positive"),
    ("max_sensitivity_peak", "0 dB", "must be positive"),
    ("min_bandwidth", "-2 Hz", "must be positive"),
    ("min_bandwidth", "2 s", "dimension mismatch"),
    ("speed", [0, 1], "unknown key"),
    ("name", "x", "unknown key"),
])
def test_every_robustness_rule_names_its_key(ema_dict, key, value, rule):
    with pytest.raises(SceneError) as err:
        build(variant(ema_dict, robustness=dict(TABLE, **{key: value})))
    assert err.value.key.split("[")[0] == f"robustness.{key}" and rule in err.value.rule  # [i]: the element


def test_robustness_needs_a_range_and_a_table(ema_dict):
    with pytest.raises(SceneError) as err:
        build(variant(ema_dict, robustness={"samples": 10}))
    assert err.value.key == "robustness.load_inertia" and "give load_inertia and/or stiffness" in err.value.rule
    with pytest.raises(SceneError) as err:
        build(variant(ema_dict, robustness=3))
    assert err.value.key == "robustness"


def test_robust_requirements_default_to_the_nominal_ones(case):
    scene, r = case
    reqs = {q.name: q for q in robust_requirements(Robustness(), r.requirements)}
    assert set(reqs) == {"stable_fraction", "gain_margin", "phase_margin", "sensitivity_peak"}
    assert reqs["stable_fraction"].value == 1.0
    for name in ("gain_margin", "phase_margin", "sensitivity_peak"):
        nominal = next(c for c in r.requirements if c.name == name)
        assert (reqs[name].value, reqs[name].source) == (nominal.required, "nominal")
    spec = build(variant(tomllib_ema(), robustness=TABLE)).robustness
    reqs = {q.name: q for q in robust_requirements(spec, r.requirements)}
    assert reqs["phase_margin"].value == pytest.approx(30.0) and reqs["phase_margin"].source == "robustness"
    assert reqs["bandwidth"].value == 2.0 and reqs["stable_fraction"].value == 0.9


def tomllib_ema():
    import tomllib
    return tomllib.loads((SCENES / "ema_reference.toml").read_text())


# --- physics: the load inertia moves the drivetrain mode ----------------------------------

def test_mode_range_is_the_two_mass_mode_at_the_corners(case):
    scene, r = case
    p = r.parameters
    rng = mode_range(p, scene.load.inertia, {"load_inertia": (0.0, 4.0), "stiffness": (0.7, 1.3)})
    # undamped two-mass eigenvalues at the heavy, soft corner (independent of the closed form)
    J1, J2, K = p.J1, p.J2 + 4.0 - scene.load.inertia, 0.7 * p.K
    A = np.array([[0, 1, 0, 0], [-K / J1, 0, K / J1, 0], [0, 0, 0, 1], [K / J2, 0, -K / J2, 0]])
    wr = np.max(np.abs(np.linalg.eigvals(A).imag))
    assert rng["resonance_hz"][0] == pytest.approx(wr / (2 * math.pi), rel=1e-9)
    assert rng["antiresonance_hz"][0] == pytest.approx(math.sqrt(K / J2) / (2 * math.pi), rel=1e-12)
    assert 12 < rng["antiresonance_hz"][0] < 13 and rng["antiresonance_hz"][1] > 500  # 12.3 Hz .. ~800 Hz


# --- the nominal design fails the variants, the robust one holds them ---------------------

@pytest.fixture(scope="module")
def robust_scene():
    return st.load_scene(SCENES / "ema_robust.toml")


@pytest.fixture(scope="module")
def robust_design(robust_scene):
    return st.design(robust_scene, progress=False)  # [robustness] present -> robust design


def test_nominal_design_leaves_variants_unstable(robust_scene):
    # the notch on the nominal anti-resonance at q0 (the design on q0's plant alone)
    nominal = st.design(robust_scene, robust=False, over_stroke=False)
    assert nominal.robustness is None and nominal.motion.filter == "notch"
    rb = robustness(robust_scene, nominal, spec=robust_scene.robustness, progress=False)
    frac = next(c for c in rb.requirements if c.name == "stable_fraction")
    assert not frac.passed and frac.achieved < 0.5 and rb.unstable_count > 500
    assert not rb.passed


def test_robust_design_keeps_every_sampled_variant_stable_with_margins(robust_scene, robust_design):
    r = robust_design
    rb = r.robustness
    assert rb.count == 1000 and rb.settings == {"method": "monte_carlo", "samples": 1000, "seed": 0}
    assert rb.all_stable and np.all(rb.figures["max_pole_real"] < 0)
    checks = {c.name: c for c in rb.requirements}
    assert set(checks) == {"stable_fraction", "gain_margin", "phase_margin", "sensitivity_peak"}
    assert checks["stable_fraction"].passed and checks["gain_margin"].passed and checks["phase_margin"].passed
    assert checks["gain_margin"].achieved >= 6.0 and checks["phase_margin"].achieved >= 45.0
    # the search holds its grid's closed-form variants to 6 dB; the row's worst variant, built
    # from the scene (heavy and soft: the chain's reduction moves with the load), is measured
    # 0.0056 dB over it, and the row says so rather than the closed form's 5.999 dB
    ms = checks["sensitivity_peak"]
    assert 6.0 < ms.achieved < 6.01 and not ms.passed, rb.table()
    # the position loop crosses over below the lowest anti-resonance of the range
    low = mode_range(r.parameters, robust_scene.load.inertia, robust_scene.robustness.ranges)["antiresonance_hz"][0]
    assert max(r.margins.gain_crossover_hz) < low
    assert r.margins.closed_loop_stable


def test_robust_design_states_what_it_misses(robust_design):
    # measured: with every variant held to 6 dB / 45 deg / 6 dB, the nominal 8 Hz bandwidth
    # (and the 90 deg lag at 8 Hz) is missed by a few percent, and the worst variant's Ms, built
    # from the scene, by 0.0056 dB; the result must say so
    r = robust_design
    assert not r.passed
    failing = {c.name for c in r.failures}
    assert failing and failing <= {"bandwidth", "phase_lag_at_bandwidth", "robust_sensitivity_peak"}
    for c in r.failures:  # a robust row's note names its worst case
        note = next(n for n in r.notes if f"misses {c.name.replace('robust_', 'worst-case ')}" in n)
        assert f"{c.achieved:.4g}" in note and f"short by {c.shortfall:.3g}" in note
    bw = next(c for c in r.requirements if c.name == "bandwidth")
    assert 0 < bw.shortfall < 1.0  # Hz
    d = r.to_dict()
    assert d["requirements_met"] is False and d["robustness"]["passed"] is False
    assert any("misses worst-case sensitivity_peak" in n for n in r.notes)
    confirm = next(n for n in r.notes if "rebuilt as a state-space loop" in n)
    assert "closed loop stable" in confirm and "DISAGREES" not in confirm


def test_worst_case_agrees_with_python_control(robust_scene, robust_design):
    r, rb = robust_design, robust_design.robustness
    at = rb.worst["phase_margin"]
    assert at["load_inertia"] > 3.5 and at["stiffness"] < 0.8  # heavy and soft: the lowest mode
    # each row's worst variant is built from the scene: python-control on that same plant
    (gm, pm, *_), loop = reference_margins(robust_scene, r, at["load_inertia"], at["stiffness"], exact=True)
    checks = {c.name: c for c in rb.requirements}
    gms, pms, *_ = ct.stability_margins(loop, returnall=True)
    np.testing.assert_allclose(checks["phase_margin"].achieved, np.min(pms), atol=1e-2)
    at_gm = rb.worst["gain_margin"]
    (_, _, *_), loop_gm = reference_margins(robust_scene, r, at_gm["load_inertia"], at_gm["stiffness"], exact=True)
    gms, _, _, wpc, *_ = ct.stability_margins(loop_gm, returnall=True)
    np.testing.assert_allclose(checks["gain_margin"].achieved, np.min(np.abs(20 * np.log10(gms[wpc > 1e-3]))),
                               atol=1e-3)
    at_ms = rb.worst["sensitivity_peak"]
    _, loop_ms = reference_margins(robust_scene, r, at_ms["load_inertia"], at_ms["stiffness"], exact=True)
    w = 2 * np.pi * np.logspace(-1, 3, 40000)
    lw = np.asarray(ct.frequency_response(loop_ms, w).complex).reshape(-1)
    # the dense grid (step 2.3e-4 in ln w) samples the peak from below, within ~1e-5 dB
    dense = 20 * np.log10(np.max(np.abs(1 / (1 + lw))))
    assert -1e-9 <= checks["sensitivity_peak"].achieved - dense < 1e-3
    sm = ct.stability_margins(loop_ms, returnall=True)[2]  # every local minimum of |1 + L|
    np.testing.assert_allclose(checks["sensitivity_peak"].achieved, -20 * np.log10(np.min(sm)), atol=1e-3)
    # and the closed loop of that variant is stable by its poles
    assert np.all(ct.poles(ct.feedback(loop, 1)).real < 0)


# --- crossings, Ms and bandwidth refined to solver precision ------------------------------

from servo_toolkit.loop.margins import frequency_grid  # noqa: E402
from servo_toolkit.loop.metrics import ROOT_TOLERANCES, grid_figures, loop_crossings  # noqa: E402
from servo_toolkit.loop.response import state_space_response  # noqa: E402

GAINS = np.array([0.3, 1.0, 4.0, 25.0, 300.0])


def _textbook(order):
    """L = K / (s (s + 1)) or K / (s (s + 1) (s + 2)) for every K in GAINS, as a response."""
    def response(rows, w):
        s = 1j * np.asarray(w, float)
        den = s * (s + 1) * ((s + 2) if order == 3 else 1)
        return GAINS[rows] / den
    return response


@pytest.mark.parametrize("points", [40, 600])
def test_textbook_loops_refine_to_their_closed_forms(points):
    # a coarse grid (40 points over 4 decades) only brackets; the figures come from the solver
    w = frequency_grid(f_min=1e-3, f_max=10.0, points=points)
    rows = np.arange(GAINS.size)[:, None]
    r2, r3 = _textbook(2), _textbook(3)
    f2 = grid_figures(w, r2(rows, w[None, :]), response=r2)
    f3 = grid_figures(w, r3(rows, w[None, :]), response=r3)
    K = GAINS
    # K/(s(s+1)): |L| = 1 at wc^2 = (sqrt(1 + 4 K^2) - 1) / 2, PM = atan(1 / wc)
    wc = np.sqrt((np.sqrt(1 + 4 * K**2) - 1) / 2)
    np.testing.assert_allclose(f2["phase_margin_deg"], np.degrees(np.arctan(1 / wc)), rtol=0, atol=1e-6)
    assert np.all(np.isinf(f2["gain_margin_db"]))  # the phase never reaches -180 deg
    # max |S|^2 = u (1 + u) / ((K - u)^2 + u) at u = w^2 = (K + sqrt(K^2 + 2K)) / 2
    u = (K + np.sqrt(K**2 + 2 * K)) / 2
    ms = 10 * np.log10(u * (1 + u) / ((K - u) ** 2 + u))
    np.testing.assert_allclose(f2["sensitivity_peak_db"], ms, rtol=0, atol=1e-6)
    # |T| = 10^(-3/20) of K/(s^2 + s + K): u^2 + (1 - 2K) u + K^2 (1 - 1/a^2) = 0
    a2 = 10 ** (-3 / 10)
    ub = ((2 * K - 1) + np.sqrt((1 - 2 * K) ** 2 - 4 * K**2 * (1 - 1 / a2))) / 2
    np.testing.assert_allclose(f2["bandwidth_hz"], np.sqrt(ub) / (2 * np.pi), rtol=1e-9)
    # K/(s(s+1)(s+2)): phase -180 deg at w = sqrt(2) where |L| = K / 6
    np.testing.assert_allclose(f3["gain_margin_db"], np.abs(20 * np.log10(6 / K)), rtol=0, atol=1e-6)
    c = loop_crossings(w, r3(rows, w[None, :]), r3)
    np.testing.assert_array_equal(np.sort(c["phase_rows"]), np.arange(K.size))
    np.testing.assert_allclose(c["phase_crossover"], np.sqrt(2), rtol=1e-10)
    # the K = 300 loop is unstable: GM negative, like python-control's 20 log10(gm)
    np.testing.assert_allclose(c["gain_margin_db"][np.argsort(c["phase_rows"])], 20 * np.log10(6 / K), atol=1e-6)
    if points == 40:  # and the grid alone is far from them (the test can fail)
        g2 = grid_figures(w, r2(rows, w[None, :]))
        assert np.max(np.abs(g2["phase_margin_deg"] - np.degrees(np.arctan(1 / wc)))) > 1e-2


def test_refined_crossings_meet_the_solver_tolerance():
    # the refined frequency solves |L| = 1 to the root tolerance in ln(w): the residual
    # ln|L| is at most the slope (-1 .. -2 for these loops) times that tolerance
    w = frequency_grid(f_min=1e-3, f_max=10.0, points=60)
    r3 = _textbook(3)
    rows = np.arange(GAINS.size)
    c = loop_crossings(w, r3(rows[:, None], w[None, :]), r3)
    x = np.log(c["gain_crossover"])
    tol = 2 * (ROOT_TOLERANCES["xatol"] + ROOT_TOLERANCES["xrtol"] * np.abs(x)) + ROOT_TOLERANCES["fatol"]
    resid = np.abs(np.log(np.abs(r3(c["gain_rows"], c["gain_crossover"]))))
    assert np.all(resid <= 3 * tol), resid


def test_state_space_response_matches_python_control(case):
    s = 1j * np.logspace(-2, 4, 50)
    notch = ct.tf2ss(ct.tf([1, 2, 4e4], [1, 100, 4e4]))
    for sys in (case[1].controller.motion, notch, ct.tf2ss(*ct.pade(0.0015, 2)),
                ct.ss([[0.0, 1.0], [0.0, 0.0]], [[0.0], [1.0]], [[1.0, 0.0]], [[0.0]])):  # defective: solve path
        ref = np.moveaxis(np.asarray(sys(s)).reshape(sys.noutputs, sys.ninputs, -1), -1, 0)
        got = state_space_response(sys.A, sys.B, sys.C, sys.D, s)
        np.testing.assert_allclose(got, ref, rtol=1e-10, atol=1e-12 * np.abs(ref).max())


def _two_mass_resonance_hz(p, scene, load, k):
    J2, K = p.J2 + load - scene.load.inertia, p.K * k
    return math.sqrt(K * (1 / p.J1 + 1 / J2)) / (2 * math.pi) if J2 > 0 else math.inf


@pytest.mark.parametrize("notch", [True, False])
def test_refined_margins_agree_with_python_control_on_hundreds_of_variants(case, notch):
    scene, r = case
    if notch:
        # the narrow notch at q0, margins only (no current-ripple bound lowering the speed gain):
        # crossings next to the resonance
        r = st.design(scene, over_stroke=False, current_ripple=math.inf)
    loads, ks = np.meshgrid(np.linspace(0.0, 4.0, 15), np.linspace(0.7, 1.3, 15))
    # and a dense line where a crossing sits on the resonance (measured: 22-25 Hz)
    values = {"load_inertia": np.concatenate([loads.ravel(), np.linspace(1.3, 1.7, 25)]),
              "stiffness": np.concatenate([ks.ravel(), np.full(25, 1.04)])}
    rb = robustness(scene, r, values, progress=False, exact=False)
    coarse = robustness(scene, r, values, progress=False, refine=False, exact=False)
    d = {"pm": [], "gm": [], "ms": [], "pm_grid": []}
    near = 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for i, (load, k) in enumerate(zip(values["load_inertia"], values["stiffness"])):
            _, loop = reference_margins(scene, r, load, k)
            gm, pm, sm, wpc, wgc, _ = ct.stability_margins(loop, returnall=True)
            gm_db = 20 * np.log10(gm[wpc > 1e-3])
            d["pm"].append(rb.figures["phase_margin_deg"][i] - np.min(pm))
            d["pm_grid"].append(coarse.figures["phase_margin_deg"][i] - np.min(pm))
            d["gm"].append(rb.figures["gain_margin_db"][i] - np.min(np.abs(gm_db)))
            d["ms"].append(rb.figures["sensitivity_peak_db"][i] + 20 * np.log10(np.min(sm)))
            fr = _two_mass_resonance_hz(r.parameters, scene, load, k)
            near += bool(np.any(np.abs(wgc / (2 * np.pi) / fr - 1) < 0.1))
    d = {key: np.abs(v) for key, v in d.items()}
    assert np.max(d["pm"]) < 1e-2 and np.max(d["gm"]) < 1e-3 and np.max(d["ms"]) < 1e-3, \
        {key: float(np.max(v)) for key, v in d.items()}
    if notch:  # crossings within 10 % of the two-mass resonance are covered, and on the
        # grid alone those steep crossings are off by more (the test can fail)
        assert near >= 10, near
        assert np.max(d["pm_grid"]) > 1e-2


def test_a_pair_of_gain_crossings_inside_one_grid_step_is_found():
    # G w0^2 / (s^2 + 2 zeta w0 s + w0^2) peaks at 1.02 midway between two grid points, where
    # the grid reads ~0.92: no sign change brackets the two crossings; the grid maximum does
    w = frequency_grid(f_min=1e-3, f_max=10.0, points=200)
    k = np.searchsorted(w, 1.0)
    zeta, w0 = 0.05, np.sqrt(w[k - 1] * w[k]) / np.sqrt(1 - 2 * 0.05**2)
    gain = 1.02 * 2 * zeta * np.sqrt(1 - zeta**2)
    loop = ct.tf([gain * w0**2], [1, 2 * zeta * w0, w0**2])

    def response(rows, ww):
        return np.asarray(loop(1j * np.asarray(ww, float)))

    L = response(None, w)[None, :]
    assert np.max(np.abs(L)) < 0.95
    c = loop_crossings(w, L, response)
    _, pm, _, _, wgc, _ = ct.stability_margins(loop, returnall=True)
    assert c["gain_crossover"].size == 2
    order = np.argsort(c["gain_crossover"])
    np.testing.assert_allclose(c["gain_crossover"][order], np.sort(wgc), rtol=1e-9)
    np.testing.assert_allclose(c["phase_margin_deg"][order], pm[np.argsort(wgc)], atol=1e-6)
