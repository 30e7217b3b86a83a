"""Model responses compared with measurements.

``plant``
    Motor current -> motor speed (rad/s per A) of the linear plant at mid-stroke: the
    mechanical block driven by tau_m = Kt * i (a drive's own frequency-response
    measurement; it runs in current control, so the electrical parameters do not enter).
``closed_loop``
    Position command -> output position (rad/rad) of the linear closed loop with a given
    controller (designed once on the initial scene and held fixed while the plant varies).
``time``
    The voltage-driven linear plant simulated from rest with the measured voltage: current,
    motor angle and output angle (deviations from the start).
"""

from __future__ import annotations

import control as ct
import numpy as np

from ..errors import SceneError
from ..plant.linear import mechanics, plant

RESPONSES = ("plant", "closed_loop")


def plant_response(scene, frequency_hz) -> np.ndarray:
    """omega_m / i (rad/s per A), complex, at the frequencies."""
    m = mechanics(scene)
    sub = m[m.output_labels.index("omega_m"), m.input_labels.index("tau_m")]
    w = 2 * np.pi * np.asarray(frequency_hz, float)
    return scene.motor.torque_constant * np.asarray(ct.frequency_response(sub, w).complex).reshape(-1)


def closed_loop_response(scene, controller, frequency_hz) -> np.ndarray:
    """theta / theta_ref of the linear closed loop, complex, at the frequencies."""
    from ..loop import linear_closed_loop
    cl = linear_closed_loop(scene, controller)
    sub = cl[cl.output_labels.index("theta"), cl.input_labels.index("theta_ref")]
    w = 2 * np.pi * np.asarray(frequency_hz, float)
    return np.asarray(ct.frequency_response(sub, w).complex).reshape(-1)


def frequency_model(scene, response: str, controller=None):
    """A function ``scene -> complex response at frequencies`` for ``response``."""
    if response == "plant":
        return plant_response
    if response == "closed_loop":
        return lambda s, f: closed_loop_response(s, controller, f)
    raise SceneError("--response", f"must be one of {', '.join(RESPONSES)} (got {response!r})")


def time_response(scene, time_s, voltage_V) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Current (A), motor angle (rad) and output angle (rad) of the voltage-driven linear
    plant from rest (no external torque) under ``voltage_V``."""
    g = plant(scene)
    t = np.asarray(time_s, float)
    u = np.vstack([np.asarray(voltage_V, float), np.zeros_like(t)])
    res = ct.forced_response(g, t - t[0], u, return_x=True)
    y, x = np.asarray(res.outputs), np.asarray(res.states)
    states = list(g.state_labels)
    n = scene.drivetrain.ratio([scene.drivetrain.mid_stroke])[0][0]
    side = states.index("theta_1") if "theta_1" in states else states.index("theta")
    motor_angle = abs(float(n)) * x[side]
    return y[g.output_labels.index("i")], motor_angle, y[g.output_labels.index("theta")]
