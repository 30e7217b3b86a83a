"""Each batched variant's step is checked where its own run is stiff, not only where the
nominal run is: a near-self-locking ball screw (efficiency 0.3, back-driven 0.1) on a hinge
spring the nominal scene has not. The nominal run (no hinge spring, no torque at its speed
reversals) allows the sample time as the step; a variant on a stiff hinge spring reverses
under the spring's torque, where the loss's blend between driving and back-driven (and the
drivetrain at its play's edge) makes it far stiffer. Its start is as calm as the nominal
one and its snapshots as they are lie inside RK4's region, yet the single run of that
variant (its own check along its run, independent of the batched check) refuses the step:
the batched check finds it at the snapshots in contact and at a speed reversal, and the
variant fails with that reason."""

from __future__ import annotations

import math

import numpy as np
import pytest

from servo_toolkit.errors import SimulationError
from servo_toolkit.scene.loader import load_scene
from servo_toolkit.sim import Reference, build_model, controller_for, simulate
from servo_toolkit.sim.stability import IMAG_LIMIT, jacobian, rk4_amplification

from .conftest import SCENES

DURATION = 0.125  # one period of the sine (simulate's shortest run), past its reversals and the variants' lagging ones
REF = Reference.sine(math.radians(2.0), 8.0)
KEYS = ("load.hinge_stiffness", "motor.current_limit")
VALUES = {KEYS[0]: np.array([0.0, 3e4, 1e5]), KEYS[1]: np.array([60.0, 60.0, 150.0])}


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    from servo_toolkit.studies.tolerances import tolerance_runs
    text = (SCENES / "ema_reference.toml").read_text()
    assert text.count("efficiency = 0.90") == 1 and text.count('hinge_moment = "700 N*m"') == 1
    path = tmp_path_factory.mktemp("hinge") / "scene.toml"
    path.write_text(text.replace("efficiency = 0.90", "efficiency = 0.30")
                    .replace('hinge_moment = "700 N*m"', 'hinge_moment = "0 N*m"')
                    + '\n[tolerances]\n"load.hinge_stiffness" = "0 N*m/rad:1e5 N*m/rad"\n'
                    '"motor.current_limit" = "60 A:150 A"\n')
    scene = load_scene(path)
    controller = controller_for(scene)[0]
    runs = tolerance_runs(scene, VALUES, controller, reference=REF, duration=DURATION, progress=False)
    return scene, controller, runs


def _single(scene, controller, runs, v):
    """The single run of variant v at the batched step, checked along its run."""
    variant = scene.tolerances.scene_keys().scene({k: float(VALUES[k][v]) for k in KEYS})
    return variant, simulate(variant, controller, reference=REF, duration=DURATION, method="rk4", dt=runs.dt_s,
                             options=runs.rows.options)


def _inside(model, P, x, t, iref, dt):
    lam = np.linalg.eigvals(jacobian(model, P, x, t, iref)) * dt
    decaying = lam.real < -1e-9 * np.abs(lam)
    return bool(np.all(np.where(decaying, np.abs(rk4_amplification(lam)) <= 1 + 1e-12,
                                np.abs(lam) <= IMAG_LIMIT)))


def test_a_variant_stiff_only_along_its_own_run_fails_with_the_reason(study):
    scene, controller, runs = study
    assert runs.dt_s == pytest.approx(scene.sensors.sample_time)  # the nominal run's step: the sample time
    assert not runs.failed[0]
    _single(scene, controller, runs, 0)  # the nominal-like variant: its own run accepts the step
    for v in (1, 2):
        with pytest.raises(SimulationError, match="left the stability region along the run"):
            _single(scene, controller, runs, v)
        assert runs.failed[v] and "outside the RK4 stability region" in runs.reasons[v]


def test_the_variant_s_start_and_snapshots_as_they_are_pass(study):
    """What the check before the contact and reversal states saw of variant 1: its start and
    its three snapshots, every one inside the region (so it was reported fine)."""
    from dataclasses import replace

    from servo_toolkit.sim.batch import NSNAP
    from servo_toolkit.sim.batch_run import integrate_variants
    from servo_toolkit.sim.reference import fill, initial_state
    from servo_toolkit.studies.montecarlo import step_check
    scene, controller, runs = study
    variant = scene.tolerances.scene_keys().scene({k: float(VALUES[k][1]) for k in KEYS})
    # the check as it was, on the smooth friction (friction that holds, now chosen by need for
    # this self-locking screw, leaves the motor stuck at a snapshot: a state the check reads at
    # the loss blend's steepest point, where the check itself already fails it)
    model = build_model(variant, controller, replace(runs.rows.options, friction="smooth"))
    P = fill(model, REF)
    x0 = initial_state(model, P)
    sub = int(round(model.sample_time / runs.dt_s))
    _, _, snaps, _ = integrate_variants(P[None], model.T[None], np.zeros(1, np.int64), x0[None], runs.dt_s,
                                        runs.steps_per_variant, sub)
    nx = model.nx
    assert _inside(model, P, x0, 0.0, x0[4], runs.dt_s)
    for k in range(NSNAP):
        s = snaps[0, k]
        assert _inside(model, P, s[:nx], s[nx], s[nx + 1], runs.dt_s)
    worst, stable = step_check(replace(model), P[None], model.T[None], np.zeros(1, np.int64), x0[None], snaps,
                               runs.dt_s)
    assert not stable[0] and worst[0] > 2.785


def test_a_node_held_by_friction_is_judged_without_the_blend_it_never_crosses(study):
    """Friction that holds (chosen by need for this self-locking screw) leaves variant 1's
    motor at rest at a snapshot, held while the moment on it stays within its breakaway level.
    Read on the smooth dynamics that state sits at the loss blend's steepest point, outside
    RK4's region; held, its speed stays 0, and the rest of the chain (the Jacobian without the
    motor speed's row and column) lies inside. The variant still fails, where its motor slides
    through the blend (its snapshot in contact)."""
    from servo_toolkit.sim.batch_run import integrate_variants
    from servo_toolkit.sim.reference import fill, initial_state
    from servo_toolkit.studies.montecarlo.variant_step import checked_states, held_nodes, step_check
    scene, controller, runs = study
    assert runs.rows.options.friction == "stick"
    variant = scene.tolerances.scene_keys().scene({k: float(VALUES[k][1]) for k in KEYS})
    model = build_model(variant, controller, runs.rows.options)
    P = fill(model, REF)
    x0 = initial_state(model, P)
    one = np.zeros(1, np.int64)
    sub = int(round(model.sample_time / runs.dt_s))
    _, _, snaps, _ = integrate_variants(P[None], model.T[None], one, x0[None], runs.dt_s, runs.steps_per_variant, sub)
    X, times, irefs, owner = checked_states(model, P[None], x0[None], snaps)
    held = held_nodes(model, P[None], model.T[None], one, X, times, irefs, owner)
    as_is = slice(2, 2 + snaps.shape[1])
    rows = [m for m in range(X.shape[0])[as_is] if held[m, 0]]
    assert rows, "a snapshot with the motor held"
    assert not held[[m for m in range(X.shape[0]) if X[m, 1] != 0.0], 0].any()  # sliding: never held
    m = rows[0]
    J = jacobian(model, P, X[m], times[m], irefs[m])
    assert not _inside(model, P, X[m], times[m], irefs[m], runs.dt_s)  # the smooth reading: outside
    keep = [j for j in range(model.nx) if j != 1]
    lam = np.linalg.eigvals(J[np.ix_(keep, keep)]) * runs.dt_s
    decaying = lam.real < -1e-9 * np.abs(lam)
    assert np.all(np.where(decaying, np.abs(rk4_amplification(lam)) <= 1 + 1e-12, np.abs(lam) <= IMAG_LIMIT))
    worst, stable = step_check(model, P[None], model.T[None], one, x0[None], snaps, runs.dt_s)
    J_held = J.copy()
    J_held[1, :] = 0.0
    assert np.abs(np.linalg.eigvals(J_held)).max() < np.abs(np.linalg.eigvals(J)).max()
    assert not stable[0] and worst[0] > 2.785  # it still fails, where it slides
