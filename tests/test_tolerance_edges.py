"""Tolerances at their edges: a single live input to the Sobol indices, degenerate and
implicitly truncated distributions, yields that no sample can show, the text's units and
intervals, and the reproducibility of the draws."""

from __future__ import annotations

import numpy as np
import pytest


def test_sobol_indices_of_a_single_input_keep_one_column_per_figure():
    from scipy.stats import uniform

    from servo_toolkit.core.sensitivity import sobol

    def f(x):  # three figures of one input: each is all of its own variance
        return np.vstack([x[0] ** 2, np.sin(3 * x[0]), x[0]])
    res = sobol(f, [uniform(0, 1)], 64, seed=0, resamples=20)
    for k in ("first", "total", "total_low", "total_high"):
        assert np.shape(res[k]) == (3, 1), k
    # one input carries all of the variance: S_1 = S_T = 1 (Saltelli's estimators, exact here)
    np.testing.assert_allclose(res["total"][:, 0], 1.0, atol=0.05)


# --- the verdict: the interval's lower end, and why it falls short -------------------------

@pytest.mark.parametrize("passed, total, met, why", [
    (100, 100, False, "at least 368 variants, all passing"),  # the sample is too small to show 99 %
    (368, 368, True, ""),
    (993, 1000, False, "the point estimate 99.3 % reaches 99 % but the interval's lower end"),
    (950, 1000, False, "50 of 1000 variants fail"),
])
def test_a_yield_short_of_its_requirement_says_why(passed, total, met, why):
    from servo_toolkit.core.yields import Yield
    y = Yield.of("all", "every requirement", passed, total, 0.95, 0.99)
    assert y.met is met and why in y.shortfall() and (y.shortfall() == "") is met
    assert y.to_dict()["shortfall"] == y.shortfall()


def test_clopper_pearson_ends_at_zero_and_all_successes_are_the_one_sided_closed_forms():
    from servo_toolkit.core.yields import clopper_pearson
    n, a = 50, 0.05
    assert clopper_pearson(n, n, 1 - a) == pytest.approx(((a / 2) ** (1 / n), 1.0))
    assert clopper_pearson(0, n, 1 - a) == pytest.approx((0.0, 1 - (a / 2) ** (1 / n)))


def test_the_check_row_of_a_sample_too_small_to_show_the_yield_says_how_many_are_needed():
    from types import SimpleNamespace

    from servo_toolkit.core.yields import Yield
    from servo_toolkit.studies.gate import yield_rows
    every = Yield.of("all", "every requirement", 100, 100, 0.95, 0.99)
    study = SimpleNamespace(tolerances=SimpleNamespace(min_yield=0.99), overall=every, yields=(every,),
                            settings={"method": "lhs"})
    row = yield_rows(study)[0]
    assert row.status == "fail" and "at least 368 variants, all passing" in row.detail


@pytest.mark.parametrize("table, line", [("tolerances", 'min_yield = 1.0\nmotor.resistance = "+-5 %"'),
                                         ("robustness", 'load_inertia = ["0.5 kg*m^2", "2 kg*m^2"]\nmin_yield = 1')])
def test_a_required_yield_of_one_is_refused_as_unprovable(table, line, tmp_path, capsys):
    from servo_toolkit.cli import main

    from .conftest import SCENES
    path = tmp_path / "one.toml"
    path.write_text((SCENES / "ema_reference.toml").read_text() + f"\n[{table}]\n{line}\n")
    assert main(["tolerances", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{table}.min_yield" in err[0] and "cannot be shown" in err[0], err


# --- the text: every share with its interval, the keys that do not enter, corner units -----

@pytest.fixture(scope="module")
def small_result():
    """A result put together from its parts (no study run): two tolerances that enter the
    figure, one known not to."""
    from servo_toolkit.core.sensitivity import rank
    from servo_toolkit.core.yields import Yield
    from servo_toolkit.scene.tolerances import Tolerance, Tolerances
    from servo_toolkit.studies.tolerances import ToleranceResult, WorstCorner
    items = (Tolerance("motor.resistance", "ohm", 0.5, "uniform", 0.5, 0.7),
             Tolerance("load.inertia", "kg*m^2", 1.0, "uniform", 0.8, 1.2),
             Tolerance("motor.voltage_limit", "V", 270.0, "uniform", 243.0, 297.0),
             Tolerance("drivetrain[1].efficiency", "dimensionless", 0.9, "uniform", 0.85, 0.92))
    rng = np.random.default_rng(0)
    X = np.column_stack([t.ppf(rng.random(200)) for t in items])
    y = 50 - 20 * X[:, 1] - 2 * X[:, 0] + 0.01 * rng.standard_normal(200)
    s = rank("phase_margin", "phase margin", "deg", [t.key for t in items], X, y,
             inert=[False, False, True, False])
    every = Yield.of("all", "every requirement", 200, 200, 0.95, 0.99)
    worst = WorstCorner({"motor.resistance": 0.7, "load.inertia": 1.2, "motor.voltage_limit": 270.0,
                         "drivetrain[1].efficiency": 0.85}, 0.3, "phase_margin", 8, {})
    return ToleranceResult("demo", Tolerances(items, samples=200), {t.key: X[:, j] for j, t in enumerate(items)},
                           {}, None, (), {}, (every,), (s,), worst, {"method": "lhs"})


def test_the_text_shows_every_share_with_its_interval_and_the_keys_that_do_not_enter(small_result):
    text = small_result.table()
    s = small_result.sensitivities[0]
    assert "standardized regression" in text and "95 % intervals" in text
    i = s.keys.index("load.inertia")
    assert f"({100 * s.low[i]:.3g}..{100 * s.high[i]:.3g} %)" in text
    assert "does not enter it (0 exactly): motor.voltage_limit" in text
    assert "motor.voltage_limit      " not in text  # not ranked among the shares


def test_the_worst_corner_is_shown_with_units(small_result):
    text = small_result.table()
    assert "motor.resistance = 0.7 ohm" in text and "load.inertia = 1.2 kg*m^2" in text
    assert "motor.voltage_limit = 270 V" in text
    assert "drivetrain[1].efficiency = 0.85" in text and "0.85 dimensionless" not in text
    assert "motor.resistance = 0.7 ohm" in small_result._repr_html_()


# --- the table: distributions the physics cannot hold ---------------------------------------

@pytest.mark.parametrize("line, rule", [
    ('motor.resistance = { sigma = "200 %" }', "30.9 % of the variants below"),  # P(z < -0.499)
    ('"drivetrain[0].backlash" = { sigma = "0.1 deg" }', "15.9 % of the variants below"),  # P(z < -1)
    ('"drivetrain[1].efficiency" = { sigma = "10 %" }', "13.3 % of the variants above"),  # P(z > 1.11)
])
def test_a_normal_the_physical_range_would_cut_silently_is_refused_naming_the_key(line, rule, tmp_path, capsys):
    from servo_toolkit.cli import main

    from .conftest import SCENES
    path = tmp_path / "wide.toml"
    path.write_text((SCENES / "ema_reference.toml").read_text() + f"\n[tolerances]\n{line}\n")
    assert main(["tolerances", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    key = line.split(" = ")[0].strip('"')
    assert len(err) == 1 and f"tolerances.{key}" in err[0] and rule in err[0] and "give m" in err[0], err


def test_a_normal_cut_where_the_scene_says_is_drawn_from_its_truncation(tmp_path):
    from scipy.stats import truncnorm

    from servo_toolkit.scene.loader import load_scene

    from .conftest import SCENES
    path = tmp_path / "cut.toml"
    path.write_text((SCENES / "ema_reference.toml").read_text()
                    + '\n[tolerances]\n"drivetrain[0].backlash" = { sigma = "0.1 deg", min = "0 deg" }\n')
    t = load_scene(path).tolerances.items[0]
    mu = sigma = np.radians(0.1)
    assert (t.low, t.mean, t.sigma) == pytest.approx((0.0, mu, sigma))
    u = np.array([0.1, 0.5, 0.9])
    np.testing.assert_allclose(t.ppf(u), truncnorm.ppf(u, -1.0, np.inf, loc=mu, scale=sigma), rtol=1e-12)


@pytest.mark.parametrize("line, side", [
    ('motor.coulomb_friction = { sigma = "0.01 N*m", min = "x1" }', +1),  # a friction that only grows
    ('"drivetrain[0].backlash" = { sigma = "0.02 deg", mean = "0.1 deg", max = "0.1 deg" }', -1),
])
def test_a_normal_whose_mean_is_its_truncation_is_a_half_normal_drawn_with_its_closed_form_moments(
        line, side, tmp_path):
    """A half-normal of scale sigma about mu has mean mu +- sigma sqrt(2/pi) and standard
    deviation sigma sqrt(1 - 2/pi): independent draws match both within 4 standard errors."""
    import math

    from servo_toolkit.loop.sampling import sample_tolerances
    from servo_toolkit.scene.loader import load_scene

    from .conftest import SCENES
    path = tmp_path / "half.toml"
    path.write_text((SCENES / "ema_reference.toml").read_text() + f"\n[tolerances]\n{line}\n")
    tol = load_scene(path).tolerances
    t = tol.items[0]
    assert t.half == ("above" if side > 0 else "below") and t.describe().startswith(f"half-normal {t.half}")
    n = 4096
    x = sample_tolerances(tol, n, "random", 3)[t.key]
    mean, sd = t.mean + side * t.sigma * math.sqrt(2 / math.pi), t.sigma * math.sqrt(1 - 2 / math.pi)
    kurtosis = 3.0 + 8 * (math.pi - 3) / (math.pi - 2) ** 2  # of the half-normal: 3.869
    assert abs(x.mean() - mean) < 4 * sd / math.sqrt(n)
    assert abs(x.std(ddof=1) - sd) < 4 * sd * math.sqrt((kurtosis - 1) / (4 * n))
    assert np.all(side * (x - t.mean) >= 0)  # every draw on the mean's one side
    assert t.ends == pytest.approx(tuple(sorted((t.mean, t.mean + 3 * side * t.sigma))))


def test_a_mean_outside_its_truncation_is_still_refused(tmp_path, capsys):
    from servo_toolkit.cli import main

    from .conftest import SCENES
    path = tmp_path / "half.toml"
    path.write_text((SCENES / "ema_reference.toml").read_text()
                    + '\n[tolerances]\nmotor.coulomb_friction = { sigma = "0.01 N*m", min = "x1.1" }\n')
    assert main(["tolerances", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "tolerances.motor.coulomb_friction:" in err[0] and "must lie inside" in err[0], err


# --- the ranking of a sample too small for a regression -------------------------------------

def test_too_few_variants_for_a_regression_say_so_instead_of_a_figure_that_does_not_vary():
    from scipy.stats import uniform

    from servo_toolkit.core.sensitivity import rank, sobol

    def f(x):
        return 3 * x[0] + x[1] ** 2
    X = np.random.default_rng(1).random((4, 3))
    s = rank("f", "f", "", ("a", "b", "c"), X, f(X.T))  # 4 variants, 3 keys: no residual left
    assert s.method == "none" and "4 variants cannot fit a regression on 3 tolerances" in s.reason
    assert "does not vary" not in s.reason
    s2 = rank("f", "f", "", ("a", "b", "c"), X[:2], f(X[:2].T))
    assert s2.method == "none" and "does not vary" not in s2.reason
    # with evaluations of its own, the variance-based indices rank it and say why (no R^2)
    s3 = rank("f", "f", "", ("a", "b", "c"), X, f(X.T),
              sobol_run=lambda live: sobol(lambda x: f(x)[None], [uniform(0, 1)] * int(live.sum()), 256, seed=1,
                                           resamples=20))
    assert s3.method == "sobol" and s3.reason.startswith("4 variants cannot fit") and np.isnan(s3.r2)
    assert s3.top == "a" and s3.high[2] < 1e-9  # c enters nothing


# --- a Sobol sample that is not a power of 2 ------------------------------------------------

def test_a_sobol_sample_not_a_power_of_two_is_noted():
    from servo_toolkit.studies.tolerances import sampling_notes
    (note,) = sampling_notes("sobol", 24)
    assert note.startswith("a Sobol sample of 24 variants, not a power of 2") and "32 variants would" in note
    assert sampling_notes("sobol", 32) == [] and sampling_notes("lhs", 24) == []


def test_the_notes_are_printed_with_the_text(small_result):
    from dataclasses import replace
    shown = replace(small_result, notes=("a Sobol sample of 24 variants, not a power of 2",))
    assert "  note: a Sobol sample of 24 variants, not a power of 2" in shown.table()


# --- montecarlo on a scene with [tolerances] ------------------------------------------------

def test_montecarlo_names_the_tolerances_it_does_not_vary():
    from servo_toolkit.scene.loader import load_scene
    from servo_toolkit.studies.montecarlo.run import unvaried_tolerances

    from .conftest import SCENES
    scene = load_scene(SCENES / "examples" / "ema_tolerances.toml")
    note, other = unvaried_tolerances(scene, {"load_inertia": np.zeros(2), "stiffness": np.ones(2)})
    for key in scene.tolerances.keys:
        assert (key in note) is (key not in ("load.inertia", "drivetrain.stiffness_scale")), key
    assert "tolerances --nonlinear" in note
    # its load.inertia of 0.8..1.2 kg*m^2 is varied, over the Monte Carlo's load_inertia range instead
    assert "load.inertia is varied over this run's range (load_inertia 0..0 kg*m^2)" in other, other
    assert "not over its tolerance (load_inertia 0.8..1.2 kg*m^2)" in other, other
    robust = load_scene(SCENES / "ema_robust.toml")  # [robustness] only: its ranges are the ones varied
    assert unvaried_tolerances(robust, {"load_inertia": np.zeros(2), "stiffness": np.ones(2)}) == []


@pytest.mark.parametrize("line, rule", [
    ('"drivetrain[0].teeth" = "+-5 %"', "not a numeric key that can vary: a list of whole numbers"),
    ('"drivetrain[0].teeth[1]" = "38:42"', "not a numeric key that can vary: a list of whole numbers"),
    ('motor.resistence = "+-5 %"', "did you mean motor.resistance?"),
    # the design's sample time is no tolerance: the margins and the time runs would ignore it
    ('sensors.sample_time = "+-1 %"', "the controller's sample time is the design's, not a tolerance"),
])
def test_a_key_that_cannot_vary_or_is_misspelt_is_told_apart(line, rule, tmp_path, capsys):
    from servo_toolkit.cli import main

    from .conftest import SCENES
    path = tmp_path / "keys.toml"
    path.write_text((SCENES / "ema_reference.toml").read_text() + f"\n[tolerances]\n{line}\n")
    assert main(["tolerances", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    key = line.split(" = ")[0].strip('"')
    assert len(err) == 1 and f"tolerances.{key}:" in err[0] and rule in err[0], err
    if "did you mean" in rule:  # the keys it lists are the ones that can vary: not the refused ones
        listed = err[0].split("motor has ")[1]
        assert "motor.inductance" in listed and "sensors.sample_time" not in listed, err
        assert "load.inertia" not in listed and len(err[0]) < 700, err  # the table's keys only


def test_a_share_interval_stops_at_all_of_the_variance():
    from servo_toolkit.core.sensitivity import rank
    rng = np.random.default_rng(3)
    X = rng.random((8, 1))
    y = X[:, 0] + 0.05 * rng.standard_normal(8)  # few variants: a wide interval about SRC ~ 1
    s = rank("f", "f", "", ("a",), X, y)
    assert s.method == "src" and s.high[0] <= max(1.0, s.share[0]) and s.low[0] <= s.share[0] <= s.high[0]


def test_the_worst_corner_shows_its_time_run_with_units_or_why_it_did_not_run():
    from types import SimpleNamespace

    from servo_toolkit.core.output_units import OutputUnit
    from servo_toolkit.studies.tolerances import WorstCorner
    t = np.linspace(0.0, 1.0, 11)
    sim = SimpleNamespace(output_angle=np.radians(0.5) * np.ones_like(t), reference_angle=np.zeros_like(t),
                          motor_current=-12.5 * np.ones_like(t), unit=OutputUnit("rad"))
    w = WorstCorner({"load.inertia": 1.2}, 0.3, "phase_margin", 2, {}, simulation=sim)
    assert w.run_text().endswith("tracking error 0.5 deg, peak current 12.5 A")
    assert w.to_dict()["simulation"]["max_tracking_error"] == pytest.approx(np.radians(0.5))
    travel = WorstCorner({"load.inertia": 1.2}, 0.3, "phase_margin", 2, {}, simulation=SimpleNamespace(
        output_angle=2e-4 * np.ones_like(t), reference_angle=np.zeros_like(t), motor_current=np.ones_like(t),
        unit=OutputUnit("m")))
    assert "tracking error 0.2 mm" in travel.run_text()
    failed = WorstCorner({"load.inertia": 1.2}, 0.3, "phase_margin", 2, {}, run_error="the step did not converge")
    assert failed.run_text() == "its time run could not be carried out: the step did not converge"
    assert failed.to_dict()["run_error"] == "the step did not converge"


# --- variants whose time run stops: the design's failure or the model's ---------------------

def _runs(reasons):
    from servo_toolkit.studies.tolerances import ToleranceRuns
    n = len(reasons)
    return ToleranceRuns(np.full(n, 0.01), np.full(n, 20.0), np.zeros(n, bool), np.array([bool(r) for r in reasons]),
                         tuple(reasons), 1e-4, 0.3, 3000, 0.1)


def test_a_variant_that_hits_its_stroke_end_or_diverges_unstable_fails_its_time_requirements():
    from servo_toolkit.loop.requirements import Requirement
    from servo_toolkit.studies.tolerances.run import _judge_failed, _meets
    runs = _runs(["", "stroke end reached at t = 0.24 s", "non-finite state at t = 0.1 s", ""])
    stable = np.array([True, True, False, True])
    judged, physical = _judge_failed(runs, {"load.inertia": np.ones(4)}, stable)
    assert physical.tolist() == [False, True, True, False]
    assert np.isnan(judged.tracking_error[1:3]).all() and judged.tracking_error[0] == 0.01
    req = Requirement("tracking_error", "<=", 1.0, "deg", "tolerances")
    assert _meets(req, np.degrees(judged.tracking_error)).tolist() == [True, False, False, True]


@pytest.mark.parametrize("reason", ["non-finite state at t = 0.1 s",  # a stable loop blowing up: the model's
                                    "step 0.0001 s outside the RK4 stability region at this variant's parameters",
                                    "no start: the initial state has no equilibrium"])
def test_a_variant_the_model_could_not_run_leaves_no_verdict(reason):
    from servo_toolkit.errors import SimulationError
    from servo_toolkit.studies.tolerances.run import _judge_failed
    with pytest.raises(SimulationError, match="could not run 1 of 2 variants"):
        _judge_failed(_runs(["", reason]), {"load.inertia": np.ones(2)}, np.array([True, True]))


def test_an_unstable_worst_corner_says_so_with_its_pole(small_result):
    from dataclasses import replace

    from servo_toolkit.studies.tolerances import WorstCorner
    worst = WorstCorner({"load.inertia": 1.2}, -np.inf, "stable", 2, {"max_pole_real": 13.05})
    text = replace(small_result, worst=worst).table()
    assert "closed loop unstable (a pole at real part 13.05 1/s) at load.inertia = 1.2 kg*m^2" in text
    assert "-inf %" not in text


@pytest.mark.parametrize("line, rule", [
    ('load.hinge_stiffness = "+-20 %"', "20 % of the scene's value 0 is no spread: give the half width with a unit"),
    ('load.hinge_stiffness = { sigma = "5 %" }', "a sigma of 5 % of a mean of 0 is no spread"),
])
def test_a_percentage_of_a_zero_value_asks_for_a_unit(line, rule, tmp_path, capsys):
    from servo_toolkit.cli import main

    from .conftest import SCENES
    path = tmp_path / "zero.toml"
    path.write_text((SCENES / "ema_reference.toml").read_text() + f"\n[tolerances]\n{line}\n")
    assert main(["tolerances", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "tolerances.load.hinge_stiffness:" in err[0] and rule in err[0], err


def test_the_gate_at_a_two_sided_90_percent_is_the_success_run_demonstration_at_95():
    from servo_toolkit.core.yields import Yield, minimum_samples
    # success-run theorem: n = ln(1 - C) / ln(R) = ln(0.05) / ln(0.99) = 298.07 -> 299 (R99/C95)
    assert minimum_samples(0.99, 0.90) == 299
    assert Yield.of("all", "", 299, 299, 0.90, 0.99).met and not Yield.of("all", "", 298, 298, 0.90, 0.99).met


def test_the_sobol_time_runs_serve_both_time_figures_once(monkeypatch):
    from types import SimpleNamespace

    from servo_toolkit.scene.tolerances import Tolerance, Tolerances
    from servo_toolkit.studies.tolerances import time_runs as module
    from servo_toolkit.studies.tolerances.run import _time_sobol
    items = (Tolerance("a", "ohm", 1.0, "uniform", 0.5, 1.5), Tolerance("b", "ohm", 1.0, "uniform", 0.5, 1.5))
    tol = Tolerances(items)
    calls = []

    def fake_runs(scene, vals, controller, **kw):  # tracking error = a, peak current = b (SI)
        calls.append(len(vals["a"]))
        return SimpleNamespace(tracking_error=np.asarray(vals["a"], float), peak_current=np.asarray(vals["b"], float),
                               failed=np.zeros(len(vals["a"]), bool))
    monkeypatch.setattr(module, "tolerance_runs", fake_runs)
    runs = SimpleNamespace(rows=SimpleNamespace(controller=None, keys=None), duration_s=0.1, dt_s=1e-4)
    cache, live = {}, np.array([True, True])
    err = _time_sobol(tol, None, runs, "tracking_error", 64, cache, 0)(live)
    cur = _time_sobol(tol, None, runs, "peak_current", 64, cache, 0)(live)
    assert sum(calls) == 64 * (2 + 2)  # one set of n (d + 2) runs for the two figures
    np.testing.assert_allclose(err["total"][0], [1.0, 0.0], atol=0.05)  # the error is a alone
    np.testing.assert_allclose(cur["total"][0], [0.0, 1.0], atol=0.05)  # the current is b alone


@pytest.mark.parametrize("line", ['motor.resistance = { sigma = "1e-300 ohm" }', 'motor.resistance = "+-1e-12 %"'])
def test_a_spread_below_the_precision_of_the_study_is_refused(line, tmp_path, capsys):
    from servo_toolkit.cli import main

    from .conftest import SCENES
    path = tmp_path / "tiny.toml"
    path.write_text((SCENES / "ema_reference.toml").read_text() + f"\n[tolerances]\n{line}\n")
    assert main(["tolerances", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    # a variant that differs by rounding would be listed as a key that does not enter the loop
    assert len(err) == 1 and "tolerances.motor.resistance:" in err[0] and "below 1e-09 of the value 0.5" in err[0]


# --- time runs in worker processes: the chunks unpickle with the standard pickle ------------

class _PicklingExecutor:
    """Runs each call here after a round trip through pickle, as a process pool sends it."""

    def submit(self, fn, *args, **kwargs):
        import pickle
        from concurrent.futures import Future
        fn, args, kwargs = pickle.loads(pickle.dumps((fn, args, kwargs)))
        future = Future()
        future.set_result(fn(*args, **kwargs))
        return future


def test_the_time_runs_chunks_travel_to_worker_processes(tmp_path):
    from servo_toolkit.loop.sampling import sample_tolerances
    from servo_toolkit.scene.loader import load_scene
    from servo_toolkit.sim import controller_for
    from servo_toolkit.studies.tolerances import tolerance_runs

    from .conftest import SCENES
    path = tmp_path / "runs.toml"
    path.write_text((SCENES / "ema_reference.toml").read_text() + '\n[tolerances]\nload.inertia = "+-20 %"\n')
    scene = load_scene(path)
    values = sample_tolerances(scene.tolerances, 4, "lhs", 0)
    ctrl, _ = controller_for(scene)  # python-control's systems and the scene do not pickle: they stay here
    sent = tolerance_runs(scene, values, ctrl, duration=0.02, progress=False, executor=_PicklingExecutor())
    assert sent.rows.fitted is not None and not sent.failed.any()
    assert np.all(np.isfinite(sent.tracking_error)) and np.ptp(sent.peak_current) > 0  # the variants differ


def test_a_study_whose_tolerances_enter_no_judged_figure_says_its_yield_is_the_nominal_verdict(tmp_path):
    from servo_toolkit.scene.loader import load_scene
    from servo_toolkit.studies.tolerances import tolerance_study

    from .conftest import SCENES
    path = tmp_path / "friction.toml"
    path.write_text((SCENES / "ema_reference.toml").read_text()
                    + '\n[tolerances]\nmotor.coulomb_friction = "x0.5:x3"\n')
    study = tolerance_study(load_scene(path), samples=8, worst_corner=False, progress=False)
    assert all(s.method == "none" for s in study.sensitivities)  # the margins are the nominal's in every variant
    assert any(n.startswith("no tolerance enters a judged figure") for n in study.notes)


@pytest.fixture(scope="module")
def reference_design():
    """The reference EMA's design (its [tolerances] do not enter it): the controller every
    variant of the studies below runs."""
    from servo_toolkit.loop import design
    from servo_toolkit.scene.loader import load_scene

    from .conftest import SCENES
    return design(load_scene(SCENES / "ema_reference.toml"), progress=False)


class _CountingExecutor(_PicklingExecutor):
    """A pickling executor that counts the chunks of time runs it was given."""

    def __init__(self):
        self.calls = 0

    def submit(self, fn, *args, **kwargs):
        self.calls += args[0].__module__.endswith("tolerances.time_runs")  # run_cases sends (function, chunk)
        return super().submit(fn, *args, **kwargs)


def test_the_sobol_time_runs_go_to_the_executor_and_give_the_same_json(tmp_path, reference_design):
    """Two variants of one tolerance cannot fit a regression: the time figures are ranked by
    Sobol indices from 4 (1 + 2) further runs, which go to the executor in chunks as the
    study's own time runs do; the JSON is byte-identical with and without it."""
    import json

    from servo_toolkit.scene.loader import load_scene
    from servo_toolkit.studies.tolerances import tolerance_study

    from .conftest import SCENES
    path = tmp_path / "sobol.toml"
    path.write_text((SCENES / "ema_reference.toml").read_text()
                    + '\n[tolerances]\nmax_tracking_error = "5 deg"\nmotor.coulomb_friction = "x0.5:x3"\n')
    scene = load_scene(path)
    kw = dict(samples=2, worst_corner=False, progress=False, sobol_runs=4, duration=0.02)
    here = tolerance_study(scene, reference_design, **kw)
    pool = _CountingExecutor()
    sent = tolerance_study(scene, reference_design, executor=pool, **kw)
    assert here.sensitivity("tracking_error").method == "sobol"
    assert pool.calls == 1 + 3  # the variants' chunk, then the Sobol sample's A, B and AB_i runs
    assert json.dumps(sent.to_dict(), sort_keys=True) == json.dumps(here.to_dict(), sort_keys=True)


def test_with_time_requirements_the_worst_corner_is_the_worst_over_them_too(tmp_path, reference_design):
    """Friction acts in time only: its tolerance does not move the margins, yet it drives the
    tracking error. With a bound on the tracking error every corner runs in time and the worst
    is the one that misses its limit by the most, its shortfall divided by the limit; the
    corner's own single simulation (an independent path from the batched runs) gives that
    figure, and no sampled variant tracks worse than the box's worst corner."""
    from servo_toolkit.scene.loader import load_scene
    from servo_toolkit.studies.tolerances import tolerance_study

    from .conftest import SCENES
    path = tmp_path / "corner.toml"
    path.write_text((SCENES / "ema_reference.toml").read_text()
                    + '\n[tolerances]\nmax_tracking_error = "1 deg"\nmotor.resistance = "+-10 %"\n'
                      'motor.coulomb_friction = "x0.5:x5"\n')
    study = tolerance_study(load_scene(path), reference_design, samples=8, progress=False, duration=0.05)
    w = study.worst
    assert all(study.yield_of(r).fraction == 1 for r in ("gain_margin", "phase_margin", "sensitivity_peak"))
    assert w.figure == "tracking_error" and w.basis.startswith("every requirement") and w.corners == 4
    assert w.values["motor.coulomb_friction"] == pytest.approx(0.1)  # the friction at its high end, not nominal
    err = np.degrees(w.run_figures()["max_tracking_error"])
    assert w.time_figures["tracking_error"] == pytest.approx(err, rel=1e-4)
    assert w.score == pytest.approx(1.0 - err / 1.0, rel=1e-4) and w.score < 0
    assert err >= np.degrees(np.max(study.runs.tracking_error))
    assert "worst corner over every requirement (margins and time runs) (4 corners evaluated): tracking_error margin" \
        in study.table()
    assert study.to_dict()["worst_corner"]["time_figures"]["tracking_error"] == pytest.approx(err, rel=1e-4)


def test_a_stiffness_and_an_inertia_are_shown_in_the_scenes_display_units_and_the_json_names_si(small_result):
    import json
    import math
    from dataclasses import replace

    from servo_toolkit.display.units import DisplayUnits
    from servo_toolkit.scene.tolerances import Tolerance, Tolerances
    from servo_toolkit.studies.tolerances import WorstCorner
    k0 = 1696.8 * 180 / math.pi  # the housing's 1696.8 N*m/deg in SI
    items = (Tolerance("drivetrain[3].stiffness", "N*m/rad", k0, "uniform", 0.85 * k0, 1.15 * k0),
             Tolerance("load.inertia", "kg*m^2", 1.0, "uniform", 0.8, 1.2),
             Tolerance("motor.rotor_inertia", "kg*m^2", 2e-4, "uniform", 1.8e-4, 2.2e-4))
    worst = WorstCorner({"drivetrain[3].stiffness": 0.85 * k0, "load.inertia": 1.2, "motor.rotor_inertia": 2.2e-4},
                        0.3, "phase_margin", 8, {}, units={t.key: t.unit for t in items})
    shown = replace(small_result, tolerances=Tolerances(items, samples=200), worst=worst,
                    display=DisplayUnits(stiffness="N*m/deg", inertia="kg*cm^2"))
    text = shown.table()
    assert "drivetrain[3].stiffness = 1442 N*m/deg" in text  # 0.85 x 1696.8
    assert "load.inertia = 12e3 kg*cm^2" in text
    assert "motor.rotor_inertia = 220e-6 kg*m^2" in text  # the motor's own inertia stays SI
    assert "N*m/rad" not in text and "1442 N*m/deg" in shown._repr_html_()
    assert shown.describe(items[0]) == "uniform 1442..1951 N*m/deg"
    d = json.loads(json.dumps(shown.to_dict()))
    assert d["worst_corner"]["values"]["drivetrain[3].stiffness"] == pytest.approx(0.85 * k0)  # SI, saying so
    assert d["worst_corner"]["units"]["drivetrain[3].stiffness"] == "N*m/rad"
    assert d["tolerances"][0]["unit"] == "N*m/rad"
    # a preference of the other output coordinate's quantity leaves a stage's own unit alone
    travel = replace(shown, display=DisplayUnits(stiffness="N/um"), linear=True)
    assert "drivetrain[3].stiffness = 82.64e3 N*m/rad" in travel.table()


def test_a_distribution_written_as_a_table_reads_back_as_the_scene_gives_it():
    """The JSON's ``written`` is TOML: pasted back into a scene it is the same table."""
    import tomllib

    from servo_toolkit import load_scene
    from servo_toolkit.scene.key_paths import table_of

    from .conftest import SCENES
    path = SCENES / "examples" / "ema_tolerances.toml"
    raw = tomllib.loads(path.read_text())["tolerances"]
    tables = 0
    for t in load_scene(path).tolerances.items:
        given = table_of(raw, t.key.rpartition(".")[0]) or {}
        given = given.get(t.key.rpartition(".")[2], raw.get(t.key))
        if isinstance(given, dict):
            tables += 1
            assert tomllib.loads(f"x = {t.written}")["x"] == given, t.written
    assert tables >= 1


@pytest.mark.parametrize("line, hint, listed", [
    ('"load.mass" = "+-5 %"', "did you mean load.inertia?", "load has load.coulomb_friction"),
    ('"motor.kt" = "+-5 %"', "did you mean motor.torque_constant?", "motor has motor.ambient_temperature"),
    ('"gearbox.ratio" = "+-5 %"', "", "the tables with numeric keys are drivetrain[0]"),
])
def test_an_unknown_key_is_told_its_usual_name_and_its_table_s_keys(line, hint, listed, tmp_path, capsys):
    """A travel's carriage mass is the load's inertia, a catalogue's Kt the torque constant: the
    line says so and lists the keys of the table named (the tables, for a table the scene does
    not have), not every key of the scene (a line of 1400 characters)."""
    from servo_toolkit.cli import main

    from .conftest import SCENES
    path = tmp_path / "keys.toml"
    path.write_text((SCENES / "ema_reference.toml").read_text() + f"\n[tolerances]\n{line}\n")
    assert main(["tolerances", str(path)]) == 2
    (err,) = capsys.readouterr().err.strip().splitlines()
    assert hint in err and listed in err and len(err) < 800, err
    assert "not a numeric key of this scene that can take a tolerance" in err
