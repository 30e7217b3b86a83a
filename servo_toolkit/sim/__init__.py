"""Time simulation: compiled closed-loop model, fixed-step RK4, stiff reference, stability.

Two levels:

- ``simulate(scene, controller=None, reference=..., duration=..., method=...)`` builds and
  runs in one call and returns a :class:`SimulationResult`.
- ``build_model(scene, controller, options) -> Model`` (immutable flat arrays) and
  ``run(model, reference, duration, method, dt, output_dt=...)`` for studies that run one
  model many times: the reference (sine amplitude/frequency/offset, step, ramp, open-loop
  voltage) lives in parameter slots read inside the kernel, so a frequency sweep is::

      model = build_model(scene, controller)
      for f in freqs:
          res = run(model, Reference.sine(a, f), duration=n_cycles / f, method="rk4")

  with no recompilation (the kernels are C, compiled when the package is installed).

Methods: ``"rk4"`` (compiled fixed step; refuses steps outside RK4's stability region),
``"paper"`` (seed 002's frozen-configuration scheme with the play operator, first order),
``"reference"`` (scipy ``solve_ivp``, LSODA or Radau, tight tolerances, same kernel) and
``"auto"`` (step from the fastest eigenvalue, |lambda dt| = 1, reduced if the eigenvalue
grows along the run, or the implicit solver when RK4 would need more than 2e7 steps).
"""

from ..loop.default_controller import default_controller
from .engine import METHODS, run
from .model import Model, ModelOptions, build_model
from .reference import Reference, initial_state
from .result import SimulationResult
from .simulate import controller_for, simulate

__all__ = ["METHODS", "Model", "ModelOptions", "Reference", "SimulationResult", "build_model",
           "controller_for", "default_controller", "initial_state", "run", "simulate"]
