"""The a-priori cost of leaving out friction that holds (``ModelOptions(friction="stick")``).

The reduced model falls back to the smooth model, the motor's Coulomb friction
``Tc tanh(w / w_s)`` alone: no stick at the reversals, no breakaway excess Ts - Tc, none of
the load's friction, no band in which a lossy chain at rest holds. The estimate is how far
the whole friction moves the output: a relay at the breakaway levels, the motor's Ts
reflected to the output (N Ts) and the load's Ts_L, of describing-function amplitude

    F1 = (4 / pi) (N Ts + Ts_L),

moves the output by ``|S_d(jw)| F1``, ``S_d`` the closed loop's response from a torque at the
output to the output; relative to the output's amplitude ``|T(jw)| A`` the estimate is the
largest ``|S_d| F1 / (|T| A)`` over the study's frequencies and amplitudes (the smallest
amplitude is the worst: friction is a fixed torque). The smooth model catches part of that
friction (the Coulomb level away from the reversals), so the estimate is an upper one, close
where friction dominates and loose where the motion does: on the reference EMA at 8 Hz
(two-mass model) it is 0.23 where leaving stick out costs 0.14 at 0.05 deg (a few encoder
counts) and 0.0058 where it costs 2e-5 at 2 deg; with a 0.2 N*m breakaway, 2.3 against 0.25
at 0.05 deg and 0.058 against 2e-5 at 2 deg (lossless). Where the drive at rest holds within
a band (:func:`~.hunting.holding_band`: the breakaway levels, widened by a lossy chain's
efficiencies) that the loop's torque at the command's whole amplitude as error, Kt |C(jw)| A
with C the motion controller's current per rad of output angle, does not leave, the output
stays still and the estimate is at least 1 (the output's whole motion): on the reference EMA
(a band of +-0.73 N*m at the motor under its 700 N*m hinge moment, +-0.02 N*m without the loss) at 0.05 deg. ``reduce``
measures the cost by running the study with and without stick.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import replace

import control as ct
import numpy as np

from ..drivetrain.stage_friction import lumped_friction
from ..plant.linear import PLANT_OUTPUTS, current_controller, plant_matrices, sample_delay
from .hunting import holding_band

def disturbance_response(p, controller, motor, w) -> np.ndarray:
    """Closed-loop response of the output angle to a torque at the output (rad per N*m, or
    m per N), at the angular frequencies ``w``, assembled as the reduction's loops are."""
    a, b, c, d, states = plant_matrices(p, True)
    g = ct.ss(a, b, c, d, inputs=["u", "tau_ext"], outputs=list(PLANT_OUTPUTS), states=states, name="plant")
    cur = current_controller(controller.current_kp, controller.current_ki, motor)
    from ..loop.closed_loop import DELAY_SAMPLES
    dly = sample_delay(controller.sample_time, DELAY_SAMPLES)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cl = ct.interconnect([g, cur, dly, controller.motion], inplist=["theta_ref", "tau_ext"],
                             outlist=["theta"], inputs=["theta_ref", "tau_ext"], outputs=["theta"],
                             check_unused=False)
    return np.asarray(ct.frequency_response(cl[0, 1], w).complex).reshape(-1)


def position_gain(controller, w) -> np.ndarray:
    """The motion controller's current command per unit of output angle (A/rad, or A/m) at the
    angular frequencies ``w``: with the output held still the loop is open there, and this is
    the current the command's error asks for."""
    motion = controller.motion
    path = motion[0, list(motion.input_labels).index("theta")]
    return np.asarray(ct.frequency_response(path, w).complex).reshape(-1)


def friction_effect(scene, controller, p, w, t_full, amplitudes, base):
    """The numbers of the effect "static friction (stick)" of a reduction, or None when the full model runs
    the smooth friction (``base.friction != "stick"``) or the scene has no Coulomb or static
    friction.

    Parameters
    ----------
    scene : Scene
    controller : CascadeController
    p : PlantParameters
        The design plant at the operating point.
    w : numpy.ndarray
        The study's angular frequencies (rad/s).
    t_full : numpy.ndarray
        Closed-loop response theta / theta_ref at ``w``.
    amplitudes : sequence of float
        Command amplitudes (rad, or m).
    base : ModelOptions
        The full model's options.

    Returns
    -------
    (str, float) or None
        The quantity compared, in words, and the estimate.
    """
    from ..core.output_units import output_unit
    motor, load = lumped_friction(scene, p.q0, True, [])  # a stage's friction reflected to the motor
    ts_m, ts_l = motor.breakaway_torque, load.breakaway
    if base.friction != "stick" or max(motor.coulomb_friction, ts_m, load.coulomb_friction, ts_l) == 0:
        return None
    n = p.N
    hold = holding_band(scene, p.q0, base.efficiency)  # N*m at the motor shaft
    s_d = np.abs(disturbance_response(p, controller, motor, w))
    swing = motor.torque_constant * np.abs(position_gain(controller, w))  # N*m per rad of error
    t = np.abs(t_full)
    worst, where, still = 0.0, (0.0, 0.0), False
    for a in amplitudes:
        for k, wk in enumerate(w):
            e = s_d[k] * 4 / math.pi * (n * ts_m + ts_l) / (t[k] * a)
            if swing[k] * a < hold:  # the error's whole amplitude cannot move the torque out of the band
                e, still = max(e, 1.0), True
            if e > worst:
                worst, where = float(e), (wk / (2 * math.pi), a)
    u = output_unit(scene)
    quantity = (f"motor breakaway {ts_m:.4g} N*m (Coulomb {motor.coulomb_friction:.4g} N*m, smoothed over "
                f"{base.friction_speed:g} rad/s without stick) as a relay at the output"
                + (f", load breakaway {ts_l:.4g} {u.moment}" if ts_l > 0 else "")
                + (f"; the drive at rest holds within +-{hold:.4g} N*m at the motor, which the loop's torque "
                   "at the command's amplitude does not leave somewhere (the output stays still: a cost of 1)"
                   if still else "")
                + f"; worst at {where[0]:.3g} Hz, {u.text(where[1], 3)}")
    return quantity, worst


def without_stick(options):
    """The reduced options with the smooth friction model."""
    return replace(options, friction="smooth")


__all__ = ["disturbance_response", "friction_effect", "without_stick"]
