"""A hand-tuned, low-bandwidth cascade from a scene's numbers (used when no designed
controller is available).

P position loop -> PI speed loop on the motor speed -> PI current loop (pole-zero
cancellation of the armature L/R). Bandwidths, from the inside out: current
``min(2 pi 1 kHz, 0.1 * 2 pi / Ts)``, speed 1/10 of it and below a third of the drivetrain's
first resonance, position 1/4 of the speed loop. It is deliberately conservative: a
stable test plant, not a design (``servo_toolkit.loop.design`` makes designs).
"""

from __future__ import annotations

import math

import numpy as np

from ..lti.system import ss
from .controller import MOTION_INPUTS, MOTION_OUTPUTS, CascadeController


def default_controller(scene) -> CascadeController:
    """A stable, conservative cascade for ``scene`` (motor-driven drivetrain)."""
    motor = scene.motor
    drive = scene.drivetrain
    q0 = drive.mid_stroke
    ts = scene.sensors.sample_time
    n0 = float(drive.ratio([q0])[0][0])
    jm = float(drive.motor_inertia([q0])[0])
    w_i = 2 * math.pi * 1000.0
    if ts > 0:
        w_i = min(w_i, 0.1 * 2 * math.pi / ts)
    w_s = w_i / 10
    k_total = float(drive.stiffness([q0]).total[0])
    if math.isfinite(k_total) and scene.load.inertia > 0:
        j_out = float(drive.inertia([q0])[0][0])
        j_red = (j_out - scene.load.inertia) * scene.load.inertia / j_out
        w_s = min(w_s, math.sqrt(k_total / max(j_red, 1e-12)) / 3)
    w_p = w_s / 4
    kv = jm * w_s / motor.torque_constant          # A per (rad/s) of motor speed
    kiv = kv * w_s / 4                             # A per rad of motor angle
    kpp = w_p * n0                                 # motor rad/s per output rad
    # state: integral of the speed error e_w = kpp (theta_ref - theta) - omega_m
    a = np.zeros((1, 1))
    b = np.array([[kpp, -kpp, -1.0]])
    c = np.array([[kiv]])
    d = np.array([[kv * kpp, -kv * kpp, -kv]])
    motion = ss(a, b, c, d, inputs=list(MOTION_INPUTS), outputs=list(MOTION_OUTPUTS),
                states=["speed_error_integral"], name="fallback_motion")
    if motor.inductance > 0:
        kp_i, ki_i = motor.inductance * w_i, motor.resistance * w_i
    else:
        kp_i, ki_i = 0.0, 0.0
    return CascadeController(motion=motion, current_kp=kp_i, current_ki=ki_i, sample_time=ts,
                             description=(f"fallback cascade: current {w_i / 2 / math.pi:.0f} Hz, "
                                          f"speed {w_s / 2 / math.pi:.1f} Hz, position "
                                          f"{w_p / 2 / math.pi:.2f} Hz"))
