"""The speed estimator of the sampled speed loop: scene/option choice -> kernel parameters.

The compiled ``speed_estimate`` (``servo_toolkit/_physics/control.h``) runs it once per sample on
the motor-encoder angle z (the motor angle rounded to ``2 pi / motor_encoder_counts``):

* ``"difference"``: omega = (z_k - z_{k-1}) / Ts. Quantization noise: the angle error is
  uniform over one count (variance q^2/12), so a difference of two independent errors has
  RMS q / (sqrt(6) Ts), and each count the motor crosses shows up as a q/Ts pulse.
* ``"kalman"``: the constant-acceleration Kalman filter of :mod:`servo_toolkit.loop.encoder_estimators`
  (measurement noise q^2/12, process noise from a jerk level) in its steady-state form,
  computed here with filterpy/scipy: predict x <- F x, update x <- x + K (z - x[0]). It
  equals filterpy's ``KalmanFilter`` started at the steady-state covariance.

The filter's state starts at the measured angle with zero speed and acceleration (the
equilibrium of a motor at rest), as does the difference's previous angle.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import SceneError
from ..loop.encoder_estimators import default_jerk as estimator_jerk
from ..loop.encoder_estimators import encoder_quantum, speed_response, steady_state_gain
from . import layout as lo


def default_jerk(scene, controller, q0: float) -> float:
    """Jerk level (motor rad/s^3) for the Kalman filter's process noise
    (:func:`servo_toolkit.loop.encoder_estimators.default_jerk`) at the controller's direct
    speed gain and the motor-side inertia at ``q0``."""
    motor = scene.motor
    jm = float(scene.drivetrain.motor_inertia([q0])[0])
    kv = float(controller.motion_block.D[0, 2])
    return estimator_jerk(motor.torque_constant, motor.current_limit, jm, kv, controller.sample_time)


def pack(scene, controller, options, kind: str, quantization: bool, nx_before: int, np_before: int):
    """Kernel data of the speed estimator.

    Parameters
    ----------
    kind : str
        ``"difference"`` or ``"kalman"`` (``"ideal"`` needs nothing).
    quantization : bool
        Round the motor angle to the encoder count.
    nx_before, np_before : int
        State and parameter lengths before the estimator's own.

    Returns
    -------
    slots : dict
        Header slot -> value.
    extra_p : numpy.ndarray
        Appended parameters (F row-major and K for the Kalman filter).
    names : list of str
        Estimator state names.
    info : dict
        What ran (JSON-ready).
    note : str
        One line for the model's notes.
    """
    sensors = scene.sensors
    ts = controller.sample_time
    if sensors.motor_encoder_counts <= 0:
        raise SceneError("sensors.motor_encoder_counts", f"speed estimator {kind!r} needs the motor "
                         "encoder: motor_encoder_counts must be > 0")
    quantum = encoder_quantum(sensors.motor_encoder_counts)
    slots = {lo.EST: lo.ESTIMATORS.index(kind), lo.LSB_M: quantum if quantization else 0.0,
             lo.OFF_E: nx_before, lo.INV_TS: 1.0 / ts}
    quant = (f"{sensors.motor_encoder_counts} counts/rev, quantum {quantum:.4g} rad"
             if quantization else "motor encoder not quantized")
    info = {"kind": kind, "motor_encoder_counts": int(sensors.motor_encoder_counts),
            "quantum_rad": quantum, "quantized": bool(quantization), "sample_time_s": ts}
    if kind == "difference":
        names = ["speed_estimator.angle_rad", "speed_estimator.speed_rad_s"]
        note = (f"speed loop fed by the backward difference of the motor encoder ({quant}) over "
                f"Ts = {ts:.3g} s: speed resolution {quantum / ts:.4g} rad/s")
        return slots, np.zeros(0), names, info, note
    jerk = options.estimator_jerk or default_jerk(scene, controller, scene.drivetrain.mid_stroke)
    F, _, K = steady_state_gain(ts, quantum, jerk)
    slots[lo.OFF_KF] = np_before
    f = np.logspace(0, math.log10(0.5 / ts), 400)
    mag = np.abs(speed_response(F, K, ts, f))
    below = np.flatnonzero(mag < math.sqrt(0.5))
    bw = float(f[below[0]]) if below.size else float(f[-1])
    info.update(jerk_rad_s3=float(jerk), gain=[float(k) for k in K], bandwidth_Hz=bw,
                jerk_source="options" if options.estimator_jerk else "default")
    names = ["speed_estimator.angle_rad", "speed_estimator.speed_rad_s",
             "speed_estimator.acceleration_rad_s2"]
    note = (f"speed loop fed by a constant-gain Kalman filter (constant acceleration, jerk "
            f"{jerk:.3g} rad/s^3, measurement noise quantum^2/12) on the motor encoder ({quant}); "
            f"speed estimate -3 dB at {bw:.4g} Hz")
    return slots, np.concatenate([F.ravel(), K]), names, info, note


