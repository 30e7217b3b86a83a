"""The drive an excitation enters, as the model's motion controller, and its linear response.

``current``: the drive in current (torque) mode inside the scene's designed position loop,
which holds the operating point against the load; the excitation is added to the loop's
current reference (an actuator under a load moment or with a lossy screw drifts to a stroke
end under a current with no feedback). ``speed``: the drive in speed mode, the design's
speed PI on the motor speed, the excitation its motor-speed reference; no position loop
(the PI's integral keeps the mean speed at the reference's, zero, so the position does not
drift).

Either is a linear motion controller from ``['theta_ref', 'theta', 'omega_m']`` to
``i_ref`` (:class:`~servo_toolkit.loop.controller.CascadeController`), so the one compiled
model runs it and :func:`~servo_toolkit.loop.linear_closed_loop` gives its linear response,
the excitation entering at ``theta_ref`` with unit gain (A, or motor rad/s). For the model's
run a held state z replaces what the run starts from: the position command the loop holds
(``current``), or the offset of the reference input (``speed``, ``e = (r + z - omega_m) /
N``); the run's equilibrium start solves it, so the drive starts at rest at the operating
point and the excitation, 0 at the start, is what the drive adds. The linear loop, about the
operating point, has no z.
"""

from __future__ import annotations

import math

import numpy as np

from ...errors import SceneError

INPUTS = ("current", "speed")
#: the excitation's unit and its column in the file
UNITS = {"current": "A", "speed": "rad/s"}
COLUMNS = {"current": "current_excitation_A", "speed": "speed_reference_rad_s"}
#: the linear response's outputs, by name in :func:`~servo_toolkit.loop.linear_closed_loop`
OUTPUTS = ("i", "u", "omega_m", "theta")
#: frequencies checked against python-control when the response is evaluated by modes
CHECK_POINTS = 32


def _abcd(sys):
    n, m, p = sys.nstates, sys.ninputs, sys.noutputs
    return (np.asarray(sys.A, float).reshape(n, n), np.asarray(sys.B, float).reshape(n, m),
            np.asarray(sys.C, float).reshape(p, n), np.asarray(sys.D, float).reshape(p, m))


def _motion(A, B, C, D):
    import control as ct
    return ct.ss(A, B, C, D, inputs=["theta_ref", "theta", "omega_m"], outputs=["i_ref"], name="motion")


def current_motion(motion, held: bool):
    """The design's motion controller with the excitation added to its output; its position
    command from a held state (``held``) or zero (the linear loop's deviation)."""
    A, B, C, D = _abcd(motion)
    n = A.shape[0]
    B2 = np.hstack([np.zeros((n, 1)), B[:, 1:]])
    D2 = np.hstack([[[1.0]], D[:, 1:]])
    if not held:
        return _motion(A, B2, C, D2)
    A2 = np.block([[A, B[:, :1]], [np.zeros((1, n + 1))]])
    return _motion(A2, np.vstack([B2, np.zeros((1, 3))]), np.hstack([C, D[:, :1]]), D2)


def speed_motion(design_motion, held: bool):
    """The design's speed PI alone on ``(r - omega_m) / N`` (+ a held offset z)."""
    import control as ct
    _, speed = design_motion.pieces()
    if speed is None:
        raise SceneError("--input", f"speed needs the drive's speed loop; the design is a {design_motion.structure} "
                         "loop without one: use --input current")
    Av, Bv, Cv, Dv = _abcd(ct.ss(ct.tf(*speed)))
    g = 1.0 / design_motion.ratio
    n = Av.shape[0]
    B = np.hstack([Bv * g, np.zeros((n, 1)), -Bv * g])
    D = np.array([[Dv[0, 0] * g, 0.0, -Dv[0, 0] * g]])
    if not held:
        return _motion(Av, B, Cv, D)
    A2 = np.block([[Av, Bv * g], [np.zeros((1, n + 1))]])
    return _motion(A2, np.vstack([B, np.zeros((1, 3))]), np.hstack([Cv, Dv * g]), D)


def drive_controller(design_result, kind: str, sample_time: float, held: bool = True):
    """The :class:`CascadeController` of the drive taking the excitation (module doc)."""
    from ...loop.controller import CascadeController
    if kind not in INPUTS:
        raise SceneError("--input", f"must be one of {', '.join(INPUTS)} (got {kind!r})")
    base = design_result.controller
    if kind == "current":
        motion = current_motion(base.motion, held)
        what = "the design's position loop, the excitation added to its current reference"
    else:
        motion = speed_motion(design_result.motion, held)
        what = "the design's speed PI (motor speed), the excitation its reference, no position loop"
    return CascadeController(motion, base.current_kp, base.current_ki, sample_time=sample_time, description=what)


def _modal_response(sys, w):
    """``(outputs, n_w)`` complex response of a one-input system at ``w`` (rad/s) from its
    eigenvectors (fast for many frequencies); None when the modes are ill-conditioned."""
    A, B, C, D = _abcd(sys)
    lam, V = np.linalg.eig(A)
    if np.linalg.cond(V) > 1e8:
        return None
    left = C @ V
    right = np.linalg.solve(V, B[:, 0])
    s = 1j * np.asarray(w, float)
    return (left * right) @ (1.0 / (s[None, :] - lam[:, None])) + D[:, :1]


def linear_loop(scene, controller, q0: float, structural_damping: float):
    """The linear loop from the excitation to :data:`OUTPUTS` (current A, voltage V, motor
    speed rad/s, output rad or m) and its slowest decay rate (1/s; poles at 0, the output's
    free position in speed mode, left out)."""
    from ...loop import linear_closed_loop
    cl = linear_closed_loop(scene, controller, q0=q0, structural_damping=structural_damping)
    sub = cl[[cl.output_labels.index(o) for o in OUTPUTS], cl.input_labels.index("theta_ref")]
    poles = cl.poles()
    moving = poles[np.abs(poles) > 1e-6 * max(1.0, float(np.max(np.abs(poles))))]
    decay = float(np.min(-moving.real)) if moving.size else math.inf
    if moving.size and not decay > 0:
        worst = moving[np.argmax(moving.real)]
        from ...errors import SimulationError
        raise SimulationError(f"the drive's loop is not stable (its rightmost pole at {worst.real:.4g} "
                              f"{worst.imag:+.4g}j 1/s): no steady response to predict")
    return sub, decay


def response(sys, frequency_hz) -> np.ndarray:
    """``(len(OUTPUTS), n)`` complex response at ``frequency_hz``: from the loop's modes,
    checked against python-control at a few frequencies (python-control throughout when
    they disagree by more than 1e-6)."""
    import control as ct
    f = np.asarray(frequency_hz, float)
    w = 2 * np.pi * f
    probe = w[np.unique(np.linspace(0, w.size - 1, min(CHECK_POINTS, w.size)).astype(int))]
    exact = np.asarray(ct.frequency_response(sys, probe).complex).reshape(len(OUTPUTS), -1)
    fast = _modal_response(sys, probe)
    if fast is not None and np.all(np.abs(fast - exact) <= 1e-6 * (np.abs(exact) + 1e-12 * np.max(np.abs(exact)))):
        return _modal_response(sys, w)
    return np.asarray(ct.frequency_response(sys, w).complex).reshape(len(OUTPUTS), -1)


def periodic_response(sys, shape, resolution_hz: float, floor: float = 1e-9) -> np.ndarray:
    """``(len(OUTPUTS), samples)``: the loop's periodic steady state over one period of the
    excitation ``shape`` (samples of one period, every bin whose amplitude is above ``floor``
    of the largest)."""
    spectrum = np.fft.rfft(shape)
    size = np.abs(spectrum)
    bins = np.flatnonzero(size > floor * size.max())
    bins = bins[bins > 0]
    out = np.zeros((len(OUTPUTS), spectrum.size), complex)
    out[:, bins] = response(sys, bins * resolution_hz) * spectrum[bins]
    return np.fft.irfft(out, len(shape), axis=1)


__all__ = ["COLUMNS", "INPUTS", "OUTPUTS", "UNITS", "current_motion", "drive_controller", "linear_loop",
           "periodic_response", "response", "speed_motion"]
