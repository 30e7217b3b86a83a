"""The nonlinear closed loop that a closed-loop log is compared with.

The compiled simulation (:mod:`servo_toolkit.sim`) runs the scene with a fixed controller
(the rig's: by default designed once on the initial scene and held while the parameters
vary) and the logged command (:func:`~.commands.command_reference`), from equilibrium at the
command's start, with everything the nonlinear model holds: Coulomb friction, backlash,
efficiency losses, the hinge moment, the voltage and current limits. It records the output
position and the motor current at the log's samples.

Every run uses one fixed step (chosen on the initial scene), so that the traces are smooth
functions of the parameters for the finite differences of the fit. The runs of the search
skip the check of that step against the fastest eigenvalue along the run (most of a run's
cost; a trial scene that the step does not resolve diverges, and its residual steps the
search back); the fitted scene's run is checked (:meth:`LoopRun.traces` with ``check``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import SceneError
from ..sim import ModelOptions, build_model, run
from .commands import command_reference

#: points of the stroke tables of the fitted model (its assembly runs at every evaluation)
TABLE_POINTS = 65


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
        model = build_model(scene, self.controller, ModelOptions(table_points=TABLE_POINTS, stroke_end="stop"))
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
