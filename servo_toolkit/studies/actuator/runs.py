"""The two nonlinear closed-loop runs ``check`` judges the actuator on, with the full model
(every drivetrain mode, backlash, the voltage and current limits, the sampled controller and
its encoders) and friction that holds (the motor's, each stage's and the load's Coulomb and
static friction, exact stick): a step run to rest, and the requirement sine.

The step starts after :data:`STEP_AT` of equilibrium and runs ``2 x`` the settling allowance;
the part after the allowance (the *rest window*) is where the position error at rest, a limit
cycle and the current ripple at rest are read. The sine runs :data:`SINE_CYCLES` periods
from rest; its first two periods are the start's transient, the last :data:`JUDGED_CYCLES`
are judged (tracking error, ripple, rms current), and the time at the limits is counted after
the transient.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ... import sim
from ...core.output_units import output_unit
from ...errors import SimulationError, StrokeEndReached

#: s of equilibrium before the step
STEP_AT = 0.01
SINE_CYCLES = 8
JUDGED_CYCLES = 3
#: the start of a sine run that is its start's transient, in periods
TRANSIENT_CYCLES = 2


def full_options() -> sim.ModelOptions:
    """The full model with friction that holds."""
    from ...plant.linear import DEFAULT_STRUCTURAL_DAMPING
    return replace(sim.ModelOptions(damping_ratio=DEFAULT_STRUCTURAL_DAMPING), chain="full", friction="stick")


def step_run(scene, controller, plan, options=None):
    """The step of ``plan`` from the operating point, run to twice its settling allowance."""
    return sim.simulate(scene, controller, reference=sim.Reference.step(plan.step, at=STEP_AT),
                        duration=STEP_AT + 2.0 * plan.settling_time, method="rk4", options=options or full_options())


def sine_run(scene, controller, plan, options=None):
    """The requirement sine of ``plan``, :data:`SINE_CYCLES` periods."""
    return sim.simulate(scene, controller, reference=sim.Reference.sine(plan.sine_amplitude, plan.frequency),
                        duration=SINE_CYCLES / plan.frequency, method="rk4", options=options or full_options())


def run_both(scene, controller, plan, options=None):
    """``(step_run, sine_run, failure, stroke_end_s)``: a run that leaves the stroke is a
    physical outcome (``failure`` says so and when, that run is None); a run that cannot be carried out numerically
    raises SimulationError naming which run it was (no verdict on a figure it did not make)."""
    runs, failure, end = [], "", float("nan")
    for fn, text in ((step_run, f"{output_unit(scene).text(plan.step, 3)} step"),
                     (sine_run, f"requirement sine at {plan.frequency:g} Hz")):
        try:
            runs.append(fn(scene, controller, plan, options))
        except StrokeEndReached as exc:
            runs.append(None)
            if not failure:
                failure, end = f"the {text} left the stroke at {exc.time_s:.4g} s: {exc}", exc.time_s
        except SimulationError as exc:
            raise SimulationError(f"the nonlinear {text} (full model, friction that holds) could not be carried "
                                  f"out: {exc} (--linear-only skips it)") from None
    return runs[0], runs[1], failure, end


def window(times, start: float) -> np.ndarray:
    """True from ``start`` on."""
    return np.asarray(times) >= start


__all__ = ["JUDGED_CYCLES", "SINE_CYCLES", "STEP_AT", "TRANSIENT_CYCLES", "full_options", "run_both", "sine_run",
           "step_run", "window"]
