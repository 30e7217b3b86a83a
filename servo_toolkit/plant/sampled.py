"""Motor speed per current as a drive's log samples them: both read at the control instants.

A drive's current loop follows a current reference that its motion controller holds for
a sample time, so the current steps towards each new reference within the sample: it is not
band-limited, and its samples at the control instants do not carry it between them. The
speed, the integral of the torque, is smooth. The response of the logged speed samples to
the logged current samples is therefore not the continuous ``omega_m / i`` at the line's
frequency: both are the held reference's zero-order-hold responses, and their ratio

    H(e^{j w T}) = G_omega(e^{j w T}) / G_i(e^{j w T})

(``G_x`` the zero-order-hold discretization at the sample time T of the current loop and
the plant from the reference to ``x``) is what an H1 estimate of such a log converges to.
It differs from the continuous response by a lead growing with frequency, of 0 for a slow
current loop (the current ramps between its samples) up to half a sample for an
instantaneous one (the current jumps just after each sample). On a 1 kHz current loop
sampled at 5 kHz it is 0.1 sample (21 us, 0.5 deg at 65 Hz). Whatever delay the drive
puts between its sample and the reference's update scales both responses alike and cancels
in the ratio, as does the motion controller that sets the reference.

The current loop is the simulation's: an analog PI ``u = kp (i_ref - i) + integral``,
``integral' = ki (i_ref - i)`` on the armature ``L i' = u - R i - Ke omega_m``; without
inductance the current is the reference itself, held for the sample.
"""

from __future__ import annotations

import numpy as np

from ..lti.response import solved_response
from .current_loop import current_loop_gains
from .linear import DEFAULT_STRUCTURAL_DAMPING, mechanics_block


def _current_to_speed(scene, mech):
    """``(b, c)``: the mechanics' input column of the motor current (``Kt`` times that of
    ``tau_m``) and its output row of ``omega_m``."""
    b = mech.B[:, [mech.inputs.index("tau_m")]] * scene.motor.torque_constant
    return b, mech.C[[mech.outputs.index("omega_m")], :]


def _held_reference_loop(scene, mech, gains, motor):
    """``(A, B, C, D)`` from the current reference to ``[omega_m, i]``, the current loop on
    ``motor``'s winding."""
    A_m = mech.A
    b, c = _current_to_speed(scene, mech)
    n = A_m.shape[0]
    if motor.inductance == 0:  # the current is the reference
        return A_m, b, np.vstack([c, np.zeros((1, n))]), np.array([[0.0], [1.0]])
    kp, ki = gains
    L, R, Ke = motor.inductance, motor.resistance, motor.back_emf_constant
    A = np.zeros((n + 2, n + 2))
    A[:n, :n] = A_m
    A[:n, [n]] = b
    A[n, :n] = -Ke * c[0] / L
    A[n, n] = -(R + kp) / L
    A[n, n + 1] = 1.0 / L
    A[n + 1, n] = -ki
    B = np.zeros((n + 2, 1))
    B[n, 0], B[n + 1, 0] = kp / L, ki
    C = np.zeros((2, n + 2))
    C[0, :n] = c[0]
    C[1, n] = 1.0
    return A, B, C, np.zeros((2, 1))


def zero_order_hold(A, B, sample_time: float):
    """``(Ad, Bd)``: the exact discretization of ``x' = A x + B u`` with ``u`` held for
    ``sample_time`` (the matrix exponential of the augmented system)."""
    from scipy.linalg import expm
    n, m = B.shape
    M = np.zeros((n + m, n + m))
    M[:n, :n], M[:n, n:] = A, B
    E = expm(M * sample_time)
    return E[:n, :n], E[:n, n:]


def drive_plant_response(scene, frequency_hz, q0=None, structural_damping: float = DEFAULT_STRUCTURAL_DAMPING,
                         sample_time: float | None = None, current_gains=None, drive_motor=None) -> np.ndarray:
    """Motor speed per current (rad/s per A, complex) of the linear plant at ``q0`` as a drive
    samples both at its control instants (module doc).

    Parameters
    ----------
    scene : Scene
    frequency_hz : array_like
        Frequencies (Hz), below half the sample rate.
    q0 : float, optional
        Operating point (default mid-stroke).
    structural_damping : float
        The drivetrain's damping ratio (:func:`~.linear.plant_parameters`).
    sample_time : float, optional
        The drive's control sample time (s); default the scene's ``sensors.sample_time``. Zero
        (a continuous controller) gives the continuous ``Kt omega_m / tau_m``.
    current_gains : (float, float), optional
        The current PI's kp (V/A) and ki (V/(A*s)); default the design's,
        :func:`~.current_loop.current_loop_gains` of the scene's motor.
    drive_motor : Motor, optional
        The motor whose winding (R, L, Ke) the current loop acts on (default the scene's): a
        fit holds the drive's as it is while the mechanics vary, so the winding's values do not
        enter a current -> speed measurement.

    Returns
    -------
    numpy.ndarray
        Complex response at each frequency.
    """
    f = np.asarray(frequency_hz, float).reshape(-1)
    mech = mechanics_block(scene, q0, structural_damping=structural_damping)
    ts = float(scene.sensors.sample_time or 0.0) if sample_time is None else float(sample_time)
    if ts <= 0:
        b, c = _current_to_speed(scene, mech)
        return solved_response(mech.A, b, c, np.zeros((1, 1)), 2j * np.pi * f)[:, 0, 0]
    motor = scene.motor if drive_motor is None else drive_motor
    gains = current_loop_gains(motor) if current_gains is None else current_gains
    A, B, C, D = _held_reference_loop(scene, mech, gains, motor)
    Ad, Bd = zero_order_hold(A, B, ts)
    h = solved_response(Ad, Bd, C, D, np.exp(2j * np.pi * f * ts))[:, :, 0]
    return h[:, 0] / h[:, 1]


__all__ = ["drive_plant_response", "zero_order_hold"]
