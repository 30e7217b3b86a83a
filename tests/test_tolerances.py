"""Tolerances: the scene table, the sampling, the yield's interval, the sensitivity ranking
(Ishigami's known indices, a tolerance that enters nothing), the variant plants against
exact builds and python-control, and the command line."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from servo_toolkit.cli import main
from servo_toolkit.errors import SceneError
from servo_toolkit.loop.sampling import sample_tolerances, unit_sample
from servo_toolkit.scene.loader import load_scene

from .conftest import SCENES

TOL = SCENES / "examples" / "ema_tolerances.toml"
SAMPLES = 256


@pytest.fixture(scope="module")
def scene():
    return load_scene(TOL)


@pytest.fixture(scope="module")
def designed(scene):
    from servo_toolkit.loop import design
    return design(scene, progress=False)


@pytest.fixture(scope="module")
def study(scene, designed):
    from servo_toolkit.studies.tolerances import tolerance_study
    return tolerance_study(scene, designed, samples=SAMPLES, progress=False)


# --- the scene table ------------------------------------------------------------------------

def test_every_distribution_form_is_read_in_si(scene):
    t = {x.key: x for x in scene.tolerances.items}
    r = t["motor.resistance"]
    assert (r.distribution, r.low, r.high, r.nominal) == ("uniform", 0.5, 0.7, 0.5)
    kt = t["motor.torque_constant"]
    assert kt.distribution == "normal" and kt.mean == 0.2 and kt.sigma == pytest.approx(0.004)
    assert (kt.low, kt.high) == pytest.approx((0.19, 0.21))
    f = t["motor.coulomb_friction"]
    assert (f.low, f.high) == pytest.approx((0.01, 0.06))
    v = t["motor.voltage_limit"]
    assert (v.low, v.high) == pytest.approx((243.0, 297.0))
    k = t["drivetrain[3].stiffness"]
    assert k.nominal == pytest.approx(1696.8 * 180 / math.pi) and k.unit == "N*m/rad"
    assert (k.low, k.high) == pytest.approx((0.85 * k.nominal, 1.15 * k.nominal))
    assert scene.tolerances.min_yield == 0.99 and scene.tolerances.samples == 1024


def test_robustness_ranges_are_tolerances_and_a_wide_range_is_log_uniform():
    robust = load_scene(SCENES / "ema_robust.toml").tolerances
    assert robust.keys == ("load.inertia", "drivetrain.stiffness_scale") and robust.min_yield is None
    assert (robust.item("load.inertia").low, robust.item("load.inertia").high) == (0.0, 4.0)
    from servo_toolkit.scene.loader import scene_keys
    from servo_toolkit.scene.tolerances import parse_distribution
    kp = scene_keys(load_scene(TOL)).resolve("drivetrain[3].stiffness")
    assert parse_distribution("x0.01:x10", kp, "w").distribution == "log_uniform"
    assert parse_distribution("x0.5:x2", kp, "w").distribution == "uniform"


BAD = {
    "unknown key": ('motor.resistence = "+-5 %"', "tolerances.motor.resistence", "motor has motor.ambient"),
    "bad distribution": ('motor.resistance = "about 5 %"', "tolerances.motor.resistance", "expected a range"),
    "negative sigma": ('motor.resistance = { sigma = "-0.1 ohm" }', "tolerances.motor.resistance",
                       "sigma must be positive"),
    "outside the conditioned range": ('motor.inductance = "0.5 mH:20 H"', "tolerances.motor.inductance",
                                      "range the model is conditioned for"),
    "a list key": ('"drivetrain[0].inertia" = "+-5 %"', "tolerances.drivetrain[0].inertia", "a list"),
    "a text key": ('motor.kind = "+-5 %"', "tolerances.motor.kind", "not a numeric key"),
    "lo above hi": ('load.inertia = "2 kg*m^2:1 kg*m^2"', "tolerances.load.inertia", "must not exceed"),
    "not physical": ('requirements.bandwidth = "+-5 %"', "tolerances.requirements.bandwidth",
                     "not a physical parameter"),
    "no yield above 1": ("min_yield = 1.5", "tolerances.min_yield", "must be in [1e-06, 1]"),
    "no certain confidence": ("confidence = 1.0", "tolerances.confidence", "must be in [0.5, 0.999999]"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_tolerance_tables_are_one_line_naming_the_key(case, tmp_path, capsys):
    line, key, rule = BAD[case]
    path = tmp_path / "bad.toml"
    path.write_text((SCENES / "ema_reference.toml").read_text() + f"\n[tolerances]\n{line}\n")
    assert main(["tolerances", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and key in err[0] and rule in err[0], err


def test_an_end_at_which_the_scene_does_not_load_names_the_tolerance(tmp_path):
    from servo_toolkit.scene.tolerances import check_ends
    path = tmp_path / "kt.toml"
    path.write_text((SCENES / "ema_reference.toml").read_text() + '\n[tolerances]\nmotor.torque_constant = "+-20 %"\n')
    with pytest.raises(SceneError, match=r"tolerances\.motor\.torque_constant: the scene does not load at 0\.16 "
                                         r"N\*m/A: motor\.back_emf_constant: must equal torque_constant within 10%"):
        check_ends(load_scene(path).tolerances)


# --- sampling -------------------------------------------------------------------------------

def test_latin_hypercube_holds_one_draw_per_stratum_and_sobol_is_balanced():
    n = 64
    u = unit_sample(3, n, "lhs", seed=3)
    for j in range(3):
        assert sorted(np.floor(u[:, j] * n).astype(int)) == list(range(n))
    s = unit_sample(2, n, "sobol", seed=3)  # a power of 2: every dyadic cell of width 1/n once
    for j in range(2):
        assert sorted(np.floor(s[:, j] * n).astype(int)) == list(range(n))
    assert unit_sample(2, 5, "random", seed=1).shape == (5, 2)


def test_draws_follow_each_distribution(scene):
    from scipy.stats import kstest, truncnorm
    values = sample_tolerances(scene.tolerances, 4000, "random", seed=5)
    kt = scene.tolerances.item("motor.torque_constant")
    a, b = (kt.low - kt.mean) / kt.sigma, (kt.high - kt.mean) / kt.sigma
    assert kstest(values[kt.key], truncnorm(a, b, loc=kt.mean, scale=kt.sigma).cdf).pvalue > 1e-3
    r = values["motor.resistance"]
    assert kstest((r - 0.5) / 0.2, "uniform").pvalue > 1e-3


# --- yield and sensitivity, against outside truth -------------------------------------------

def test_the_yield_interval_covers_the_true_yield_at_its_stated_rate():
    from servo_toolkit.core.yields import Yield, clopper_pearson, minimum_samples
    rng = np.random.default_rng(11)
    for p, n in ((0.97, 200), (0.6, 50)):
        draws = rng.binomial(n, p, size=4000)
        interval = {k: clopper_pearson(k, n, 0.95) for k in np.unique(draws)}  # one per count drawn
        cover = np.mean([interval[k][0] <= p <= interval[k][1] for k in draws])
        assert 0.943 <= cover <= 0.995, (p, n, cover)  # at least the level (Monte Carlo error 0.0035), not vacuous
    y = Yield.of("all", "every requirement", 368, 368, 0.95, 0.99)
    assert y.met and minimum_samples(0.99) == 368
    assert not Yield.of("all", "every requirement", 367, 367, 0.95, 0.99).met


def test_ishigami_sobol_indices_are_recovered():
    from scipy.stats import uniform

    from servo_toolkit.core.sensitivity import sobol
    a, b = 7.0, 0.1

    def ishigami(x):
        return (np.sin(x[0]) + a * np.sin(x[1]) ** 2 + b * x[2] ** 4 * np.sin(x[0]))[None]
    res = sobol(ishigami, [uniform(-np.pi, 2 * np.pi)] * 3, 1024, seed=2, resamples=100)
    v = a ** 2 / 8 + b * np.pi ** 4 / 5 + b ** 2 * np.pi ** 8 / 18 + 0.5
    v1, v2, v13 = 0.5 * (1 + b * np.pi ** 4 / 5) ** 2, a ** 2 / 8, b ** 2 * np.pi ** 8 * (1 / 18 - 1 / 50)
    first, total = np.array([v1, v2, 0.0]) / v, np.array([v1 + v13, v2, v13]) / v
    np.testing.assert_allclose(res["first"][0], first, atol=0.06)
    np.testing.assert_allclose(res["total"][0], total, atol=0.06)
    assert np.all(res["total_low"][0] - 0.02 <= total) and np.all(total <= res["total_high"][0] + 0.02)


def test_a_tolerance_that_enters_nothing_gets_a_share_indistinguishable_from_zero():
    from servo_toolkit.core.sensitivity import rank
    rng = np.random.default_rng(4)
    X = rng.random((2000, 3))
    y = 3 * X[:, 0] + X[:, 1] + 0.05 * rng.standard_normal(2000)
    s = rank("f", "f", "", ("a", "b", "idle"), X, y)
    assert s.method == "src" and s.r2 > 0.99 and s.top == "a"
    assert s.low[2] == 0.0 and s.high[2] < 1e-3  # its interval holds 0 and nothing more than noise
    np.testing.assert_allclose(s.share[:2], [9 / 10, 1 / 10], atol=0.01)  # 3^2 : 1^2 of the explained variance


def test_an_idle_tolerance_of_a_nonlinear_figure_gets_a_sobol_index_indistinguishable_from_zero():
    from scipy.stats import uniform

    from servo_toolkit.core.sensitivity import rank, sobol

    def f(x):  # x[2] enters nothing; x0 and x1 interact
        return np.sin(2 * np.pi * x[0]) * (1 + 4 * x[1] ** 2)
    rng = np.random.default_rng(6)
    X = rng.random((500, 3))
    s = rank("f", "f", "", ("a", "b", "idle"), X, f(X.T),
             sobol_run=lambda live: sobol(lambda x: f(x)[None], [uniform(0, 1)] * int(live.sum()), 512, seed=1))
    assert s.method == "sobol" and s.r2 < 0.9
    assert s.low[2] == 0.0 and abs(s.share[2]) < 1e-12 and s.high[2] < 1e-9  # not one evaluation moved it
    assert s.low[0] > 0.5 and s.low[1] > 0.05  # the two that enter are told apart from 0
    again = [sobol(lambda x: f(x)[None], [uniform(0, 1)] * 3, 64, seed=3, resamples=50) for _ in range(2)]
    for k in again[0]:  # seeded bootstrap: the intervals are the same in every process
        np.testing.assert_array_equal(again[0][k], again[1][k])


def test_keys_outside_the_linear_loop_get_exactly_zero(study):
    for s in study.sensitivities:
        ranking = {k: v for k, v, _, _ in s.ranking()}
        assert ranking["motor.coulomb_friction"] == 0.0 and ranking["motor.voltage_limit"] == 0.0
        assert s.to_dict()["ranking"][-1]["does_not_enter"]
    assert "motor.coulomb_friction" in study.notes[1]


# --- the variant plants and margins, against exact builds and python-control ----------------

def test_mapped_plants_equal_plants_built_from_the_varied_scene(scene, designed):
    from servo_toolkit.loop.variant_plants import FIELDS, check_matrices, keyed_plants
    from servo_toolkit.plant.linear import plant_parameters
    values = sample_tolerances(scene.tolerances, 64, seed=9)
    p = designed.parameters
    plants = keyed_plants(scene, p, values, 0.05)
    assert plants.method == "separable" and plants.error < 1e-4
    keys = scene.tolerances.scene_keys()
    for i in (0, 17):
        q = plant_parameters(keys.scene({k: v[i] for k, v in values.items()}), p.q0, "two_mass", 0.05)
        for f in FIELDS:
            assert plants.cols[f][i] == pytest.approx(getattr(q, f), rel=1e-4), f
    assert check_matrices(plants.cols, plants.rigid, 5) < 1e-9


def test_a_range_end_beyond_the_sampled_box_is_built_exactly():
    """The maps are verified over the sampled box: the robust scene's load-inertia range
    starts at 0, where a map in log(J) has no value; the worst-corner search asks for that
    end, and gets the plant of the scene built with it."""
    from servo_toolkit.loop.variant_plants import FIELDS, keyed_plants
    from servo_toolkit.plant.linear import plant_parameters
    from servo_toolkit.scene.loader import scene_keys
    robust = load_scene(SCENES / "ema_robust.toml")
    p = plant_parameters(robust, 0.0, "two_mass", 0.05)
    values = {"load.inertia": np.geomspace(0.01, 4.0, 24)}
    plants = keyed_plants(robust, p, values, 0.05)
    assert plants.method == "separable" and plants.mapper is not None
    ends = plants.mapper({"load.inertia": np.array([0.0, 4.0])})
    for i, J in enumerate((0.0, 4.0)):
        q = plant_parameters(scene_keys(robust).scene({"load.inertia": J}), p.q0, "two_mass", 0.05)
        for f in FIELDS:
            assert np.isfinite(ends.cols[f][i]) and ends.cols[f][i] == pytest.approx(getattr(q, f), rel=1e-4), f


def test_the_variant_grid_gives_the_figures_of_the_uniform_grid(scene, designed):
    from servo_toolkit.loop.robustness import variant_figures
    values = sample_tolerances(scene.tolerances, 48, seed=2)
    f_req = next(r.required for r in designed.requirements if r.name == "bandwidth")
    fine = variant_figures(scene, designed.parameters, designed.controller, values, f_req, progress=False)
    uniform = variant_figures(scene, designed.parameters, designed.controller, values, f_req, progress=False,
                              points=600)
    for k in ("gain_margin_db", "phase_margin_deg", "sensitivity_peak_db", "bandwidth_hz"):
        np.testing.assert_allclose(fine[k], uniform[k], rtol=1e-9, atol=1e-9)


def test_the_worst_corner_margins_agree_with_python_control(study):
    w = study.worst
    assert w.corners == 2 ** 5  # the five tolerances that enter the loop
    assert w.values["motor.coulomb_friction"] == study.tolerances.item("motor.coulomb_friction").nominal
    assert w.reference["gain_margin_db"] == pytest.approx(w.figures["gain_margin_db"], abs=1e-2)
    assert w.reference["phase_margin_deg"] == pytest.approx(w.figures["phase_margin_deg"], abs=1e-2)
    assert w.simulation is not None and np.all(np.isfinite(w.simulation.output_angle))
    # no sampled variant is worse than the corner on the figure that decides it
    score = w.score
    r = next(q for q in study.requirements if q.name == w.figure)
    fig = study.figures[{"gain_margin": "gain_margin_db", "phase_margin": "phase_margin_deg",
                         "sensitivity_peak": "sensitivity_peak_db"}[w.figure]]
    rel = (fig - r.value) / abs(r.value) if r.sense == ">=" else (r.value - fig) / abs(r.value)
    assert score <= rel.min() + 1e-6


def test_yields_count_the_variants_and_the_rows_judge_the_lower_end(study):
    from servo_toolkit.studies.gate import yield_rows
    y = study.overall
    assert y.total == SAMPLES and y.passed == int(study.passes["all"].sum())
    assert y.passed <= min(x.passed for x in study.yields[:-1])
    rows = {r.id: r for r in yield_rows(study)}
    assert set(rows) == {"yield", "yield_stable", "yield_gain_margin", "yield_phase_margin", "yield_sensitivity_peak"}
    # 256 variants cannot show 99 % at 95 % confidence (368 would): the gate says so, whatever the count
    assert y.low < 0.99 and rows["yield"].status == "fail" and not study.passed
    d = study.to_dict()
    json.dumps(d)
    assert d["yields"][-1]["name"] == "all" and d["worst_corner"]["corners_evaluated"] == 32
    stiffness = d["worst_corner"]["values"]["drivetrain[3].stiffness"]  # SI in the JSON, which says so
    assert d["worst_corner"]["units"]["drivetrain[3].stiffness"] == "N*m/rad"
    assert f"drivetrain[3].stiffness = {stiffness * math.pi / 180:.4g} N*m/deg" in study.table()
    assert repr(study).startswith("<ToleranceResult: ema_tolerances: 256 variants") and "<svg" in study._repr_html_()


def test_the_command_prints_json_and_exits_on_the_yield(capsys):
    code = main(["tolerances", str(TOL), "--samples", "400", "--json"])
    d = json.loads(capsys.readouterr().out)
    assert code == (0 if d["passed"] else 1)
    assert d["variants"] == 400 and d["passed"] == (d["yields"][-1]["low"] >= 0.99)


def test_check_gates_on_the_lower_end_and_the_report_shows_the_same_rows(tmp_path, capsys):
    from servo_toolkit.report.builder import run_section
    from servo_toolkit.report.context import Context
    from servo_toolkit.report.sections_tolerances import tolerance_results, tolerances_section
    from servo_toolkit.studies.gate import yield_rows
    path = tmp_path / "scene.toml"
    path.write_text(TOL.read_text().replace("samples = 1024", "samples = 400"))
    junit = tmp_path / "check.xml"
    code = main(["check", str(path), "--linear-only", "--junit", str(junit), "--json"])
    d = json.loads(capsys.readouterr().out)["scenes"][0]
    rows = [r for r in d["rows"] if r["id"].startswith("yield")]
    overall = d["tolerances"]["yields"][-1]
    assert rows[0]["id"] == "yield" and rows[0]["status"] == ("pass" if overall["low"] >= 0.99 else "fail")
    assert code == (0 if all(r["status"] == "pass" for r in d["rows"]) else 1)
    assert 'name="yield"' in junit.read_text()
    ctx = Context(load_scene(path))
    section = run_section("tolerances", "Tolerances", tolerances_section, ctx)
    assert section.status in ("pass", "fail") and "tolerance-yields" in section.html and section.figures
    assert "Worst corner over the linear figures" in section.html and "load.inertia = 1.2 kg*m^2" in section.html
    # the housing's stiffness in the scene's [display] unit, as it is written (1696.8 N*m/deg +- 15 %)
    assert "uniform 1442..1951 N*m/deg" in section.html and "N*m/rad" not in section.html
    assert [r.to_dict() for r in yield_rows(tolerance_results(ctx))] == rows


def test_the_default_sampling_is_the_one_the_help_names():
    """A scene with only [robustness] draws its ranges at random (as its Monte Carlo does), a
    [tolerances] table without a method by Latin hypercube: the --method help says both."""
    from servo_toolkit.cli import build_parser
    assert load_scene(SCENES / "ema_robust.toml").tolerances.method == "random"
    sub = next(a for a in build_parser()._subparsers._group_actions[0].choices["tolerances"]._actions
               if "--method" in a.option_strings)
    assert "[tolerances] method, lhs" in sub.help and "random draws" in sub.help and "only [robustness]" in sub.help


def test_a_signed_key_takes_the_loaders_rule_finite_and_bounded_in_magnitude(tmp_path):
    """A hinge spring is signed (``finite, |x| <= 1e+12``): a normal about it is not cut at the
    smallest magnitude of the unit's range, and an end the loader accepts is accepted."""
    text = (SCENES / "ema_reference.toml").read_text().replace('hinge_stiffness = "0 N*m/rad"',
                                                                'hinge_stiffness = "20 N*m/rad"')
    small = tmp_path / "small.toml"
    small.write_text(text.replace('hinge_stiffness = "20 N*m/rad"', 'hinge_stiffness = "0.001 N*m/rad"'))
    load_scene(small)  # the loader's rule: a magnitude below 0.01 N*m/rad is a valid spring
    path = tmp_path / "spring.toml"
    path.write_text(text + '\n[tolerances]\nload.hinge_stiffness = { sigma = "200 %" }\n')
    t = {x.key: x for x in load_scene(path).tolerances.items}
    k = t["load.hinge_stiffness"]
    assert (k.distribution, k.mean, k.sigma) == ("normal", 20.0, pytest.approx(40.0))
    assert (k.low, k.high) == (-1e12, 1e12)
    path.write_text(text + '\n[tolerances]\nload.hinge_stiffness = "-0.001 N*m/rad:30 N*m/rad"\n')
    t = {x.key: x for x in load_scene(path).tolerances.items}
    assert (t["load.hinge_stiffness"].low, t["load.hinge_stiffness"].high) == (-0.001, 30.0)
    path.write_text(text + '\n[tolerances]\nload.hinge_stiffness = "-2e12 N*m/rad:30 N*m/rad"\n')
    with pytest.raises(SceneError, match=r"tolerances\.load\.hinge_stiffness: .*within \+-1e\+12"):
        load_scene(path)
