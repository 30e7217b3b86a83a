"""The linear loop's tracking of a sine with and without the velocity and acceleration
feedforward (the tuner's and the report's quick view; the nonlinear simulation runs the
model-based feedforward along the stroke).

The feedforward enters the linear closed loop at two points, as in the kernel
(:func:`servo_toolkit.sim.kernel.controller_update`): a current ``i_ff = Kv r' + Ka r''``
added to the motion controller's output, and a speed reference ``w_ff = N(q0) r'`` that the
speed loop's measured motor speed is taken against. Both come from the command's analytic
derivatives, so the closed loop with the inputs ``theta_ref``, ``tau_ext``, ``i_ff`` and
``w_ff`` stays proper; its poles are the loop's own (the feedforward adds inputs, not
feedback).
"""

from __future__ import annotations

import math
import warnings

import control as ct
import numpy as np

from ..plant.current_loop import current_controller, sample_delay
from ..plant.linear import DEFAULT_STRUCTURAL_DAMPING, plant
from .closed_loop import DELAY_SAMPLES


def feedforward_closed_loop(plant_ss, controller, motor) -> ct.StateSpace:
    """The linear closed loop with the feedforward's inputs: ``theta_ref`` (rad),
    ``tau_ext`` (N*m), ``i_ff`` (A, added to i_ref), ``w_ff`` (rad/s, subtracted from the
    motor speed the motion controller reads); outputs ``theta``, ``i``, ``omega_m``."""
    m = controller.motion
    B, D = np.asarray(m.B, float), np.asarray(m.D, float)
    nx = m.nstates
    B5 = np.hstack([B, np.zeros((nx, 1)), -B[:, 2:3]])
    D5 = np.hstack([D, np.ones((1, 1)), -D[:, 2:3]])
    motion = ct.ss(m.A, B5, m.C, D5, inputs=["theta_ref", "theta", "omega_m", "i_ff", "w_ff"], outputs=["i_ref"],
                   name="motion_ff")
    cur = current_controller(controller.current_kp, controller.current_ki, motor)
    dly = sample_delay(controller.sample_time, DELAY_SAMPLES)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return ct.interconnect([plant_ss, cur, dly, motion], inplist=["theta_ref", "tau_ext", "i_ff", "w_ff"],
                               outlist=["theta", "i", "omega_m"], inputs=["theta_ref", "tau_ext", "i_ff", "w_ff"],
                               outputs=["theta", "i", "omega_m"], name="closed_loop_ff")


def sine_tracking(scene, controller, amplitude: float, frequency: float, q0: float | None = None,
                  cycles: int = 4, points: int = 800, feedforward=None,
                  structural_damping: float = DEFAULT_STRUCTURAL_DAMPING) -> dict:
    """The linear closed loop's response to ``amplitude sin(2 pi frequency t)`` from rest,
    with ``feedforward`` (a :class:`~.controller.Feedforward`; its velocity and acceleration
    gains; None: the controller's own, if any).

    Returns
    -------
    dict
        ``t`` (s), ``reference``, ``output`` (arrays, rad or m), ``peak_error`` over the last
        two cycles and ``steady_error`` (the amplitude of |1 - T_ff| at the frequency, from the
        frequency response).
    """
    ff = controller.feedforward if feedforward is None else feedforward
    kv, ka = (0.0, 0.0) if ff is None else (ff.velocity, ff.acceleration)
    if ff is not None and ff.model:  # the model-based feedforward, linearized at q0: the designed gains
        from .feedforward import feedforward_gains
        g = feedforward_gains(scene, q0)
        kv, ka = kv + g["velocity"], ka + g["acceleration"]
    n0 = abs(float(scene.drivetrain.ratio([scene.drivetrain.mid_stroke if q0 is None else q0])[0][0]))
    speed = 1.0 if (kv or ka) else 0.0
    g_ss = plant(scene, q0, inductance=True, structural_damping=structural_damping)
    cl = feedforward_closed_loop(g_ss, controller, scene.motor)
    w = 2 * math.pi * frequency
    t = np.linspace(0.0, cycles / frequency, points)
    r = amplitude * np.sin(w * t)
    rd = amplitude * w * np.cos(w * t)
    rdd = -w * w * r
    u = np.vstack([r, np.zeros_like(t), kv * rd + ka * rdd, speed * n0 * rd])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        y = np.asarray(ct.forced_response(cl, t, u).outputs)[0]
        h = ct.frequency_response(cl, [w]).complex[0, :, 0]
    s = 1j * w
    t_ff = h[0] + h[2] * (kv * s + ka * s * s) + h[3] * speed * n0 * s
    last = t >= t[-1] - 2.0 / frequency
    return {"t": t, "reference": r, "output": y, "peak_error": float(np.max(np.abs(y - r)[last])),
            "steady_error": float(abs(amplitude) * abs(1.0 - t_ff))}


__all__ = ["feedforward_closed_loop", "sine_tracking"]
