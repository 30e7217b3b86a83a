"""Nonlinear time runs of tolerance variants: every varied parameter reaches its variant's row
of parameters, and each batched variant equals ``simulate`` of the scene built with its
values."""

from __future__ import annotations

import math

import numpy as np
import pytest

from servo_toolkit.scene.loader import load_scene
from servo_toolkit.sim import layout as lo

from .conftest import SCENES

DURATION = 0.125  # one period of the 8 Hz sine, the shortest run simulate takes
TABLE = """
[tolerances]
motor.resistance = "+-20 %"
motor.voltage_limit = "25 V:60 V"
motor.coulomb_friction = "x0.5:x3"
"drivetrain[0].backlash" = "0.05 deg:0.3 deg"
sensors.output_encoder_bits = "10:16"
"""


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    from servo_toolkit.sim import controller_for
    from servo_toolkit.studies.tolerances import tolerance_runs
    path = tmp_path_factory.mktemp("tol") / "scene.toml"
    path.write_text((SCENES / "ema_reference.toml").read_text() + TABLE)
    scene = load_scene(path)
    controller, _ = controller_for(scene)
    values = {k: np.array(v) for k, v in {
        "motor.resistance": [0.5, 0.42, 0.58], "motor.voltage_limit": [60.0, 25.0, 40.0],
        "motor.coulomb_friction": [0.02, 0.06, 0.01], "drivetrain[0].backlash": np.radians([0.1, 0.3, 0.05]),
        "sensors.output_encoder_bits": [16.0, 10.0, 13.0]}.items()}
    return scene, controller, values, tolerance_runs(scene, values, controller, duration=DURATION, progress=False)


def test_every_varied_parameter_is_in_its_variant_s_row(runs):
    scene, _, values, r = runs
    rows = r.rows
    assert rows.fitted is not None and rows.error < 1e-4 and not rows.inert
    assert rows.options.backlash and any("backlash kept" in n for n in r.notes)  # the reduced model had left it out
    X = np.column_stack([values[k] for k in rows.names])
    P, _, _ = rows.rows(X)
    np.testing.assert_allclose(P[:, lo.R], values["motor.resistance"], rtol=1e-12)
    np.testing.assert_allclose(P[:, lo.VLIM], values["motor.voltage_limit"], rtol=1e-12)
    np.testing.assert_allclose(P[:, lo.TC], values["motor.coulomb_friction"], rtol=1e-12)
    np.testing.assert_allclose(P[:, lo.LSB], 2 * math.pi / 2 ** values["sensors.output_encoder_bits"], rtol=1e-12)
    assert np.all(np.diff(P[[2, 0, 1], lo.HALF_PLAY]) > 0)  # more gear backlash, more lost motion
    assert np.all(P[:, lo.KPI] == rows.P0[lo.KPI])  # the controller is the nominal one


def test_each_batched_variant_equals_simulate_of_its_scene(runs):
    from servo_toolkit.sim import simulate
    scene, controller, values, r = runs
    keys = scene.tolerances.scene_keys()
    for i in range(3):
        variant = keys.scene({k: v[i] for k, v in values.items()})
        single = simulate(variant, controller, reference=r.rows.reference, duration=DURATION, method="rk4",
                          dt=r.dt_s, options=r.rows.options, output_dt=r.dt_s)
        err = float(np.max(np.abs(single.output_angle - single.reference_angle)))
        cur = float(np.max(np.abs(single.motor_current)))
        assert r.tracking_error[i] == pytest.approx(err, rel=1e-4)
        assert r.peak_current[i] == pytest.approx(cur, rel=1e-4)
    assert not r.failed.any()
    # the 25 V supply limits the second variant: it saturates and tracks worse than the nominal one
    assert r.saturated[1] and r.tracking_error[1] > 1.05 * r.tracking_error[0]


def test_stiffness_and_inertia_tolerances_keep_the_fitted_rows(tmp_path):
    """A stage stiffness moves the two-mass mode's damping (the chain's lowest mode's, with a
    damper per compliance; 0.3 % across these variants, so held nominal it would miss the
    fit's tolerance): the rows fit it like the inertias and stiffness, verified against exact
    builds over the box the variants span (its corners included), so the batch keeps its fast
    path. (At +-30 % and +-40 % the separable fit's pair term leaves the damping slot some
    5e-4 off at the box's far corners: every variant is then built exactly.)"""
    from servo_toolkit.sim import controller_for
    from servo_toolkit.studies.tolerances import tolerance_runs
    path = tmp_path / "scene.toml"
    path.write_text((SCENES / "ema_reference.toml").read_text()
                    + '\n[tolerances]\n"drivetrain[3].stiffness" = "+-10 %"\nload.inertia = "+-10 %"\n')
    scene = load_scene(path)
    controller, _ = controller_for(scene)
    k0 = scene.tolerances.scene_keys().resolve("drivetrain[3].stiffness").value
    j0 = scene.load.inertia
    values = {"drivetrain[3].stiffness": k0 * np.array([1.0, 0.9, 1.1, 0.95]),
              "load.inertia": j0 * np.array([1.0, 1.1, 0.9, 1.05])}
    r = tolerance_runs(scene, values, controller, duration=0.02, progress=False)
    assert r.rows.fitted is not None and r.rows.error < 1e-4, r.rows.error
    betas = r.rows.rows(np.column_stack([values[k] for k in r.rows.names]))[0][:, lo.BETA]
    assert np.ptp(betas) > 0  # the damper follows the mode


def test_a_corner_that_makes_no_scene_is_left_out_of_the_checks(runs, tmp_path):
    """Keys whose rules bind each other at their ends: every variant's static friction is at
    least its Coulomb friction, but the box's corner with the highest Coulomb and the lowest
    static friction makes no scene; the rows are fitted and verified on the other corners."""
    from servo_toolkit.errors import SceneError
    from servo_toolkit.scene.loader import scene_keys
    from servo_toolkit.sim import Reference
    from servo_toolkit.sim.tolerance_rows import ToleranceRows, _box, keep_effects
    from servo_toolkit.studies.time.run import sine_run_options
    _, controller, _, _ = runs  # the reference EMA's design: the same on every variant
    text = (SCENES / "ema_reference.toml").read_text()
    path = tmp_path / "scene.toml"
    path.write_text(text.replace('coulomb_friction = "0.02 N*m"',
                                 'coulomb_friction = "0.02 N*m"\nstatic_friction = "0.03 N*m"', 1))
    scene = load_scene(path)
    assert scene.motor.breakaway_torque == pytest.approx(0.03)
    values = {"motor.coulomb_friction": np.array([0.02, 0.01, 0.028]),
              "motor.static_friction": np.array([0.03, 0.02, 0.04])}
    reference = Reference.sine(math.radians(2.0), 8.0)
    options, _ = keep_effects(sine_run_options(scene, controller, reference, False)[0], values)
    rows = ToleranceRows.create(scene, scene_keys(scene), values, controller, options, reference)
    X = np.column_stack([values[k] for k in rows.names])
    assert [0.028, 0.02] in _box(X).tolist()
    with pytest.raises(SceneError, match="static_friction"):
        rows.exact_model(np.array([0.028, 0.02]))
    assert rows.fitted is not None and rows.error <= 1e-4, rows.error
