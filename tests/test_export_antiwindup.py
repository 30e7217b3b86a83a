"""The exported C against the simulation's own sampled controller through the current clamp.

The simulation back-calculates the motion controller's integrator at the current limit (a
clamped sample moves the integral by the clamp's excess, so the next output starts at the
limit; ``tests/test_antiwindup.py`` checks that against Astrom & Hagglund). The exported C
does the same on its biquads' states. Here a closed-loop run of the reference EMA (holding
its 700 N*m hinge moment, then a 20 deg step against it: the current at its 60 A limit for
46 ms, then released) is recorded at every controller sample: the inputs the controller saw
(theta_ref, theta, omega_m) and the i_ref it gave. The compiled C, started holding the same
current, is fed the same inputs and must give the same i_ref, sample by sample, within the
export's tolerances (floating point: 1e-6 of the largest i_ref; fixed point: the stated
rounding bound). Without the back-calculation the C's integral winds up while the clamp
holds and its i_ref stays at the limit long after the run's has left it.
"""

from __future__ import annotations

import ctypes
import dataclasses
import json
import math

import numpy as np
import pytest

from servo_toolkit import design, load_scene, simulate
from servo_toolkit.export import export, quantized_controller
from servo_toolkit.sim import ModelOptions, Reference

from .conftest import SCENES
from .test_export import CController, needs_cc, python_controller, sim_back_calculation

STEP, AT, DURATION = math.radians(20.0), 0.005, 0.3


@pytest.fixture(scope="module")
def ema():
    scene = load_scene(SCENES / "ema_reference.toml")
    return scene, design(scene, progress=False)


def recorded_run(scene, controller):
    """The closed-loop step at every controller sample: (theta_ref, theta, omega_m) as the
    controller saw them (output encoder quantization off) and the i_ref it gave."""
    ts = controller.sample_time
    run = simulate(scene, controller, reference=Reference.step(STEP, at=AT), duration=DURATION,
                   options=ModelOptions(quantization=False), output_dt=ts)
    assert np.allclose(np.diff(run.times), ts, rtol=1e-9)
    assert any("anti-windup" in n for n in run.notes)
    return np.column_stack([run.reference_angle, run.output_angle, run.motor_speed]), run.current_reference


def direct_form_states(sections):
    """``(A, C)`` of biquads in series as the C runs them (direct form II transposed, the
    states of each section in turn)."""
    mats = [(np.array([[-s.a[0], 1.0], [-s.a[1], 0.0]]), np.array([s.b[1] - s.a[0] * s.b[0], s.b[2] - s.a[1] * s.b[0]]),
             np.array([1.0, 0.0]), s.b[0]) for s in sections]
    a, b, c, dd = mats[0]
    for a2, b2, c2, d2 in mats[1:]:
        a = np.block([[a, np.zeros((a.shape[0], 2))], [np.outer(b2, c), a2]])
        b, c, dd = np.concatenate([b, b2 * dd]), np.concatenate([d2 * c, c2]), d2 * dd
    return a, c.reshape(1, -1)


def start_holding(c, res, current):
    """Set the C's states to hold ``current`` (A) at rest, where the run starts: the
    integrator's direction in the C's states over its output gain (the simulation's
    back-calculation gains: a state that adds 1 A to every later output) times it, in
    state counts of each section's output in fixed point."""
    q = res.quantized
    blocks = res.blocks if q is None else q.blocks
    v = sim_back_calculation(*direct_form_states(blocks.sections())) * current
    if q is None:
        for j, value in enumerate(v):
            c.state[j] = value
        return
    states = (ctypes.c_int64 * 256).from_buffer(c.state)
    for j, value in enumerate(v):
        states[j] = round(value / q.sections()[j // 2].lsb_out * 2**q.guard)


def _at_limit(i_ref, limit):
    return np.abs(i_ref) >= limit * (1 - 1e-12)


def _held(want, limit):
    """The samples at the limit, checked to be a long hold that ends for good."""
    held = _at_limit(want, limit)
    last = np.nonzero(held)[0][-1]
    assert held[last - 400:last + 1].all() and last < len(want) - 1000
    assert np.max(np.abs(want[last + 1:])) < limit
    return held


@needs_cc
def test_float_c_follows_the_simulation_through_the_clamp(ema, tmp_path):
    """The run holds 25.2 A for 5 ms, then the step's clamp holds i_ref at +60 A for 46 ms
    and lets go at 60 ms; the compiled C on its inputs gives its i_ref to 1e-6 of the
    largest (measured: 7e-9 A), at the limit on the same samples. The C without
    back-calculation stayed at the limit to the end of the run (0.3 s) and differed by up
    to 120 A."""
    scene, d = ema
    res = export(d, scene, tmp_path)
    u, want = recorded_run(scene, d.controller)
    limit = scene.motor.current_limit
    held = _held(want, limit)
    c = CController(tmp_path, fixed=False)
    c.init()
    start_holding(c, res, want[0])
    got = np.array([c.motion(*row) for row in u])
    np.testing.assert_array_equal(_at_limit(got, limit), held)
    assert np.max(np.abs(got - want)) <= 1e-6 * np.max(np.abs(want))


@needs_cc
@pytest.mark.parametrize("fmt", ["q15", "q31"])
def test_fixed_point_c_follows_the_simulation_through_the_clamp(ema, tmp_path, fmt):
    """The quantized controller simulated through the same step, and the fixed-point C on
    its inputs rounded to counts: within the stated rounding bound (q15 1.0 A, q31 0.10 A)
    at every sample, the clamp's 46 ms included (measured: q15 0.15 A, q31 5e-4 A). The C
    without back-calculation differed by 4 A (its integral saturated at the state's full
    scale instead of winding up further)."""
    scene, d = ema
    res = export(d, scene, tmp_path, fixed_point=fmt)
    q = res.quantized
    u, want = recorded_run(scene, quantized_controller(d, q))
    limit = q.blocks.current_limit
    held = _held(want, limit)
    c = CController(tmp_path, fixed=True)
    c.init()
    start_holding(c, res, want[0])
    counts = np.rint(u / np.array([q.lsb["theta"], q.lsb["theta"], q.lsb["omega"]])).astype(int)
    got = np.array([c.motion(*map(int, row)) for row in counts]) * q.lsb["current"]
    assert res.error_bound < 0.02 * limit
    assert np.max(np.abs(got - want)) <= res.error_bound
    assert abs(int(np.sum(_at_limit(got, limit))) - int(held.sum())) <= 5


@needs_cc
@pytest.mark.parametrize("fmt", [None, "q15"])
def test_a_feedforward_current_is_clamped_with_the_controller(ema, tmp_path, fmt):
    """``servo_motion_step_ff`` clamps the controller's output plus the feedforward current
    and back-calculates the excess, as the simulation's sample does with a feedforward:
    +-80 A pulses of feedforward current, which alone hold the clamp, move the integral by
    the excess (the controller's own output, clamped first and the feedforward added after,
    would overshoot the limit)."""
    scene, d = ema
    res = export(d, scene, tmp_path, fixed_point=fmt)
    ts, limit = d.controller.sample_time, scene.motor.current_limit
    n = 2000
    t = np.arange(n) * ts
    u = np.column_stack([0.002 * np.sin(2 * math.pi * 8 * t), 0.0015 * np.sin(2 * math.pi * 8 * t - 0.3),
                         20.0 * np.cos(2 * math.pi * 8 * t)])
    i_ff = np.where((t > 0.05) & (t < 0.08), 80.0, 0.0) - np.where((t > 0.12) & (t < 0.13), 80.0, 0.0)
    c = CController(tmp_path, fixed=fmt is not None)
    c.init()
    if fmt is None:
        want = python_controller(res.motion, u, limit, i_ff)
        got = np.array([c.motion_ff(*row, f) for row, f in zip(u, i_ff)])
        tolerance = 1e-6 * np.max(np.abs(want))
    else:
        q = res.quantized
        lsb = np.array([q.lsb["theta"], q.lsb["theta"], q.lsb["omega"]])
        counts = np.rint(u / lsb).astype(int)
        ff = np.rint(i_ff / q.lsb["current"]).astype(int)
        got = np.array([c.motion_ff(*map(int, row), int(f)) for row, f in zip(counts, ff)]) * q.lsb["current"]
        want = python_controller(q.blocks.state_space(), u, q.blocks.current_limit, i_ff)
        tolerance = res.error_bound
    assert np.sum(_at_limit(want, limit)) > 300
    assert np.max(np.abs(got - want)) <= tolerance
    assert np.max(np.abs(got)) <= limit


@needs_cc
@pytest.mark.parametrize("structure", ["pid", "pi"])
@pytest.mark.parametrize("fmt", [None, "q15", "q31"])
def test_back_calculation_of_a_position_integrator(ema, tmp_path, structure, fmt):
    """The pid and pi structures integrate in the position path (the pi's integrator in its
    second section, behind the notch; the pid's gains move both of its section's states).
    Feedforward pulses of +-80 A push i_ref past the limit (the controller's own output
    stays within the fixed-point current full scale, 64 A, where the stated bound holds):
    the back-calculation moves the integral by the excess (over 15 A off the controller that
    winds up, once the pulses end), and the C, in floating point and fixed point, follows the
    simulation's sampled controller (on the quantized coefficients in fixed point) within the
    export's tolerance."""
    from .test_export import inputs
    scene, _ = ema
    d = design(scene, progress=False, over_stroke=False, structure=structure)
    res = export(d, scene, tmp_path, fixed_point=fmt)
    q = res.quantized
    blocks = res.blocks if q is None else q.blocks
    assert blocks.back_calculation().integrator == blocks.sections()[-1].name
    n, ts = 1000, d.controller.sample_time
    t = np.arange(n) * ts
    u = inputs(n, ts, 4, amplitude=0.05, speed=100.0)  # the pid's own i_ref within +-30 A
    i_ff = np.where((t > 0.02) & (t < 0.04), 80.0, 0.0) - np.where((t > 0.06) & (t < 0.07), 80.0, 0.0)
    limit = blocks.current_limit
    sys_d = res.motion if q is None else q.blocks.state_space()
    want = python_controller(sys_d, u, limit, i_ff)
    # the back-calculation moved the integral: after the pulses i_ref is 20 A off the wound-up one
    wound = python_controller(sys_d, u, limit, i_ff, back_calculation=False)
    assert np.min(np.abs(want - wound)[t > 0.08]) > 15.0
    c = CController(tmp_path, fixed=q is not None)
    c.init()
    if q is None:
        got = np.array([c.motion_ff(*row, f) for row, f in zip(u, i_ff)])
        tolerance = 1e-6 * limit
    else:
        counts = np.rint(u / np.array([q.lsb["theta"], q.lsb["theta"], q.lsb["omega"]])).astype(int)
        ff = np.rint(i_ff / q.lsb["current"]).astype(int)
        got = np.array([c.motion_ff(*map(int, row), int(f)) for row, f in zip(counts, ff)]) * q.lsb["current"]
        tolerance = res.error_bound
    assert np.max(np.abs(got - want)) <= tolerance


@pytest.mark.parametrize("options", [{}, {"structure": "pid"}, {"structure": "pi"}, {"resonance_filter": "none"}])
def test_gains_are_the_simulations_on_the_exported_states(ema, options):
    """The export's gains, from the biquads' closed form, are the simulation's own
    back-calculation gains (the integrator's eigenvector over its output gain) computed on
    the exported realization: the biquads in direct form II transposed, in series."""
    scene, _ = ema
    d = design(scene, progress=False, over_stroke=False, **options)
    blocks = export(d, scene).blocks
    sections = blocks.sections()
    want = sim_back_calculation(*direct_form_states(sections))
    got = blocks.back_calculation()
    assert want is not None and got is not None
    np.testing.assert_allclose(got.vector(sections), want, atol=1e-12)
    # the realization the simulation runs has its own states, the same effect on i_ref: a
    # unit excess adds 1 A to every later output
    ad, _, cd, _ = d.controller.discrete_motion()
    g = sim_back_calculation(ad, cd)
    assert (cd @ g).item() == pytest.approx(1.0) and np.allclose(ad @ g, g)


def test_the_header_and_json_state_the_limit_and_the_gains(ema, tmp_path):
    """The header names the clamp (A, and counts in fixed point) and every back-calculation
    gain with its unit; controller.json carries them; a lead-lag has no integrator and says
    so."""
    scene, d = ema
    h = export(d, scene, tmp_path / "f").files["servo_controller.h"]
    assert "clamped at +-60 A (SERVO_CURRENT_LIMIT_A)" in h
    assert "speed_pi state s0 += 1 A/A * e" in h and "#define SERVO_HAS_BACK_CALCULATION 1" in h
    data = json.loads((tmp_path / "f" / "controller.json").read_text())
    assert data["blocks"]["back_calculation"] == {"integrator": "speed_pi",
                                                  "gains": [{"section": 1, "name": "speed_pi", "state": 0, "gain": 1.0,
                                                             "unit": "A/A"}]}
    res = export(d, scene, tmp_path / "q", fixed_point="q15")
    h = res.files["servo_controller.h"]
    assert "(SERVO_CURRENT_LIMIT_A, 30720 counts)" in h
    assert "speed_pi state s0 += 1 A/A * e\n" in h and "states' 2^-SERVO_GUARD counts" in h
    assert res.controller_json()["quantized"]["back_calculation"]["name"] == "speed_pi"
    assert "st->speed[0] += e;" in res.files["servo_controller.c"]
    assert "st->speed[1]" not in res.files["servo_controller.c"].split("excess")[-1]  # -a2 = 0 in a PI
    lead = design(scene, progress=False, over_stroke=False, structure="lead_lag")
    out = export(lead, scene)
    assert "No integrator: the clamp needs no anti-windup." in out.files["servo_controller.h"]
    assert "#define SERVO_HAS_BACK_CALCULATION 0" in out.files["servo_controller.h"]
    assert "excess" not in out.files["servo_controller.c"]
    assert "no integrator: no anti-windup" in out.table()
    assert "clamp at 60 A, anti-windup by back-calculation into speed_pi: speed_pi s0 += 1 A/A x excess" in res.table()


@needs_cc
def test_an_integrator_before_other_sections(ema, tmp_path):
    """The closed form holds wherever the integrator sits: the pi structure's two sections
    in the other order (Tustin sections commute), its integrator first and the notch after
    it, whose states move to their steady state on the integrator's constant (the gains
    divided by the notch's DC gain). The floating-point C through the clamp equals the
    simulation's sampled controller; the fixed-point code, which back-calculates in the
    integrator section's own arithmetic, refuses such an order (no design makes it)."""
    from servo_toolkit.export.c_code import header, source
    from servo_toolkit.export.quantize import quantize
    from .test_export import inputs
    scene, _ = ema
    d = design(scene, progress=False, over_stroke=False, structure="pi")
    res = export(d, scene)
    swapped = dataclasses.replace(res.blocks, position=res.blocks.position[::-1])
    bc = swapped.back_calculation()
    assert bc.integrator == "position[1]" and {k for k, _, _, _ in bc.gains} == {0, 1}
    np.testing.assert_allclose(bc.vector(swapped.sections()),
                               sim_back_calculation(*direct_form_states(swapped.sections())), atol=1e-12)
    (tmp_path / "servo_controller.h").write_text(header(swapped))
    (tmp_path / "servo_controller.c").write_text(source(swapped))
    c = CController(tmp_path, fixed=False)
    c.init()
    n, ts, limit = 1000, d.controller.sample_time, scene.motor.current_limit
    t = np.arange(n) * ts
    u = inputs(n, ts, 4, amplitude=0.05, speed=100.0)
    i_ff = np.where((t > 0.02) & (t < 0.04), 80.0, 0.0)
    want = python_controller(res.motion, u, limit, i_ff)
    got = np.array([c.motion_ff(*row, f) for row, f in zip(u, i_ff)])
    assert np.max(np.abs(got - want)) <= 1e-6 * limit
    with pytest.raises(ValueError, match="integrator in the last section"):
        quantize(swapped, scene.motor, "q15")
