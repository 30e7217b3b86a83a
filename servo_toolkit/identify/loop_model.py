"""The nonlinear closed loop that a closed-loop log is compared with.

The compiled simulation (:mod:`servo_toolkit.sim`) runs the scene with a fixed controller
(the rig's: by default designed once on the initial scene and held while the parameters
vary) and the logged command (:func:`~.commands.command_reference`), from equilibrium at the
command's start, with the full model that ``simulate --full`` runs (:data:`LOG_MODEL`): the
sampled controller, the current loop on the winding's inductance, every drivetrain mode
(structural damping :data:`~servo_toolkit.plant.linear.DEFAULT_STRUCTURAL_DAMPING` where a
stage gives none, as the linear plant), friction that holds at rest, backlash, efficiency
losses, the hinge moment, the voltage and current limits. It records the output position
and the motor current at the log's samples, the control instants.

One effect is left out: the encoders' counts in the controller's feedback. The rig's
controller reads its output encoder in counts, and the loop answers every count the output
crosses; the model cannot know where the counts lie on the rig's shaft (the encoder's
mounting), and with them its traces jump as a parameter moves a crossing by one sample, so
the Jacobian of the fit (central differences of 1e-6 of each value, :func:`.search.differences`)
would see either the frozen feedback between two crossings or a jump, not the loop's
response: with them (and 5 % damping, smooth friction), the intervals of the rotary flap's
inertia and hinge moment came out as narrow as 1e-5 of their values and missed the truth in 7
of 8 cases over four logs. The counts' effect on the loop
is a dither of the current of a few per cent of a typical current sensor's noise (0.0045 A
RMS on the rotary flap of ``tests/test_identify_loop_coverage.py`` against 0.05 A), which the fit
takes as part of the noise.

Every run uses one fixed step (chosen on the initial scene), so that the traces are smooth
functions of the parameters for the finite differences of the fit. The runs of the search
skip the check of that step against the fastest eigenvalue along the run (most of a run's
cost; a trial scene that the step does not resolve diverges, and its residual steps the
search back); the fitted scene's run is checked (:meth:`LoopRun.traces` with ``check``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..errors import SceneError
from ..plant.linear import DEFAULT_STRUCTURAL_DAMPING
from ..sim import ModelOptions, build_model, run
from .commands import command_reference
from .data import LoopData

#: points of the stroke tables of the fitted model (its assembly runs at every evaluation)
TABLE_POINTS = 65
#: the model a closed-loop log is compared with: ``simulate --full``'s (every drivetrain mode,
#: friction that holds, the linear plant's structural damping), without the encoders' counts in
#: the controller's feedback, with an elastic end stop (a trial value that drives the output
#: to the end of its stroke costs residual instead of stopping the fit)
LOG_MODEL = ModelOptions(damping_ratio=DEFAULT_STRUCTURAL_DAMPING, friction="stick", chain="full",
                         quantization=False, stroke_end="stop", table_points=TABLE_POINTS)


@dataclass(frozen=True)
class LoopRun:
    """One closed-loop run of a scene, at the samples of a log.

    Parameters
    ----------
    controller : CascadeController
        The controller the rig runs.
    reference : Reference
        The logged command.
    duration, record_dt, dt : float
        Length of the log, its sample interval and the simulation's step (s).
    """

    controller: object
    reference: object
    duration: float
    record_dt: float
    dt: float
    points: int

    @classmethod
    def for_log(cls, scene, controller, data) -> "LoopRun":
        """The run of ``data`` (a :class:`~.data.LoopData`) with the step of ``scene``'s
        automatic choice."""
        if scene.drivetrain.output_unit != data.unit:
            raise SceneError("header", f"the log gives the output in {data.unit}, the scene's output is in "
                             f"{scene.drivetrain.output_unit} (columns command_{scene.drivetrain.output_unit}, "
                             f"output_{scene.drivetrain.output_unit})", data.source)
        t = data.time_s
        record_dt = float(t[-1] - t[0]) / (t.size - 1)
        ts = scene.sensors.sample_time
        if ts > 0 and abs(record_dt / ts - round(record_dt / ts)) > 1e-6 * record_dt / ts:
            raise SceneError("time_s", f"the log's step {record_dt:g} s must be a multiple of the scene's sample "
                             f"time {ts:g} s ([sensors] sample_time)", data.source)
        reference = command_reference(t, data.command, data.source)
        first = cls(controller, reference, float(t[-1] - t[0]), record_dt, 0.0, t.size)
        res = first._run(scene, None)
        return cls(controller, reference, first.duration, record_dt, float(res.dt_s), t.size)

    def _run(self, scene, dt, check=True):
        model = build_model(scene, self.controller, LOG_MODEL)
        return run(model, self.reference, self.duration, "rk4", dt, output_dt=self.record_dt, check_stability=check)

    def traces(self, scene, check: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """Output position and motor current at the log's samples.

        Parameters
        ----------
        scene : Scene
        check : bool
            Check the step against the fastest eigenvalue along the run (False: a run the
            step does not resolve is caught only when it diverges).

        Raises
        ------
        SimulationError
            The run left the stroke, diverged or (``check``) left RK4's stability region.
        """
        res = self._run(scene, self.dt, check)
        n = self.points
        return np.asarray(res.output_angle[:n]), np.asarray(res.motor_current[:n])


def simulated_log(scene, controller, reference, duration: float):
    """A closed-loop log as a drive writes it, from the compiled simulation: the command, the
    output position and the motor current at the control instants (every ``[sensors]
    sample_time``), the loop with every effect :data:`LOG_MODEL` holds and the encoders'
    counts in the controller's feedback, as the rig has them.

    The output is exact and the current noiseless: round the output to the rig's encoder and
    add the current sensor's noise to make it a rig's. A log read off ``simulate -o``'s
    traces is not one: their records are not the control instants (the recorder keeps at most
    4000 of them), and a current interpolated between them misses its steps within each
    sample.

    Parameters
    ----------
    scene : Scene
        With a ``[sensors] sample_time``.
    controller : CascadeController
    reference : Reference
        The position command.
    duration : float
        Seconds.

    Returns
    -------
    LoopData
    """
    ts = scene.sensors.sample_time
    if not ts > 0:
        raise SceneError("sensors.sample_time", "a drive's log is written at the control instants; give the "
                         "scene's sample time")
    model = build_model(scene, controller, replace(LOG_MODEL, quantization=True, stroke_end="error",
                                                          table_points=ModelOptions.table_points))
    res = run(model, reference, duration, "rk4", output_dt=ts)
    n = int(round(duration / ts))  # the record at the final time is the next log's first
    return LoopData(np.asarray(res.times[:n]), np.asarray(res.reference_angle[:n]),
                    np.asarray(res.output_angle[:n]), np.asarray(res.motor_current[:n]),
                    scene.drivetrain.output_unit)
