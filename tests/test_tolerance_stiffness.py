"""The tolerance study's time runs keep in their reduced model what a toleranced stiffness acts on.

On a belt and ball screw whose sine run leaves its compliance out and lumps the chain's upper
mode (1553 Hz, lumping cost 1.9e-5 at the nominal stiffness), a tolerance on the stiffness
(``drivetrain.stiffness_scale``, or a stage's own stiffness key) keeps the compliance, and
keeps the upper mode when lumping it costs more than simulate's rule allows at the softest
variant: the soft variants' figures then equal the full model's, where the lumped chain's
missed them (by 2.6 % of the tracking error at 0.001 x nominal; by half at a belt 0.03 x as
stiff with the scale at 0.02, where the series factor alone would judge the lumping cheap).
"""

import numpy as np
import pytest

from servo_toolkit.drivetrain.operating_point import operating_point
from servo_toolkit.scene.loader import load_scene
from servo_toolkit.sim import controller_for
from servo_toolkit.studies.time.run import MODES_KEPT
from servo_toolkit.studies.tolerances.time_runs import key_spans, stiffness_factors, tolerance_runs

from .conftest import ROOT

BELT = ROOT / "tests" / "scenes" / "belt_screw.toml"
DURATION = 0.25
SCALE = "drivetrain.stiffness_scale"
BELT_K = "drivetrain[0].torsional_stiffness"
SCREW_K = "drivetrain[1].axial_stiffness"


def _scene(tmp_path, base, table):
    path = tmp_path / f"{base.stem}_tol.toml"
    path.write_text(base.read_text() + "\n[tolerances]\nsamples = 4\n" +
                    "".join(f'"{k}" = "{v}"\n' for k, v in table.items()))
    return load_scene(path)


@pytest.fixture(scope="module")
def belt(tmp_path_factory):
    scene = _scene(tmp_path_factory.mktemp("belt"), BELT, {SCALE: "0.02:1", BELT_K: "x0.03:x1", SCREW_K: "+-15 %"})
    return scene, controller_for(scene)[0]


def _both(scene, controller, values):
    return [tolerance_runs(scene, values, controller, duration=DURATION, full=full, progress=False)
            for full in (False, True)]


def test_a_soft_scale_keeps_the_upper_modes_and_agrees_with_the_full_model(belt):
    scene, controller = belt
    reduced, full = _both(scene, controller, {SCALE: np.array([0.001, 0.003, 1.0])})
    assert not reduced.failed.any() and not full.failed.any()
    assert reduced.rows.options.compliance and reduced.rows.options.chain == "full"
    kept, = [n for n in reduced.notes if n.startswith(MODES_KEPT)]
    assert "0.001..1 x nominal" in kept and "costs ~0.019 at 0.001 x nominal" in kept
    assert any(n.startswith("drivetrain compliance kept whatever its estimate") for n in reduced.notes)
    # the lumped chain's soft variants missed the full model's tracking error by 2.6 and 3.6 %
    np.testing.assert_allclose(reduced.tracking_error, full.tracking_error, rtol=0.005)
    assert reduced.tracking_error[0] > 10 * reduced.tracking_error[2]
    assert reduced.stiffness == (0.001, 1.0)


def test_a_stage_key_keeps_the_modes_its_chain_needs(belt):
    """A belt 0.03 x as stiff moves the series stiffness by only 0.62, but lumping that chain's
    upper mode costs 2.4e-4 (8 x what the series factor gives); over a scale of 0.02 it
    exceeds 0.01: the modes are kept, and the softest variant runs as on the full model."""
    scene, controller = belt
    values = {BELT_K: np.array([600.0, 600.0, 2e4, 2e4]), SCALE: np.array([0.02, 1.0, 0.02, 1.0])}
    reduced, full = _both(scene, controller, values)
    kept, = [n for n in reduced.notes if n.startswith(MODES_KEPT)]
    assert f"varies {BELT_K}" in kept and "measured on that chain, over the lowest stiffness_scale 0.02" in kept
    assert not any("lumped into the two-mass reduction" in n for n in reduced.notes)
    # the lumped chain gave 3.84 mm where the full model gives 7.85 mm
    np.testing.assert_allclose(reduced.tracking_error, full.tracking_error, rtol=0.005)
    np.testing.assert_allclose(reduced.peak_current, full.peak_current, rtol=0.005)


def test_a_stage_keys_factor_is_its_series_stiffness_over_the_nominal(belt):
    scene, _ = belt
    keys = scene.tolerances.scene_keys()
    q0 = operating_point(scene)[0]
    c_belt, c_screw = 1.0 / scene.drivetrain.stiffness([q0]).stage_stiffness[:, 0]
    # springs in series: 1/k = c_belt + c_screw / f for the screw f x as stiff
    for f in (0.3, 1.2):
        expected = (c_belt + c_screw) / (c_belt + c_screw / f)
        low, high = stiffness_factors(scene, keys, {SCREW_K: np.array([1.5e8 * f, 1.5e8])})
        assert low == pytest.approx(min(expected, 1.0), rel=1e-9) and high == pytest.approx(max(expected, 1.0))
    assert stiffness_factors(scene, keys, {SCALE: np.array([0.5, 2.0]), SCREW_K: np.array([1.5e8, 1.5e8])}) == \
        pytest.approx((0.5, 2.0))
    assert stiffness_factors(scene, keys, {"motor.resistance": np.array([0.3, 0.5])}) is None


def test_the_spans_reach_the_tolerance_ends_the_corners_take(belt):
    scene, _ = belt
    spans = key_spans(scene, {SCREW_K: np.array([1.5e8, 1.6e8]), "motor.resistance": np.array([0.3, 0.5])})
    assert spans[SCREW_K] == pytest.approx((0.85 * 1.5e8, 1.15 * 1.5e8))
    assert spans["motor.resistance"] == (0.3, 0.5)


def test_a_narrow_stiffness_tolerance_keeps_the_nominal_lumping(belt):
    scene, controller = belt
    r = tolerance_runs(scene, {SCREW_K: np.array([0.85, 1.15]) * 1.5e8}, controller, duration=0.02, progress=False)
    assert r.rows.options.compliance and r.rows.options.chain == "two_mass"
    assert not any(n.startswith(MODES_KEPT) for n in r.notes)


def test_the_modes_stay_lumped_when_a_key_changes_the_chains_form(tmp_path):
    """The reference EMA's full chain loses its load node at a load inertia of 0: the modes a
    0.001 x stiffness would keep are lumped again, and the note says what that costs."""
    scene = _scene(tmp_path, ROOT / "scenes" / "ema_reference.toml",
                   {"load.inertia": "0 kg*m^2:1 kg*m^2", SCALE: "0.001:1"})
    r = tolerance_runs(scene, {"load.inertia": np.array([0.0, 1.0]), SCALE: np.array([1.0, 1.0])},
                       controller_for(scene)[0], duration=0.01, progress=False)
    note, = [n for n in r.notes if n.startswith("drivetrain modes above the first lumped")]
    assert "costs ~0.043 at 0.001 x nominal" in note and "load.inertia = 0" in note
    assert r.rows.options.chain == "two_mass" and r.rows.options.compliance
