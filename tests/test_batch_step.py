"""The batched time runs' RK4 step is checked along the nominal run as a single run's is: on
a near-self-locking ball screw (efficiency 0.3, back-driven 0.1) the single run's own check
accepts the step the Monte Carlo and the tolerance runs chose, and the notes say so."""

from __future__ import annotations

import math

import numpy as np
import pytest

from servo_toolkit.errors import SceneError
from servo_toolkit.scene.loader import load_scene
from servo_toolkit.sim import Reference, controller_for, run
from servo_toolkit.sim.stability import REAL_LIMIT

from .conftest import SCENES

DURATION = 0.05
REF = Reference.sine(math.radians(2.0), 8.0)


@pytest.fixture(scope="module")
def lossy_scene(tmp_path_factory):
    text = (SCENES / "ema_reference.toml").read_text()
    assert text.count("efficiency = 0.90") == 1  # the ball screw's
    path = tmp_path_factory.mktemp("lossy") / "scene.toml"
    path.write_text(text.replace("efficiency = 0.90", "efficiency = 0.30")
                    + '\n[tolerances]\n"drivetrain[1].efficiency" = "0.28:0.32"\n')
    return load_scene(path)


@pytest.fixture(scope="module")
def controller(lossy_scene):
    return controller_for(lossy_scene)[0]


@pytest.fixture(scope="module")
def mc(lossy_scene, controller):
    from servo_toolkit.studies.montecarlo import montecarlo
    return montecarlo(lossy_scene, {"load_inertia": (0.5, 2.0)}, samples=2, duration=DURATION,
                      reference=REF, controller=controller, progress=False)


def test_montecarlo_step_passes_the_single_runs_check_along_the_run(mc):
    builder, _, reference, _ = mc.runner
    # the single run's own check (engine.run, a fixed RK4 step): raises if the step leaves the
    # stability region anywhere along the nominal run
    single = run(builder.model, reference, DURATION, "rk4", mc.dt_s)
    assert single.stability["dt_limit_s"] >= mc.dt_s
    assert any("checked along the nominal run" in n for n in mc.notes)
    assert np.all(mc.abs_lambda_dt[~mc.failed] <= REAL_LIMIT)


def test_a_given_step_outside_the_region_along_the_run_is_refused(mc, lossy_scene, controller):
    from servo_toolkit.studies.montecarlo import montecarlo
    builder, _, reference, _ = mc.runner
    limit = run(builder.model, reference, DURATION, "rk4", mc.dt_s).stability["dt_limit_s"]
    with pytest.raises(SceneError, match="stability region along the nominal run"):
        montecarlo(lossy_scene, {"load_inertia": (0.5, 2.0)}, samples=2, duration=DURATION, reference=REF,
                   controller=controller, dt=1.5 * limit, progress=False)


def test_tolerance_runs_step_passes_the_single_runs_check(lossy_scene, controller):
    from servo_toolkit.studies.tolerances import tolerance_runs
    values = {"drivetrain[1].efficiency": np.array([0.28, 0.32])}
    r = tolerance_runs(lossy_scene, values, controller, reference=REF, duration=DURATION, progress=False)
    run(r.rows.model, REF, DURATION, "rk4", r.dt_s)  # raises if outside the region along the run
    assert any("checked along the nominal run" in n for n in r.notes)


def test_the_batched_step_is_the_single_run_s_automatic_step(mc):
    """One step choice for both: the Monte Carlo's step and the single run's ``auto`` step of
    the nominal model, its choice in the same words."""
    import json

    from servo_toolkit.sim.engine import choose_step
    from servo_toolkit.sim.reference import initial_state
    builder, P0, reference, _ = mc.runner
    step = choose_step(builder.model, P0, initial_state(builder.model, P0), DURATION)
    single = run(builder.model, reference, DURATION, "auto")
    assert step.dt == mc.dt_s == single.dt_s and step.choice == single.choice and not step.refused
    assert step.along["dt_limit_s"] >= step.dt and "\n" not in repr(step)
    json.dumps(step.to_dict())
