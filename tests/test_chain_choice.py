"""Which model of the drivetrain chain a run takes, and what the lumped modes do to the loop.

One rule keeps or lumps the chain's modes above the first for ``simulate`` and for the time
runs of the studies (:func:`servo_toolkit.sim.chain_choice.choose_chain`): the cost of lumping
them at the frequencies the run works at (the scene's own time-run studies included), against
the RK4 step the reduction gains. The loop designed on the two-mass plant is checked on the
n-mass plant, and the design notes say when a lumped mode lies near the loop.
"""

import math
from dataclasses import replace

import pytest

from servo_toolkit import design, load_scene
from servo_toolkit.drivetrain.operating_point import operating_point
from servo_toolkit.sim import ModelOptions, Reference, build_model, controller_for
from servo_toolkit.sim import layout as lo
from servo_toolkit.sim.chain_choice import LUMP_TOLERANCE, choose_chain, working_frequencies
from servo_toolkit.studies.time.run import sine_run_options

from .conftest import SCENES, build, variant
from .test_sim_full_chain import three_mass


@pytest.fixture(scope="module")
def ema():
    sc = load_scene(SCENES / "ema_reference.toml")
    return sc, controller_for(sc)[0]


def test_simulate_lumps_the_reference_ema_s_upper_modes_and_says_what_for(ema):
    """At the reference EMA's working frequencies (its kv studies, the 8 Hz sine, the loop's
    crossover) the modes at 1.6 to 2.9 kHz cost 1e-5 of the response: lumped, and the note
    gives both RK4 step limits and that cost."""
    sc, ctrl = ema
    model = build_model(sc, ctrl)
    assert model.P[lo.NMID] == 0
    freqs, what = working_frequencies(sc, ctrl)
    assert 8.0 in freqs and any(abs(f - 1 / 0.6) < 1e-9 for f in freqs)  # kv_8hz, kv_stroke
    choice = choose_chain(sc, ctrl, model.q0, freqs, ModelOptions().damping_ratio, what)
    assert choice.chain == "two_mass" and choice.cost < 1e-3
    assert choice.dt_reduced == pytest.approx(sc.sensors.sample_time) and choice.dt_full < 0.6 * choice.dt_reduced
    note = next(n for n in model.notes if "lumped into the two-mass reduction" in n)
    assert note == choice.note
    assert f"{choice.dt_full:.3g} s" in note and f"{choice.dt_reduced:.3g} s" in note and "1633" in note


def test_a_time_study_near_the_resonance_keeps_the_chain(ema_dict, ema):
    """The same scene with a simulate study at 30 Hz, near its 33 Hz mode (where the upper
    modes' dampers show in the response, ~3 %): simulate keeps the full chain and takes its
    smaller step, and says so."""
    sc = build(variant(ema_dict, studies__near={"kind": "simulate", "frequency": "30 Hz", "amplitude": "0.5 deg"}))
    ctrl = ema[1]
    model = build_model(sc, ctrl)
    assert model.P[lo.NMID] == 3
    note = next(n for n in model.notes if "full drivetrain chain kept" in n)
    freqs, what = working_frequencies(sc, ctrl)
    assert 30.0 in freqs
    choice = choose_chain(sc, ctrl, model.q0, freqs, ModelOptions().damping_ratio, what)
    assert choice.chain == "full" and choice.cost > LUMP_TOLERANCE and note == choice.note


def test_a_time_run_takes_simulate_s_rule_at_its_own_frequency(ema):
    """The command line's closed-loop sine run (``sine_run_options``, the reduction of that
    run) keeps or lumps the modes as ``choose_chain`` does at the run's frequency, and its
    notes carry the rule's note."""
    sc, ctrl = ema
    for f in (8.0, 30.0):
        options, notes = sine_run_options(sc, ctrl, Reference.sine(math.radians(0.5), f))
        choice = choose_chain(sc, ctrl, operating_point(sc)[0], [f], options.damping_ratio, "the study's frequencies")
        assert options.chain == choice.chain
        assert any(n == choice.note for n in notes)
        assert options.chain_note == choice.note  # the model built on the choice carries it


def test_a_model_on_a_chain_a_study_chose_does_not_note_the_lumping_again(ema):
    """The same two-mass model, asked for as such (its notes say the modes are lumped) and
    chosen by a study's rule (the study's notes say so, with the figures; the model's not
    again): the two models are the same, only the notes differ."""
    sc, ctrl = ema
    options, notes = sine_run_options(sc, ctrl, Reference.sine(math.radians(0.5), 8.0))
    assert options.chain == "two_mass" and sum("lumped into the two-mass" in n for n in notes) == 1
    chosen = build_model(sc, ctrl, options)
    asked = build_model(sc, ctrl, replace(options, chain_note=""))
    assert (chosen.P == asked.P).all()
    assert not any("lumped into the two-mass" in n for n in chosen.notes)
    assert any("lumped into the two-mass reduction (chain='two_mass')" in n for n in asked.notes)


def test_a_low_second_mode_near_the_loop_is_noted_in_the_design():
    """A three-mass chain with soft springs, its second mode at 40 Hz within ten times the
    loop's crossover (4 Hz): the design (on the two-mass plant) notes the margins the same
    controller has on the n-mass plant."""
    sc = three_mass(k=(30.0, 75.0))
    r = design(sc)
    n = r.chain_margins
    assert n is not None and n.near and n.near[0] == pytest.approx(39.6, abs=0.1)
    assert n.near[0] < 10 * max(r.margins.gain_crossover_hz)
    assert n.note in r.notes and f"gain margin {n.margins.gain_margin_db:.3g} dB" in n.note
    assert n.margins.gain_margin_db != pytest.approx(r.margins.gain_margin_db, abs=0.1)  # it does differ
    assert r.to_dict()["n_mass_plant"]["modes_hz"] == list(n.modes_hz)


def test_the_reference_ema_s_upper_modes_leave_its_margins_as_they_are():
    """Modes at 1.6 kHz and above, a loop crossing at 6 Hz: the n-mass plant's margins are the
    two-mass plant's within the stated amounts, and the notes say nothing."""
    r = design(load_scene())
    n = r.chain_margins
    assert n is not None and not n.near and n.note is None
    assert abs(n.gain_change_db) < 0.1 and abs(n.phase_change_deg) < 0.1 and abs(n.peak_change_db) < 0.1
    assert n.margins.closed_loop_stable


def test_steps_capped_by_the_sample_time_are_said_to_be_so():
    """On the carriage (a gearhead's and a screw's spring, the mode at 635 Hz lumped) both
    models' stability limits lie above the 0.125 ms sample time: the note gives the one step
    both take and each limit, not the same number twice as a comparison."""
    import tomllib
    from servo_toolkit.scene.loader import scene_from_dict
    from servo_toolkit.sim.chain_choice import stability_limit
    from .carriage_scene import carriage_scene
    sc = scene_from_dict(tomllib.loads(carriage_scene()))
    ctrl = controller_for(sc)[0]
    freqs, what = working_frequencies(sc, ctrl)
    damping = ModelOptions().damping_ratio
    choice = choose_chain(sc, ctrl, 0.1, freqs, damping, what)
    sample = sc.sensors.sample_time
    assert choice.dt_full == choice.dt_reduced == sample == choice.sample_time
    full, red = (stability_limit(sc, ctrl, 0.1, m, damping) for m in ("chain", "two_mass"))
    assert min(full, red) > sample and (choice.limit_full, choice.limit_reduced) == (full, red)
    assert (f"RK4 step {sample:.3g} s, the sample time, for both models (stability limits {red:.3g} s "
            f"two-mass, {full:.3g} s full chain)") in choice.note
    assert f"{sample:.3g} s against {sample:.3g} s" not in choice.note


def test_steps_that_differ_are_told_apart():
    from servo_toolkit.sim.chain_choice import steps_text
    # the reduction capped by the sample time, the full chain below it
    assert steps_text(2e-4, 1.18e-4, 4.4e-4, 1.18e-4, 2e-4) == (
        "RK4 step limit 0.0002 s (the sample time) for the two-mass reduction against 0.000118 s for the full chain")
    # equal to three digits but not equal: enough digits to show the difference
    text = steps_text(1.2341e-4, 1.2347e-4, 1.2341e-4, 1.2347e-4, 0.0)
    assert text == ("RK4 step limit 0.0001234 s for the two-mass reduction against 0.0001235 s for the "
                    "full chain")
