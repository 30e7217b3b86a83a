"""Nonlinear Monte Carlo: the batched variants equal single runs of the same models (built by
``build_model`` from the varied scene), one failing variant leaves the others untouched, the
executor path equals the serial one, and the command line's JSON and exit codes."""

import json
import math
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

from servo_toolkit.cli import main
from servo_toolkit.scene.loader import load_scene
from servo_toolkit.sim import ModelOptions, Reference, build_model, controller_for, run, simulate
from servo_toolkit.sim import layout as lo
from servo_toolkit.sim.batch import F_CUR, F_ERR, F_STATUS
from servo_toolkit.sim.batch_run import integrate_variants
from servo_toolkit.sim.reference import fill, initial_state
from servo_toolkit.sim.variants import VariantBuilder, with_load_inertia
from servo_toolkit.studies.montecarlo import montecarlo
from servo_toolkit.studies.time.run import sine_run_options

from .conftest import SCENES

EMA = str(SCENES / "ema_reference.toml")
DURATION = 0.25
REF = Reference.sine(math.radians(2.0), 8.0)


@pytest.fixture(scope="module")
def ema():
    scene = load_scene(EMA)
    controller, _ = controller_for(scene)
    options, _ = sine_run_options(scene, controller, REF)
    return scene, controller, options


def _single(scene, controller, options, dt):
    """One ``simulate`` run recording every step: (max |q - r|, max |i|, final state)."""
    res = simulate(scene, controller, reference=REF, duration=DURATION, method="rk4", dt=dt, options=options,
                   output_dt=dt)
    return (float(np.max(np.abs(res.output_angle - res.reference_angle))),
            float(np.max(np.abs(res.motor_current))), res.states[-1])


def _mc(scene, controller, variants, **kw):
    return montecarlo(scene, variants, controller=controller, duration=DURATION, progress=False, **kw)


def test_degenerate_ranges_equal_the_single_simulate_run(ema):
    scene, controller, options = ema
    r = _mc(scene, controller, {"load_inertia": (1.0, 1.0), "stiffness": (1.0, 1.0)}, samples=3)
    err, cur, final = _single(scene, controller, options, r.dt_s)
    assert r.steps_per_variant == round(DURATION / r.dt_s) and not r.failed.any()
    np.testing.assert_allclose(r.tracking_error, err, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(r.peak_current, cur, rtol=1e-9)
    # the single loop on the batched variant's own rows ends in the same state
    np.testing.assert_allclose(r.trace(1).states[-1], final, rtol=1e-9, atol=1e-12)
    assert err > 1e-4  # the comparison is not between two zeros
    # the study's choice of the two-mass reduction is noted once, with its figures
    lumped = [n for n in r.notes if "lumped into the two-mass reduction" in n]
    assert len(lumped) == 1 and "RK4 step" in lumped[0] and "the sample time" in lumped[0]
    assert len(set(r.notes)) == len(r.notes)
    text = repr(r)
    assert text.startswith("<MonteCarloResult: ema_reference: 3 variants") and "\n" not in text
    card = r._repr_html_()  # a card as every result's: the figures, the plot, the notes
    assert 'class="st-card"' in card and "<table>" in card and "<svg" in card and "worst tracking error" in r.table()
    import matplotlib
    matplotlib.use("Agg")
    assert len(r.plot()) == 2


def test_a_heavier_load_equals_simulate_of_the_scene_with_that_inertia(ema):
    scene, controller, options = ema
    r = _mc(scene, controller, {"load_inertia": np.array([1.0, 3.0]), "stiffness": np.array([1.0, 1.3])})
    nominal = _single(scene, controller, options, r.dt_s)
    # the stiffness factor scales the series stiffness of the model that runs (the reduced
    # model's own scale carries the compliance it left out)
    heavy = _single(with_load_inertia(scene, 3.0), controller,
                    ModelOptions(**{**options.__dict__, "stiffness_scale": 1.3 * options.stiffness_scale}), r.dt_s)
    np.testing.assert_allclose([r.tracking_error[1], r.peak_current[1]], heavy[:2], rtol=1e-9)
    np.testing.assert_allclose(r.trace(1).states[-1], heavy[2], rtol=1e-9, atol=1e-12)
    # three times the load inertia: the same controller lags more and needs more current
    assert heavy[0] > 1.05 * nominal[0] and heavy[1] > 1.05 * nominal[1]
    np.testing.assert_allclose([r.tracking_error[0], r.peak_current[0]], nominal[:2], rtol=1e-9)


def test_rigid_chain_variants_carry_their_own_tables(ema):
    """A rigid chain's inertia table holds the load: each variant gets its own table, equal
    to build_model's, and the batched run equals the single run of that model."""
    scene, controller, options = ema
    rigid = ModelOptions(**{**options.__dict__, "compliance": False})
    b = VariantBuilder.create(scene, controller, rigid)
    assert b.fast and b.model.rigid and b.d_table is not None
    values = {"load_inertia": np.array([0.5, 3.0]), "stiffness": np.array([1.0, 1.0])}
    assert b.self_check(values)
    P0 = fill(b.model, REF)
    P, T, tix = b.rows(P0, values, None)
    assert len(T) == 3 and list(tix) == [1, 2]
    exact = build_model(with_load_inertia(scene, 3.0), controller, rigid)
    np.testing.assert_allclose(T[2], exact.T, rtol=1e-12)
    # the fallback path (build_model per variant) gives the same rows
    from dataclasses import replace
    P_slow, T_slow, tix_slow = replace(b, fast=False).rows(P0, values, lambda m: fill(m, REF))
    np.testing.assert_allclose(P_slow, P, rtol=1e-12)
    np.testing.assert_allclose(T_slow[tix_slow], T[tix], rtol=1e-12)
    X0 = np.array([initial_state(b.model, p) for p in P])
    dt = controller.sample_time
    n = round(DURATION / dt)
    _, figs, _, _ = integrate_variants(P, T, tix, X0, dt, n, 1)
    single = run(exact, REF, DURATION, "rk4", dt, output_dt=dt)
    assert figs[1, F_ERR] == pytest.approx(np.max(np.abs(single.output_angle - single.reference_angle)), rel=1e-9)
    assert figs[1, F_CUR] == pytest.approx(np.max(np.abs(single.motor_current)), rel=1e-9)
    assert figs[0, F_CUR] < figs[1, F_CUR]


def test_a_failing_variant_leaves_the_others_untouched(ema):
    scene, controller, _ = ema
    good = _mc(scene, controller, {"stiffness": np.array([0.8, 1.2])})
    mixed = _mc(scene, controller, {"stiffness": np.array([0.8, 1e6, 1.2])})
    assert list(mixed.failed) == [False, True, False]
    assert "stability region" in mixed.reasons[1] and mixed.reasons[0] == ""
    np.testing.assert_array_equal(mixed.tracking_error[[0, 2]], good.tracking_error)
    np.testing.assert_array_equal(mixed.peak_current[[0, 2]], good.peak_current)
    assert mixed.worst()["tracking_error"]["index"] in (0, 2)
    # a non-finite parameter: that variant stops with its status, the other runs on unchanged
    P0 = fill(build_model(scene, controller, ModelOptions()), REF)
    P = np.array([P0, P0])
    P[0, lo.KT] = np.nan
    X0 = np.array([initial_state(build_model(scene, controller, ModelOptions()), P0)] * 2)
    _, figs, _, _ = integrate_variants(P, np.array([build_model(scene, controller, ModelOptions()).T]),
                                       np.zeros(2, dtype=np.int64), X0, 1e-4, 500, 1)
    _, alone, _, _ = integrate_variants(P[1:], np.array([build_model(scene, controller, ModelOptions()).T]),
                                        np.zeros(1, dtype=np.int64), X0[1:], 1e-4, 500, 1)
    assert figs[0, F_STATUS] == lo.NONFINITE and figs[1, F_STATUS] == lo.OK
    np.testing.assert_array_equal(figs[1], alone[0])


def test_chunks_on_an_executor_equal_the_serial_run(ema):
    scene, controller, _ = ema
    serial = _mc(scene, controller, {"load_inertia": (0.0, 4.0)}, samples=5, seed=3)
    with ThreadPoolExecutor(2) as pool:
        pooled = _mc(scene, controller, {"load_inertia": (0.0, 4.0)}, samples=5, seed=3, executor=pool,
                     chunk_size=2)
    np.testing.assert_array_equal(pooled.tracking_error, serial.tracking_error)
    np.testing.assert_array_equal(pooled.values["load_inertia"], serial.values["load_inertia"])


def test_cli_json_shape(capsys):
    assert main(["montecarlo", EMA, "--vary", "load_inertia=0:2", "--samples", "3", "--duration", "0.1",
                 "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["samples"] == 3 and d["steps_per_variant"] == 1000 and d["wall_s"] > 0
    assert len(d["variants"]) == 3
    v = d["variants"][0]
    # as check --vary: a scene without [robustness] varies what the command line names
    assert set(v) == {"load_inertia", "max_abs_tracking_error_deg", "peak_current_A", "saturated", "failed"}
    assert 0.0 <= v["load_inertia"] <= 2.0 and not v["failed"]
    worst = d["worst"]["tracking_error"]
    assert worst["max_abs_tracking_error_deg"] == max(x["max_abs_tracking_error_deg"] for x in d["variants"])


@pytest.mark.parametrize("args, key", [(["--vary", "mass=0:1"], "--vary mass=0:1"),
                                       (["--vary", "load_inertia=2:1"], "--vary load_inertia=2:1"),
                                       (["--samples", "0"], "--samples"), (["--duration", "-1"], "--duration"),
                                       (["--workers", "0"], "--workers")])
def test_cli_bad_input_exits_2_with_one_line(args, key, capsys):
    assert main(["montecarlo", EMA, *args]) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"servo-toolkit: error: {key}:") and captured.out == ""


def test_check_rows_hold_the_worst_variant_to_the_scene_limits(ema):
    from servo_toolkit.scene.loader import Robustness
    from servo_toolkit.studies.montecarlo import check_cases, montecarlo_checks
    scene, controller, _ = ema
    spec = Robustness(load_inertia=(0.5, 1.5), stiffness=None, samples=4, max_tracking_error=math.radians(10.0),
                      tracking_error_dimension="angle", max_peak_current=1.0)
    checks, result = montecarlo_checks(scene, spec, controller)
    by = {c.name: c for c in checks}
    assert by["tracking_error"].passed and by["tracking_error"].unit == "deg"
    assert by["tracking_error"].achieved == pytest.approx(result.error_display.max(), rel=1e-12)
    assert not by["peak_current"].passed and by["peak_current"].achieved == pytest.approx(result.peak_current.max())
    names = [c[0] for c in check_cases(checks, result)]
    assert names == ["robust_tracking_error", "robust_peak_current"]
    assert montecarlo_checks(scene, Robustness(), controller) == ([], None)  # nothing asked, nothing run


def test_check_command_adds_the_rows_and_fails_on_them(tmp_path, capsys):
    text = (SCENES / "ema_robust.toml").read_text().replace(
        "samples = 1000", 'samples = 6\nmax_tracking_error = "0.001 deg"\nmax_peak_current = "500 A"')
    path = tmp_path / "ema_mc.toml"
    path.write_text(text)
    assert main(["check", str(path), "--json"]) == 1
    d = json.loads(capsys.readouterr().out)["scenes"][0]
    rows = d["montecarlo"]["requirements"]
    assert not rows["tracking_error"]["passed"] and rows["peak_current"]["passed"]
    assert d["montecarlo"]["samples"] == 6
    bad = text.replace('max_tracking_error = "0.001 deg"', 'max_tracking_error = "0.1 mm"')
    path.write_text(bad)
    assert main(["check", str(path)]) == 2
    assert "robustness.max_tracking_error" in capsys.readouterr().err


def test_defaults_are_the_simulate_command(ema):
    """Without a command, a duration or a model choice, montecarlo runs what `servo-toolkit
    simulate SCENE` runs: the same sine, the same reduced model, the same step."""
    from servo_toolkit.studies.time.run import simulate_study
    scene, _, _ = ema
    study = simulate_study(scene)
    r = montecarlo(scene, {"load_inertia": (1.0, 1.0)}, samples=1, progress=False)
    assert r.dt_s == study.dt_s and r.steps_per_variant == study.steps and r.duration_s == study.t_final
    np.testing.assert_allclose(r.trace(0).states[-1], study.states[-1], rtol=1e-9, atol=1e-12)
    # the peaks of both are kept at every step, not at the records (every third step)
    d = study.to_dict()
    np.testing.assert_allclose(r.tracking_error[0], math.radians(d["max_abs_tracking_error_deg"]), rtol=1e-9)
    np.testing.assert_allclose(r.peak_current[0], d["max_abs_current_A"], rtol=1e-9)
    recorded = np.max(np.abs(study.output_angle - study.reference_angle))
    assert recorded <= r.tracking_error[0]


def test_a_nominal_variant_prints_what_simulate_prints(capsys):
    """``montecarlo`` at exactly the nominal values and ``simulate`` print the same peak
    tracking error and peak current, full model and reduced, to 1e-9."""
    for full in ([], ["--full"]):
        assert main(["simulate", EMA, *full, "--json"]) == 0
        single = json.loads(capsys.readouterr().out)
        assert main(["montecarlo", EMA, "--vary", "load_inertia=1:1", "--vary", "stiffness=1:1", "--samples", "1",
                     *full, "--json"]) == 0
        variant = json.loads(capsys.readouterr().out)["variants"][0]
        assert variant["max_abs_tracking_error_deg"] == pytest.approx(single["max_abs_tracking_error_deg"], rel=1e-9)
        assert variant["peak_current_A"] == pytest.approx(single["max_abs_current_A"], rel=1e-9)
        assert single["max_abs_tracking_error_deg"] > 0.1


def test_the_time_requirements_of_both_tables_read_the_tracking_error_in_the_outputs_dimension():
    """``[robustness]`` and ``[tolerances]`` bound the same time figures with one reader: the
    tracking error in deg for an output angle (mm for a travel), the peak current in A, and a
    bound given in the other dimension is one line naming that table's key."""
    from types import SimpleNamespace

    from servo_toolkit.errors import SceneError
    from servo_toolkit.loop.requirements import time_requirements
    rotary = load_scene()
    linear = load_scene(SCENES / "linear_roller_screw_actuator.toml")
    assert not rotary.drivetrain.output_is_linear and linear.drivetrain.output_is_linear
    for table in ("robustness", "tolerances"):
        spec = SimpleNamespace(max_tracking_error=math.radians(0.5), tracking_error_dimension="angle",
                               max_peak_current=12.0)
        rows = time_requirements(rotary, spec, table)
        assert [(r.name, r.sense, r.unit, r.source) for r in rows] == [
            ("tracking_error", "<=", "deg", table), ("peak_current", "<=", "A", table)]
        assert rows[0].value == pytest.approx(0.5, rel=1e-12) and rows[1].value == 12.0
        with pytest.raises(SceneError, match=rf"^{table}\.max_tracking_error: .*give a length, got an angle"):
            time_requirements(linear, spec, table)
        travel = SimpleNamespace(max_tracking_error=2e-4, tracking_error_dimension="length", max_peak_current=None)
        (row,) = time_requirements(linear, travel, table)
        assert (row.value, row.unit) == (pytest.approx(0.2, rel=1e-12), "mm")
        with pytest.raises(SceneError, match=rf"^{table}\.max_tracking_error: .*give an angle, got a length"):
            time_requirements(rotary, travel, table)


def _light_load(tmp_path, tolerances: str = ""):
    """The reference EMA with a 0.2 kg*m^2 load (and ``tolerances`` as its [tolerances])."""
    text = (SCENES / "ema_reference.toml").read_text().replace('inertia = "1.0 kg*m^2"', 'inertia = "0.2 kg*m^2"')
    path = tmp_path / "light.toml"
    path.write_text(text + (f"\n[tolerances]\n{tolerances}\n" if tolerances else ""))
    return path


def test_the_default_load_range_is_relative_to_the_scenes_load(tmp_path):
    """Without [robustness] the load varies from 0 to four times the scene's own: 0..4
    kg*m^2 on the reference EMA's 1 kg*m^2 (its defaults unchanged), 0..0.8 kg*m^2 on a
    0.2 kg*m^2 load, not the reference's absolute 0..4; design --robust takes the same."""
    from servo_toolkit.loop.design import robust_spec
    from servo_toolkit.loop.robustness import default_variations
    assert default_variations(load_scene(EMA)) == {"load_inertia": (0.0, 4.0), "stiffness": (0.7, 1.3)}
    light = load_scene(_light_load(tmp_path))
    assert default_variations(light) == {"load_inertia": (0.0, pytest.approx(0.8)), "stiffness": (0.7, 1.3)}
    assert robust_spec(light, True).ranges == default_variations(light)
    r = montecarlo(light, samples=4, duration=0.02, progress=False)
    assert (r.values["load_inertia"].min(), r.values["load_inertia"].max()) == (0.0, pytest.approx(0.8))


def test_the_note_on_tolerances_names_only_keys_the_run_leaves_alone(tmp_path):
    """load.inertia is the Monte Carlo's load_inertia: it is never listed among the keys not
    varied; varied over the run's own range, the note gives both ranges."""
    from servo_toolkit.loop.robustness import default_variations, sample_variants
    from servo_toolkit.studies.montecarlo.run import unvaried_tolerances
    scene = load_scene(_light_load(tmp_path, 'motor.resistance = "+-10 %"\nload.inertia = [0.15, 0.3]'))
    notes = unvaried_tolerances(scene, sample_variants(default_variations(scene), 8, False, 0))
    left = [n for n in notes if "are not varied here" in n]
    assert len(left) == 1 and "motor.resistance" in left[0] and "load.inertia" not in left[0], notes
    other = [n for n in notes if "load.inertia is varied over this run's range" in n]
    assert len(other) == 1 and "0..0.8 kg*m^2" in other[0] and "0.15..0.3 kg*m^2" in other[0], notes
    same = unvaried_tolerances(scene, sample_variants({"load_inertia": (0.15, 0.3)}, 8, False, 0))
    assert len(same) == 1 and "load.inertia" not in same[0] and "motor.resistance" in same[0], same
