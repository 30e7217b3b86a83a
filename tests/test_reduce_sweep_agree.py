"""What a reduction says it leaves out is what the study's runs leave out: a frequency sweep
chooses its model by the same plan as ``reduce`` (its full model holds friction), keeps friction
that holds where the plan judges it needed, and ``reduce`` measures the full model (friction
that holds included) against the model the sweep runs."""

from __future__ import annotations

import tomllib

import pytest

from servo_toolkit.sim import ModelOptions
from servo_toolkit.studies.reduce import reduce, reduced_options
from servo_toolkit.studies.reduce.estimates import FRICTION_EFFECT
from servo_toolkit.studies.sine_dwell import DwellPlan
from servo_toolkit.studies.sweep.compute import sweep

from .carriage_scene import LOOP_REQUIREMENTS, carriage_scene
from .conftest import build, variant

#: the carriage with lash, whose Coulomb friction (30 N, 40 N static) dwarfs the force its own
#: motion needs at 0.5 mm
CARRIAGE = carriage_scene(lash=True, load_friction=True,
                          requirements=LOOP_REQUIREMENTS + 'max_sensitivity_peak = "6 dB"\n')

SHORT = DwellPlan(settling_cycles=3, estimation_cycles=2, min_settling_time=0.2)


def _names(left_out) -> list:
    return [item.split(": ", 1)[0] for item in left_out]


def test_a_dominant_load_friction_holds_in_the_sweep_the_plan_keeps_it_in():
    """At 0.5 mm, 1 and 3 Hz the load's 40 N breakaway against the ~2 N its motion needs puts
    the friction's estimate far over the budget: the plan keeps it, the sweep runs friction
    that holds (not the smooth model that leaves the 30 N out), its first line's left-out
    list is the plan's, and ``reduce`` runs the same options as its reduced model (nothing
    left out: one model, no difference to claim)."""
    sc = build(tomllib.loads(CARRIAGE))
    freqs, amps = [1.0, 3.0], [0.5e-3]
    options, plan = reduced_options(sc, None, frequencies=freqs, amplitudes=amps)
    fric = next(e for e in plan.effects if e.effect == FRICTION_EFFECT)
    assert not fric.omitted and fric.estimate > 10 and options.friction == "stick"
    res = sweep(sc, frequencies=freqs, amplitudes=amps, plan=SHORT, progress=False)
    assert res.options["friction"] == "stick"
    assert _names(res.left_out) == [e.effect for e in plan.omitted]
    assert FRICTION_EFFECT not in _names(res.left_out)
    assert not any("load's friction left out" in n for n in res.notes)
    assert any(n.startswith("friction that holds (stick) kept") and "load holds" in n for n in res.notes)
    red = reduce(sc, frequencies=freqs, amplitudes=amps, plan=SHORT, per_effect=False, progress=False)
    assert red.reduced_options == res.options
    assert red.full_options["friction"] == "stick"
    if not plan.omitted:
        assert red.same_model and "nothing to compare" in red.table()


def test_friction_left_out_is_named_by_the_sweep_and_measured_against_friction_that_holds():
    """With 1 N of Coulomb friction (1.5 N static) at 6 Hz, 4 mm (within the limits) the
    friction is small against the force the carriage's motion needs, its estimate is within
    the budget and the plan leaves it out: the
    sweep then runs the smooth model and names friction among what it left out, ``reduce``
    compares the full model (friction that holds) with exactly that model, and the measured
    differences, all together and friction's on its own, are not zero."""
    sc = build(variant(tomllib.loads(CARRIAGE), load__coulomb_friction="1 N", load__static_friction="1.5 N"))
    freqs, amps = [6.0], [4e-3]
    _, plan = reduced_options(sc, None, frequencies=freqs, amplitudes=amps)
    assert FRICTION_EFFECT in [e.effect for e in plan.omitted]
    res = sweep(sc, frequencies=freqs, amplitudes=amps, plan=SHORT, progress=False)
    assert res.options["friction"] == "smooth"
    assert _names(res.left_out) == [e.effect for e in plan.omitted]
    assert FRICTION_EFFECT in res.table().splitlines()[1]
    red = reduce(sc, frequencies=freqs, amplitudes=amps, plan=SHORT, per_effect=[FRICTION_EFFECT], progress=False)
    assert red.full_options["friction"] == "stick" and red.reduced_options == res.options
    assert not red.same_model and red.measured > 1e-6
    (alone,) = red.per_effect
    assert alone.effect == FRICTION_EFFECT and alone.measured > 1e-6


def test_options_given_without_stick_say_so_on_the_sweep_s_first_line():
    """A sweep run on options given that leave the friction out (the smooth model) names it on
    its model line, with the estimate over the budget and what that means for the figures;
    the full model says it holds friction."""
    sc = build(tomllib.loads(CARRIAGE))
    res = sweep(sc, frequencies=[1.0], amplitudes=[0.5e-3], plan=SHORT, progress=False,
                options=ModelOptions(friction="smooth"))
    line = res.table().splitlines()[1]
    assert line.startswith("model: options as given, left out: friction that holds (stick)")
    assert "load left out (estimate" in line and "over the budget 0.01" in line and "do not hold" in line
    full = sweep(sc, frequencies=[1.0], amplitudes=[0.5e-3], plan=SHORT, progress=False, full=True)
    assert full.options["friction"] == "stick"
    assert full.table().splitlines()[1] == "model: full model (friction that holds)"


if __name__ == "__main__":  # pragma: no cover
    pytest.main([__file__])
