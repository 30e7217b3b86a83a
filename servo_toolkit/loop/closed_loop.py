"""The linear loop of a scene and a :class:`CascadeController`: the toolkit's own state-space
blocks (``*_block``, what the margins are computed on) and the same as python-control
systems."""

from __future__ import annotations

from ..lti.connect import interconnect
from ..lti.system import StateSpace, as_system, ss
from ..plant.current_loop import current_loop_block, sample_delay_block
from ..plant.linear import DEFAULT_STRUCTURAL_DAMPING, plant_block

#: Sampling is modelled as this many sample times of delay (ZOH half sample + computation).
DELAY_SAMPLES = 1.5
#: the closed loop's outputs
CLOSED_LOOP_OUTPUTS = ("theta", "i", "omega_m", "u", "omega")


def linear_closed_loop(scene, controller, q0=None, model: str = "auto",
                       structural_damping: float = DEFAULT_STRUCTURAL_DAMPING) -> "control.StateSpace":
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
    return closed_loop_block(scene, controller, q0, model, structural_damping).to_control()


def closed_loop_block(scene, controller, q0=None, model: str = "auto",
                      structural_damping: float = DEFAULT_STRUCTURAL_DAMPING) -> StateSpace:
    """:func:`linear_closed_loop` as the toolkit's own state-space block."""
    g = plant_block(scene, q0, inductance=True, model=model, structural_damping=structural_damping)
    return closed_loop_of(g, controller, scene.motor, ("theta_ref", "tau_ext"), CLOSED_LOOP_OUTPUTS,
                          name="closed_loop")


def closed_loop_of(plant_ss, controller, motor, inputs=("theta_ref", "tau_ext"), outputs=CLOSED_LOOP_OUTPUTS,
                   name: str = "") -> StateSpace:
    """The closed loop of a given plant block (a python-control system or the toolkit's own,
    inputs ``u`` and ``tau_ext``) with ``controller``'s current loop on ``motor``, its
    sampling delay and its motion controller, from ``inputs`` to ``outputs`` (signal names of
    the blocks), as :func:`closed_loop_block` assembles the scene's."""
    cur = current_loop_block(controller.current_kp, controller.current_ki, motor)
    dly = sample_delay_block(controller.sample_time, DELAY_SAMPLES)
    return interconnect([as_system(plant_ss), cur, dly, controller.motion_block], inplist=list(inputs),
                        outlist=list(outputs), inputs=list(inputs), outputs=list(outputs), name=name)


def open_loop(scene, controller, q0=None, model: str = "auto",
              structural_damping: float = DEFAULT_STRUCTURAL_DAMPING) -> "control.StateSpace":
    """Open loop broken at the position error: input ``theta_error`` (rad), output ``theta``;
    inner (current, speed) loops closed. Negative unit feedback of it is the closed loop."""
    return open_loop_block(scene, controller, q0, model, structural_damping).to_control()


def open_loop_block(scene, controller, q0=None, model: str = "auto",
                    structural_damping: float = DEFAULT_STRUCTURAL_DAMPING) -> StateSpace:
    """:func:`open_loop` as the toolkit's own state-space block."""
    g = plant_block(scene, q0, inductance=True, model=model, structural_damping=structural_damping)
    return open_loop_block_of(g, controller, scene.motor)


def open_loop_of(plant_ss, controller, motor) -> "control.StateSpace":
    """:func:`open_loop` for a given plant block (e.g. a parameter variant; a python-control
    system or the toolkit's own)."""
    return open_loop_block_of(plant_ss, controller, motor).to_control()


def open_loop_block_of(plant_ss, controller, motor) -> StateSpace:
    """:func:`open_loop_of` as the toolkit's own state-space block."""
    cur = current_loop_block(controller.current_kp, controller.current_ki, motor)
    dly = sample_delay_block(controller.sample_time, DELAY_SAMPLES)
    m = controller.motion_block
    cut = ss(m.A, m.B, m.C, m.D, inputs=["theta_ref", "theta_meas", "omega_m"], outputs=["i_ref"],
             name="motion_cut")
    sys = interconnect([as_system(plant_ss), cur, dly, cut], inplist=["theta_meas"], outlist=["theta"],
                       check_unused=False)
    return ss(sys.A, -sys.B, sys.C, -sys.D, inputs=["theta_error"], outputs=["theta"], name="loop")
