"""The designed cascade as discrete blocks at its sample times.

The simulation runs the motion controller as the Tustin sampling of
``design(scene).controller.motion`` (:meth:`CascadeController.discrete_motion`), output
clamped at the current limit with back-calculation into its integrator (the exported step
does the same on its own states, :mod:`.antiwindup`). Tustin is the substitution
``s = (2 / Ts) (z - 1) / (z + 1)``, so it commutes with series and parallel connection: the
same controller is, block by block,

* the position path (position gain times the resonance filter; the compensator of the
  ``pid``, ``lead_lag`` and ``pi`` structures) on the error ``theta_ref - theta``, as
  second-order sections (biquads, direct form II transposed);
* for the cascade, the speed PI ``(kv / N) (s + wvi) / s`` on the motor-side speed error
  ``N omega_ref - omega_m`` (the ratio N folded into the position path, so that the speed
  error is a plain difference of motor speeds);
* the clamp at the motor's current limit, whose excess moves the integrator (the section with
  a pole at z = 1) as the simulation's back-calculation does.

The analog current PI of the design runs here at ``current_sample_time`` (an integer
fraction of the motion sample time): the simulation's equations
``vc = Kp e + xi; v = clamp(vc, Vlim); xi' = Ki e + (v - vc) Ki / Kp`` integrated by forward
Euler (back-calculation anti-windup with the tracking time Kp / Ki).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import control as ct
import numpy as np
from scipy import signal

from ..errors import SceneError
from . import antiwindup


@dataclass(frozen=True)
class Biquad:
    """One second-order section, ``(b0 + b1 z^-1 + b2 z^-2) / (1 + a1 z^-1 + a2 z^-2)``.

    Attributes
    ----------
    name : str
    b : tuple of float
        ``(b0, b1, b2)`` in output unit per input unit.
    a : tuple of float
        ``(a1, a2)``.
    input_unit, output_unit : str
    """

    name: str
    b: tuple
    a: tuple
    input_unit: str
    output_unit: str

    def tf(self, dt: float) -> ct.TransferFunction:
        """The section as a discrete python-control transfer function."""
        return ct.tf(list(self.b), [1.0, *self.a], dt)

    def to_dict(self) -> dict:
        return {"name": self.name, "b": [float(v) for v in self.b], "a": [1.0] + [float(v) for v in self.a],
                "input_unit": self.input_unit, "output_unit": self.output_unit}


@dataclass(frozen=True)
class CurrentLoop:
    """The current PI at its own sample time.

    Attributes
    ----------
    mode : str
        ``"pi"`` (PI with back-calculation anti-windup) or ``"ideal"`` (no inductance:
        ``v = clamp(R i_ref + Ke omega_m, Vlim)``, what the simulation does with L = 0).
    kp : float
        V/A.
    ki : float
        V/(A*s).
    kaw : float
        Back-calculation gain (1/s).
    voltage_limit : float
        V.
    sample_time : float
        s.
    resistance, back_emf_constant : float
        Ohm, V*s/rad (``"ideal"`` mode).
    """

    mode: str
    kp: float
    ki: float
    kaw: float
    voltage_limit: float
    sample_time: float
    resistance: float = 0.0
    back_emf_constant: float = 0.0

    def to_dict(self) -> dict:
        return {"mode": self.mode, "kp_V_per_A": self.kp, "ki_V_per_A_s": self.ki, "kaw_per_s": self.kaw,
                "voltage_limit_V": self.voltage_limit, "sample_time_s": self.sample_time,
                "resistance_ohm": self.resistance, "back_emf_constant_V_s_per_rad": self.back_emf_constant}


@dataclass(frozen=True)
class Estimator:
    """The motor speed fed to the speed loop: ``"ideal"`` (measured speed), ``"difference"``
    ((z_k - z_{k-1}) / Ts of the motor-encoder angle) or ``"kalman"`` (predict x <- F x,
    update x <- x + K (z - x[0]))."""

    kind: str = "ideal"
    F: tuple = ()
    K: tuple = ()
    quantum: float = 0.0

    def to_dict(self) -> dict:
        return {"kind": self.kind, "F": [list(r) for r in self.F], "K": list(self.K),
                "motor_encoder_quantum_rad": self.quantum}


@dataclass(frozen=True)
class Blocks:
    """The motion controller and current loop as blocks (see the module docstring).

    Attributes
    ----------
    structure : str
    sample_time : float
        Motion-controller sample time (s).
    position : tuple of Biquad
        Error (``output_unit``) -> motor speed command (rad/s) for the cascade, -> i_ref (A)
        otherwise.
    speed : Biquad or None
        Motor speed error (rad/s) -> i_ref (A); None without a speed loop.
    ratio : float
        N (motor rad per output rad, or per output m), folded into ``position``.
    current_limit : float
        A.
    current : CurrentLoop
    estimator : Estimator
    design : dict
        The continuous design the sections come from: position gain ``kp`` (1/s), speed
        gains ``kv`` (A per output rad/s) and ``wvi`` (rad/s) or the compensator's gains, the
        filter and its parameters (rad/s).
    output_unit : {"rad", "m"}
        Unit of the output position (theta_ref, theta): an angle, or a travel in m.
    stroke : tuple of float
        ``(lower, upper)`` of the output position (``output_unit``): the drivetrain's stroke,
        which sets the fixed-point position full scale (:mod:`.quantize`).
    """

    structure: str
    sample_time: float
    position: tuple
    speed: Biquad | None
    ratio: float
    current_limit: float
    current: CurrentLoop
    estimator: Estimator
    design: dict = field(default_factory=dict)
    output_unit: str = "rad"
    stroke: tuple = (-math.pi, math.pi)

    def sections(self) -> tuple:
        """Every section, in signal order."""
        return self.position + ((self.speed,) if self.speed is not None else ())

    def back_calculation(self):
        """The clamp's back-calculation gains (:class:`.antiwindup.BackCalculation`), None
        without an integrator."""
        return antiwindup.back_calculation(self.sections())

    def state_space(self) -> ct.StateSpace:
        """The motion controller as one discrete state space (inputs ``theta_ref``, ``theta``,
        ``omega_m``; output ``i_ref``), composed from the sections (clamp left out)."""
        pos = _series([ct.ss(s.tf(self.sample_time)) for s in self.position])
        if self.speed is None:
            a, b, c, d = _mats(pos)
            z = np.zeros((a.shape[0], 1))
            return _named(a, np.hstack([b, -b, z]), c, np.hstack([d, -d, [[0.0]]]), self.sample_time)
        vel = ct.ss(self.speed.tf(self.sample_time))
        ap, bp, cp, dp = _mats(pos)
        av, bv, cv, dv = _mats(vel)
        npos, nvel = ap.shape[0], av.shape[0]
        e_in, w_in = np.array([[1.0, -1.0, 0.0]]), np.array([[0.0, 0.0, -1.0]])
        a = np.block([[ap, np.zeros((npos, nvel))], [bv @ cp, av]])
        b = np.vstack([bp @ e_in, bv @ (dp @ e_in + w_in)])
        return _named(a, b, np.hstack([dv @ cp, cv]), dv @ (dp @ e_in + w_in), self.sample_time)

    def to_dict(self) -> dict:
        return {"structure": self.structure, "sample_time_s": self.sample_time, "ratio": self.ratio,
                "output_unit": self.output_unit,
                f"stroke_{self.output_unit}": [float(v) for v in self.stroke],
                "design": self.design,
                "position": [s.to_dict() for s in self.position],
                "speed": None if self.speed is None else self.speed.to_dict(),
                "current_limit_A": self.current_limit,
                "back_calculation": None if (bc := self.back_calculation()) is None else bc.to_dict(),
                "current_loop": self.current.to_dict(),
                "speed_estimator": self.estimator.to_dict()}


def _mats(sys):
    n = sys.nstates
    return (np.asarray(sys.A, float).reshape(n, n), np.asarray(sys.B, float).reshape(n, 1),
            np.asarray(sys.C, float).reshape(1, n), np.asarray(sys.D, float).reshape(1, 1))


def _series(systems):
    """SISO state spaces in series (first applied first)."""
    a, b, c, d = _mats(systems[0])
    for s in systems[1:]:
        a2, b2, c2, d2 = _mats(s)
        a = np.block([[a, np.zeros((a.shape[0], a2.shape[0]))], [b2 @ c, a2]])
        b, c, d = np.vstack([b, b2 @ d]), np.hstack([d2 @ c, c2]), d2 @ d
    return ct.ss(a, b, c, d, systems[0].dt)


def _named(a, b, c, d, dt):
    return ct.ss(a, b, c, d, dt, inputs=["theta_ref", "theta", "omega_m"], outputs=["i_ref"], name="motion")


def tustin_sections(num, den, sample_time: float, name: str, input_unit: str, output_unit: str) -> tuple:
    """Tustin sampling of ``num / den`` (descending powers of s) as biquads (scipy's
    ``bilinear_zpk`` and ``zpk2sos``; the gain sits in the first section)."""
    z, p, k = signal.tf2zpk(np.atleast_1d(num), np.atleast_1d(den))
    zd, pd, kd = signal.bilinear_zpk(z, p, k, 1.0 / sample_time)
    sos = signal.zpk2sos(zd, pd, kd, pairing="nearest")
    out = []
    for j, row in enumerate(sos):
        out.append(Biquad(f"{name}[{j}]" if len(sos) > 1 else name, tuple(float(v) for v in row[:3]),
                          tuple(float(v) for v in row[4:]), input_unit if j == 0 else output_unit,
                          output_unit))
    return tuple(out)


def current_loop(controller, motor, current_sample_time: float | None) -> CurrentLoop:
    """The current loop of ``controller`` for ``motor`` at ``current_sample_time`` (default:
    the motion sample time over the smallest integer n with ``w_i Ts / n <= 0.2``,
    ``w_i = Kp / L`` the bandwidth of the pole-cancelling current PI)."""
    ts = controller.sample_time
    kp, ki = controller.current_kp, controller.current_ki
    if kp <= 0 and ki <= 0:
        return CurrentLoop("ideal", 0.0, 0.0, 0.0, motor.voltage_limit, ts, motor.resistance,
                           motor.back_emf_constant)
    kaw = ki / kp if kp > 0 else motor.resistance / motor.inductance
    if current_sample_time is None:
        w_i = kp / motor.inductance if kp > 0 and motor.inductance > 0 else 2 * math.pi * 1000.0
        current_sample_time = ts / max(1, math.ceil(w_i * ts / 0.2 - 1e-9))
    if not (math.isfinite(current_sample_time) and 0 < current_sample_time <= ts):
        raise SceneError("current_sample_time", f"must be > 0 and at most the motion sample time "
                         f"{ts:g} s, got {current_sample_time!r}")
    w_i = kp / motor.inductance if motor.inductance > 0 else 0.0
    if kaw * current_sample_time >= 1.0 or w_i * current_sample_time >= 1.0:
        raise SceneError("current_sample_time", f"{current_sample_time:g} s is too long for the current "
                         f"PI (bandwidth {w_i:.4g} rad/s, anti-windup {kaw:.4g} 1/s): forward Euler needs "
                         "both times Ts below 1")
    return CurrentLoop("pi", kp, ki, kaw, motor.voltage_limit, current_sample_time)


def estimator_of(scene, controller) -> Estimator:
    """The scene's speed estimator with the gains the simulation uses."""
    kind = scene.sensors.speed_estimator
    if kind == "ideal":
        return Estimator()
    from ..sim.speed_estimator import pack
    from ..sim.model import ModelOptions
    _, extra, _, info, _ = pack(scene, controller, ModelOptions(), kind, True, 0, 0)
    if kind == "difference":
        return Estimator(kind, quantum=info["quantum_rad"])
    F = tuple(tuple(float(v) for v in row) for row in np.asarray(extra[:9]).reshape(3, 3))
    return Estimator(kind, F, tuple(float(v) for v in extra[9:12]), info["quantum_rad"])


def blocks_of(design_result, scene, current_sample_time: float | None = None) -> Blocks:
    """The blocks of a design (:func:`servo_toolkit.loop.design`) on ``scene``."""
    ctrl, motion = design_result.controller, design_result.motion
    ts = ctrl.sample_time
    if ts <= 0:
        raise SceneError("sensors.sample_time", "export needs a sampled controller: sample_time must be > 0 "
                         "(this design is continuous; set sensors.sample_time in the scene, or pass "
                         "`export --sample-time 0.2ms` to design the loop sampled and export it)")
    if motion is None:
        raise SceneError("design", "export needs a designed motion controller (design(scene)); this "
                         "result carries only a state space")
    (pn, pd), speed = motion.pieces()
    unit = scene.drivetrain.output_unit
    if speed is None:
        position = tustin_sections(pn, pd, ts, "position", unit, "A")
        vel = None
    else:
        n = motion.ratio
        position = tustin_sections(n * np.asarray(pn), pd, ts, "position", unit, "rad/s")
        vel = tustin_sections(np.asarray(speed[0]) / n, speed[1], ts, "speed_pi", "rad/s", "A")[0]
    info = {"gains": {k: float(v) for k, v in motion.gains.items()}, "filter": motion.filter,
            "filter_params": {k: float(v) for k, v in motion.filter_params.items()}, "method": "tustin"}
    return Blocks(motion.structure, ts, position, vel, motion.ratio, scene.motor.current_limit,
                  current_loop(ctrl, scene.motor, current_sample_time), estimator_of(scene, ctrl), info, unit,
                  tuple(float(v) for v in scene.drivetrain.stroke))


def tustin_to_continuous(sys_d: ct.StateSpace) -> ct.StateSpace:
    """The continuous system whose Tustin sampling (python-control's ``sample_system``,
    no prewarping) is ``sys_d``: the bilinear map inverted in state space."""
    t = sys_d.dt
    ad, bd, cd, dd = (np.atleast_2d(np.asarray(m, float)) for m in (sys_d.A, sys_d.B, sys_d.C, sys_d.D))
    n = ad.shape[0]
    eye = np.eye(n)
    a = (2.0 / t) * (ad - eye) @ np.linalg.inv(ad + eye)
    ima = eye - 0.5 * t * a
    b = ima @ bd / t
    c = cd @ ima
    d = dd - 0.5 * c @ bd
    return ct.ss(a, b, c, d, inputs=list(sys_d.input_labels), outputs=list(sys_d.output_labels),
                 name=sys_d.name)
