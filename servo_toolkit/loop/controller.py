"""The controller description shared by loop design and simulation.

A cascade: an inner analog current loop (PI on the armature current, output a voltage
clamped at the motor's voltage limit) and a sampled motion controller, a linear system from
``['theta_ref', 'theta', 'omega_m']`` (output-angle reference and measurement, rad; motor
speed, rad/s) to ``['i_ref']`` (A), clamped at the motor's current limit.
"""

from __future__ import annotations

from dataclasses import dataclass

import control as ct
import numpy as np

MOTION_INPUTS = ("theta_ref", "theta", "omega_m")
MOTION_OUTPUTS = ("i_ref",)


@dataclass(frozen=True)
class CascadeController:
    """A designed controller; immutable, shared by linear analysis and simulation.

    Parameters
    ----------
    motion : control.StateSpace
        Continuous-time motion controller with inputs ``MOTION_INPUTS`` and output
        ``i_ref`` (A). It is sampled at ``sample_time`` (Tustin) for simulation.
    current_kp : float
        Current-loop proportional gain (V/A).
    current_ki : float
        Current-loop integral gain (V/(A*s)).
    sample_time : float
        Motion-controller sample time (s); 0 for continuous.
    description : str
        What the controller is made of (for reports).
    """

    motion: ct.StateSpace
    current_kp: float
    current_ki: float
    sample_time: float = 0.0
    description: str = ""

    def discrete_motion(self):
        """``(Ad, Bd, Cd, Dd)`` of the motion controller sampled at ``sample_time``.

        With ``sample_time == 0`` the continuous matrices are returned.
        """
        sys = self.motion
        if self.sample_time > 0:
            sys = ct.sample_system(sys, self.sample_time, method="tustin")
        return tuple(np.asarray(m, dtype=float) for m in (sys.A, sys.B, sys.C, sys.D))
