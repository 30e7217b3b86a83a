"""The blocks between the motion controller's current command and the plant's armature
voltage, linear: the analog current PI (its gains cancelling the armature pole, or the ideal
loop of a motor without inductance) and the sampling delay on the current command (Pade).

Each is built as the toolkit's own :class:`~servo_toolkit.lti.system.StateSpace`
(``*_block``); :func:`current_controller` and :func:`sample_delay` hand the same matrices
and names over as python-control systems.
"""

from __future__ import annotations

import math

from ..lti.convert import pade, tf2ss
from ..lti.system import StateSpace, ss


def current_loop_gains(motor, bandwidth_hz: float = 1000.0) -> tuple[float, float]:
    """PI gains (V/A, V/(A*s)) cancelling the armature pole: kp = L*wc, ki = R*wc, so the
    current loop (back-emf aside) is a first-order lag at ``bandwidth_hz``."""
    wc = 2 * math.pi * bandwidth_hz
    return motor.inductance * wc, motor.resistance * wc


def current_controller(kp: float, ki: float, motor=None) -> "control.StateSpace":
    """Analog current PI: inputs ``i_cmd``, ``i`` (A), ``omega_m`` (rad/s); output ``u`` (V);
    state ``current_integral`` (V). With ``motor`` of zero inductance the loop is ideal:
    u = R * i_cmd + Ke * omega_m (no state, no ``i`` input), as in :class:`CascadeController`."""
    return current_loop_block(kp, ki, motor).to_control()


def current_loop_block(kp: float, ki: float, motor=None) -> StateSpace:
    """:func:`current_controller` as the toolkit's own state-space block."""
    if motor is not None and motor.inductance == 0:
        return ss([], [], [], [[motor.resistance, motor.back_emf_constant]],
                  inputs=["i_cmd", "omega_m"], outputs=["u"], name="current_loop")
    return ss([[0.0]], [[ki, -ki, 0.0]], [[1.0]], [[kp, -kp, 0.0]],
              inputs=["i_cmd", "i", "omega_m"], outputs=["u"], states=["current_integral"],
              name="current_loop")


def sample_delay(sample_time: float, samples: float = 1.5, order: int = 2) -> "control.StateSpace":
    """Sampling as a delay on the current command: ``samples`` * T (half a sample of
    zero-order hold plus one of computation), Pade order ``order``; input ``i_ref``,
    output ``i_cmd`` (A). A zero sample time gives a unit gain."""
    return sample_delay_block(sample_time, samples, order).to_control()


def sample_delay_block(sample_time: float, samples: float = 1.5, order: int = 2) -> StateSpace:
    """:func:`sample_delay` as the toolkit's own state-space block."""
    delay = samples * sample_time
    if delay <= 0:
        return ss([], [], [], [[1.0]], inputs=["i_ref"], outputs=["i_cmd"], name="sample_delay")
    num, den = pade(delay, order)
    return tf2ss(num, den, inputs=["i_ref"], outputs=["i_cmd"], name="sample_delay")
