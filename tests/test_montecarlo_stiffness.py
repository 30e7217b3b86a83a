"""A Monte Carlo that varies the drivetrain stiffness keeps what the factor acts on.

The stiffness factor scales the drivetrain compliance, so a reduced model that leaves the
compliance out gives every factor the same figures. On a belt and ball screw whose sine run
leaves its compliance out (estimate 4.3e-4 at the nominal stiffness), a run varying the
stiffness keeps it: its figures move with the factor and agree with the full model within the
reduction's bound; a run that does not vary the stiffness keeps the reduction it had. The
chain's upper modes are kept when lumping them, a cost that grows with the inverse of the
factor, exceeds simulate's rule at the smallest factor; the first-order law is checked against
the lumping cost of a chain with every spring scaled.
"""

import json
import math
from types import SimpleNamespace

import numpy as np
import pytest

from servo_toolkit.cli import main
from servo_toolkit.drivetrain.operating_point import operating_point
from servo_toolkit.scene.loader import load_scene
from servo_toolkit.sim import controller_for
from servo_toolkit.sim.chain_choice import lumping_cost
from servo_toolkit.studies.montecarlo import montecarlo
from servo_toolkit.studies.reduce.estimates import varied_stiffness
from servo_toolkit.studies.time.reference import run_spec
from servo_toolkit.studies.time.run import sine_run_options

from .conftest import ROOT

BELT = ROOT / "tests" / "scenes" / "belt_screw.toml"
DURATION = 0.25
VARIANTS = {"load_inertia": np.array([40.0, 40.0]), "stiffness": np.array([0.02, 1.0])}


@pytest.fixture(scope="module")
def belt():
    scene = load_scene(BELT)
    controller, _ = controller_for(scene)
    return scene, controller


@pytest.fixture(scope="module")
def runs(belt):
    scene, controller = belt
    return {full: montecarlo(scene, dict(VARIANTS), controller=controller, duration=DURATION, full=full,
                             progress=False) for full in (False, True)}


def test_the_scenes_sine_run_leaves_its_compliance_out(belt):
    scene, controller = belt
    options, notes = sine_run_options(scene, controller, run_spec(scene, None)[0])
    assert not options.compliance and "drivetrain compliance (estimate" in notes[0]


def test_a_varied_stiffness_moves_the_figures_and_agrees_with_the_full_model(runs):
    reduced, full = runs[False], runs[True]
    assert not reduced.failed.any() and not full.failed.any()
    # the softest variant draws more current than the nominal one, as the full model's does
    assert reduced.peak_current[0] > 1.1 * reduced.peak_current[1]
    assert full.peak_current[0] > 1.1 * full.peak_current[1]
    # within the reduction's bound (0.02 of the 1 mm amplitude's response) at both factors
    amplitude_mm = 1.0
    np.testing.assert_allclose(reduced.error_display, full.error_display, rtol=0, atol=0.02 * amplitude_mm)
    np.testing.assert_allclose(reduced.peak_current, full.peak_current, rtol=0.02)
    assert reduced.worst_index("peak_current") == 0


def test_the_notes_name_what_the_run_kept_and_why(runs):
    notes = runs[False].notes
    kept = [n for n in notes if n.startswith("drivetrain compliance kept whatever its estimate")]
    assert len(kept) == 1 and "varies the stiffness (0.02..1 x nominal)" in kept[0]
    assert "drivetrain compliance" not in next(n for n in notes if n.startswith("reduced model"))
    assert runs[False].runner[0].options.compliance


def test_a_run_that_does_not_vary_the_stiffness_keeps_the_reduction(belt):
    scene, controller = belt
    r = montecarlo(scene, {"load_inertia": np.array([40.0])}, controller=controller, duration=0.05,
                   progress=False)
    assert not r.runner[0].options.compliance
    assert not any("kept whatever" in n for n in r.notes)


def test_the_lumping_cost_grows_with_the_inverse_of_the_stiffness_factor(belt, tmp_path):
    scene, controller = belt
    q0 = operating_point(scene)[0]
    nominal = lumping_cost(scene, controller, q0, [8.0], 0.02)
    text = BELT.read_text()
    for factor in (0.5, 0.1):
        soft = text.replace('"2e4 N*m/rad"', f'"{2e4 * factor:g} N*m/rad"').replace(
            '"1.5e8 N/m"', f'"{1.5e8 * factor:g} N/m"')
        assert soft != text
        path = tmp_path / f"soft_{factor:g}.toml"
        path.write_text(soft)
        cost = lumping_cost(load_scene(path), controller, q0, [8.0], 0.02)
        assert cost == pytest.approx(nominal / factor, rel=0.05)


@pytest.mark.parametrize("low, kept", [(0.02, False), (0.001, True)])
def test_the_chain_modes_are_kept_when_lumping_costs_too_much_at_the_smallest_factor(low, kept):
    choice = SimpleNamespace(chain="two_mass", cost=1.9e-5)
    rigid = SimpleNamespace(switch="compliance")
    keep = varied_stiffness((low, 1.0), rigid, choice, 0.01)
    assert "compliance" in keep and ("chain" in keep) is kept
    if kept:
        assert "0.019 at 0.001 x nominal" in keep["chain"]
    assert varied_stiffness((low, 1.0), None, None, 0.01) == {}  # a rigid chain: nothing to keep


def test_cli_prints_and_writes_what_it_kept(capsys):
    args = ["montecarlo", str(BELT), "--vary", "load_inertia=40:40", "--vary", "stiffness=0.02:1", "--samples",
            "2", "--duration", str(DURATION)]
    assert main([*args, "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    currents = {v["stiffness"]: v["peak_current_A"] for v in data["variants"]}
    assert set(currents) == {0.02, 1.0} and currents[0.02] > 1.1 * currents[1.0]
    assert any(n.startswith("drivetrain compliance kept") for n in data["notes"])
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "note: drivetrain compliance kept whatever its estimate" in out
    assert not math.isclose(currents[0.02], currents[1.0])


def test_the_modes_stay_lumped_when_the_full_chain_changes_form_within_the_load_range():
    """On the reference EMA lumping costs 4.3e-5 at the nominal stiffness, ~0.043 at 1e-3 x:
    the modes would be kept, but its full chain loses the load node at a load inertia of 0
    (``--full`` refuses that range). The run lumps them and says what that costs."""
    scene = load_scene(ROOT / "scenes" / "ema_reference.toml")
    r = montecarlo(scene, {"load_inertia": np.array([0.0, 1.0]), "stiffness": np.array([1e-3, 1.0])},
                   duration=0.01, progress=False)
    note, = [n for n in r.notes if n.startswith("drivetrain modes above the first lumped")]
    assert "costs ~0.043 at 0.001 x nominal" in note and "load_inertia = 0" in note
    assert r.runner[0].options.chain == "two_mass" and r.runner[0].options.compliance
