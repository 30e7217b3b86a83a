"""Step choice along a run: auto shrinking the step, RK4 leaving its stability region, auto
handing over to the implicit solver, the paper scheme's step check and divergence message,
and the wall-time contract (compilation excluded)."""

from __future__ import annotations

import math
import tomllib

import numpy as np
import pytest

from servo_toolkit import SimulationError
from servo_toolkit.sim import ModelOptions, Reference, build_model, default_controller, run
from servo_toolkit.sim import engine, fixed_run

from .conftest import SCENES, build, variant

BASE = tomllib.loads((SCENES / "ema_reference.toml").read_text())
#: 200 deg/s from 20 deg: the output reaches the 30 deg elastic stop at t = 0.05 s
RAMP = Reference.ramp(math.radians(200.0), offset=math.radians(20.0))


@pytest.fixture(scope="module")
def stop_model():
    """A 1000x stiffer drivetrain (the end stop is 10x the drivetrain stiffness): on the stop
    the fastest mode is about 3x faster than at the start of the run (lossless chain)."""
    scene = build(BASE)
    return build_model(scene, default_controller(scene),
                       ModelOptions(controller_mode="continuous", stroke_end="stop", stiffness_scale=1000.0,
                                    efficiency=False))


def test_auto_shrinks_the_step_when_the_run_hits_a_stiffer_configuration(stop_model):
    a = run(stop_model, RAMP, 0.1, "auto", output_dt=None)
    assert "reduced to dt" in a.choice
    first = float(a.choice.split("dt = ")[1].split(" s")[0])
    assert a.dt_s < first / 2
    assert a.stability["t_s"] > 0.05                      # found on the stop, not at t = 0
    assert a.stability["max_abs_lambda"] * a.dt_s <= 1.0 + 1e-6
    b = run(stop_model, RAMP, 0.1, "reference", output_dt=a.times[1] - a.times[0])
    n = min(len(a.times), len(b.times))
    assert np.allclose(a.times[:n], b.times[:n])
    err = np.max(np.abs(a.output_angle[:n] - b.output_angle[:n])) / math.radians(10.0)
    assert err < 1e-3, err


@pytest.mark.parametrize("dt", [1.5e-4, 4e-4])
def test_fixed_rk4_step_that_leaves_the_stability_region_raises(stop_model, dt):
    """Both steps are stable at t = 0 (limit 4.5e-4 s) and unstable on the stop."""
    with pytest.raises(SimulationError, match=r"left the stability region along the run: "
                                              r"\|lambda\| = .* at t = 0\.09"):
        run(stop_model, RAMP, 0.1, "rk4", dt)


def test_auto_hands_over_to_the_implicit_solver_above_the_step_budget(monkeypatch):
    scene = build(BASE)
    model = build_model(scene, default_controller(scene), ModelOptions(controller_mode="continuous"))
    ref = Reference.sine(math.radians(2.0), 8.0)
    monkeypatch.setattr(engine, "AUTO_MAX_STEPS", 50)
    res = run(model, ref, 0.02, "auto", output_dt=1e-3)
    assert res.method.startswith("reference:") and res.requested == "auto"
    assert "implicit solver instead" in res.choice
    monkeypatch.undo()
    rk = run(model, ref, 0.02, "rk4", 2e-5, output_dt=1e-3)
    assert np.max(np.abs(rk.output_angle - res.output_angle)) < 1e-6 * math.radians(2.0)


@pytest.fixture(scope="module")
def fast_electrics():
    """1 uH armature: the current loop's pole near -R/L = -5e5 1/s."""
    scene = build(variant(BASE, motor__inductance="1 uH"))
    return build_model(scene, default_controller(scene))


def test_paper_scheme_refuses_a_step_outside_its_stability_region(fast_electrics):
    with pytest.raises(SimulationError, match=r"paper scheme step 0\.0001 s is outside the stability region"):
        run(fast_electrics, Reference.sine(math.radians(2.0), 8.0), 0.05, "paper", 1e-4)


def test_paper_scheme_divergence_is_called_divergence(fast_electrics):
    with pytest.raises(SimulationError, match=r"paper scheme diverged at t = [0-9.e-]+ s .*current_A = ") as err:
        run(fast_electrics, Reference.sine(math.radians(2.0), 8.0), 0.05, "paper", 1e-4,
            check_stability=False)
    assert "stroke end" not in str(err.value)


def test_wall_time_excludes_the_first_call(monkeypatch):
    """The first call of the compiled loop may compile (seconds); ``wall_s`` must not include
    it. The run's clock is a counter that the stand-in loop advances: 100 s on its first
    call (a compilation), 1 ms per step after it. ``wall_s`` is then exactly the timed call's
    0.1 s, on any machine however busy."""
    from types import SimpleNamespace
    calls, clock = [], [0.0]
    real = fixed_run.integrate

    def counted(*args):
        clock[0] += 100.0 if not calls else 1e-3 * args[5]  # args[5]: n_steps
        calls.append(args[5])
        return real(*args)

    monkeypatch.setattr(fixed_run, "integrate", counted)
    monkeypatch.setattr(fixed_run, "time", SimpleNamespace(perf_counter=lambda: clock[0]))
    scene = build(BASE)
    model = build_model(scene, default_controller(scene))
    res = run(model, Reference.sine(math.radians(2.0), 8.0), 0.01, "rk4", 1e-4)
    assert calls == [0, 100]
    assert res.wall_s == pytest.approx(0.1, rel=1e-9)
