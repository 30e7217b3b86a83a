"""Model responses compared with measurements.

``plant``
    Motor current -> motor speed (rad/s per A) of the linear plant at mid-stroke, as a
    drive's own frequency-response measurement sees it: the mechanical block driven by
    tau_m = Kt * i, both signals sampled at the control instants of the scene's sample time
    (:func:`servo_toolkit.plant.sampled.drive_plant_response`: the current loop steps the
    current towards each held reference within the sample, which its samples do not carry,
    a lead of up to half a sample; a scene without a sample time gives the continuous
    response). The drive's current loop (the design's gains and the winding they act on) is
    the initial scene's, held fixed while the plant varies, so the winding's values do not
    enter.
``closed_loop``
    Position command -> output position (rad/rad) of the linear closed loop with a given
    controller (designed once on the initial scene and held fixed while the plant varies).
``time``
    The voltage-driven linear plant simulated from rest with the measured voltage: current,
    motor angle and output angle (deviations from the start).
"""

from __future__ import annotations

import numpy as np

from ..errors import SceneError
from ..plant.current_loop import current_loop_gains
from ..plant.linear import plant
from ..plant.sampled import drive_plant_response

RESPONSES = ("plant", "closed_loop")


def plant_response(scene, frequency_hz, drive_motor=None) -> np.ndarray:
    """omega_m / i (rad/s per A), complex, at the frequencies, as a drive logging both at
    its control instants measures it: its current loop the design's for ``drive_motor``
    (default the scene's motor) acting on that motor's winding."""
    motor = scene.motor if drive_motor is None else drive_motor
    return drive_plant_response(scene, frequency_hz, current_gains=current_loop_gains(motor), drive_motor=motor)


def closed_loop_response(scene, controller, frequency_hz) -> np.ndarray:
    """theta / theta_ref of the linear closed loop, complex, at the frequencies."""
    from ..loop.closed_loop import closed_loop_block
    sub = closed_loop_block(scene, controller)["theta", "theta_ref"]
    return np.asarray(sub(2j * np.pi * np.asarray(frequency_hz, float))).reshape(-1)


def frequency_model(scene, response: str, controller=None):
    """A function ``scene -> complex response at frequencies`` for ``response``."""
    if response == "plant":
        return lambda s, f: plant_response(s, f, scene.motor)
    if response == "closed_loop":
        return lambda s, f: closed_loop_response(s, controller, f)
    raise SceneError("--response", f"must be one of {', '.join(RESPONSES)} (got {response!r})")


def time_response(scene, time_s, voltage_V) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Current (A), motor angle (rad) and output angle (rad) of the voltage-driven linear
    plant from rest (no external torque) under ``voltage_V``."""
    import control as ct
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
