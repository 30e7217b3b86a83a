"""The linear loop of a scene and a :class:`CascadeController`, as python-control systems."""

from __future__ import annotations

import warnings

import control as ct

from ..plant.linear import DEFAULT_STRUCTURAL_DAMPING, current_controller, plant, sample_delay

#: Sampling is modelled as this many sample times of delay (ZOH half sample + computation).
DELAY_SAMPLES = 1.5


def _blocks(scene, controller, q0, model, structural_damping):
    g = plant(scene, q0, inductance=True, model=model, structural_damping=structural_damping)
    cur = current_controller(controller.current_kp, controller.current_ki, scene.motor)
    dly = sample_delay(controller.sample_time, DELAY_SAMPLES)
    return g, cur, dly


def linear_closed_loop(scene, controller, q0=None, model: str = "auto",
                       structural_damping: float = DEFAULT_STRUCTURAL_DAMPING) -> ct.StateSpace:
    """Closed loop of the linear plant at ``q0`` with ``controller``.

    Parameters
    ----------
    scene : Scene
    controller : CascadeController
    q0 : float, optional
        Operating point (rad), default mid-stroke.
    model : {"auto", "two_mass", "rigid"}
    structural_damping : float
        Damping ratio of the drivetrain mode.

    Returns
    -------
    control.StateSpace
        Inputs ``theta_ref`` (rad) and ``tau_ext`` (N*m); outputs ``theta`` (rad), ``i`` (A),
        ``omega_m`` (rad/s), ``u`` (V), ``omega`` (rad/s). The motion controller runs
        continuous here; sampling enters as a Pade delay of 1.5 sample times on the current
        command. Limits (voltage, current) are not in a linear model.
    """
    g, cur, dly = _blocks(scene, controller, q0, model, structural_damping)
    return ct.interconnect([g, cur, dly, controller.motion], inplist=["theta_ref", "tau_ext"],
                           outlist=["theta", "i", "omega_m", "u", "omega"],
                           inputs=["theta_ref", "tau_ext"], outputs=["theta", "i", "omega_m", "u", "omega"],
                           name="closed_loop")


def open_loop(scene, controller, q0=None, model: str = "auto",
              structural_damping: float = DEFAULT_STRUCTURAL_DAMPING) -> ct.StateSpace:
    """Open loop broken at the position error: input ``theta_error`` (rad), output ``theta``;
    inner (current, speed) loops closed. Negative unit feedback of it is the closed loop."""
    g = plant(scene, q0, inductance=True, model=model, structural_damping=structural_damping)
    return open_loop_of(g, controller, scene.motor)


def open_loop_of(plant_ss, controller, motor) -> ct.StateSpace:
    """:func:`open_loop` for a given plant block (e.g. a parameter variant)."""
    cur = current_controller(controller.current_kp, controller.current_ki, motor)
    dly = sample_delay(controller.sample_time, DELAY_SAMPLES)
    m = controller.motion
    cut = ct.ss(m.A, m.B, m.C, m.D, inputs=["theta_ref", "theta_meas", "omega_m"], outputs=["i_ref"],
                name="motion_cut")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sys = ct.interconnect([plant_ss, cur, dly, cut], inplist=["theta_meas"], outlist=["theta"],
                              check_unused=False)
    return ct.ss(sys.A, -sys.B, sys.C, -sys.D, inputs=["theta_error"], outputs=["theta"], name="loop")
