"""Cam drive of seed 002: follower load, equivalent inertia, clearance (its constant-speed
study is :mod:`servo_toolkit.studies.cam.constant_speed`).

Sign conventions
----------------
X is the rise direction of the follower, Y completes a right-handed frame with Z along the
cam shaft, and the cam turns positively (theta increasing) about Z. Gravity G has the
components ``G (sin(gamma) cos(beta), sin(gamma) sin(beta), -cos(gamma))``: ``gamma`` is the
tilt from the Z axis (0 = lying flat), ``beta`` the heading of its in-plane part from the
rise direction. (The seed measures beta from the *current* direction of motion and swaps it
for its supplement on the return stroke; with a fixed X axis that swap is automatic.)

The follower is a yoke with two rollers on a conjugate cam (s(theta) + s(theta + pi) =
stroke, checked in the tests), so the cam can push it both ways. The cam force along X is
``P = m a - G_x + sign(v) f``; the roller carrying it sits at ``rho = r0 + s`` (P >= 0) or
``rho = r0 + stroke - s`` (P < 0), and the common normal there tilts by the pressure angle
``tan(alpha) = (ds/dtheta) / rho``, so the contact pushes the yoke sideways with
``|P| tan(alpha)``. The ball guide reacts the side force and the weight across the base;
its friction is ``f = mu (|N_r| + |N_g|)`` with ``N_r = |P| tan(alpha) + G_y`` and
``N_g = G cos(gamma)``. When every term is positive this is the seed's eq 1 with the
corrected denominator: ``f = mu ((m a - G_x) tan(alpha) + G_y + |G_z|) / (1 - mu tan(alpha))``.
The load torque on the shaft is ``M_l = P ds/dtheta`` (eq 3, virtual work) and the shaft
adds the Coulomb friction ``M_f``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from .geometry import Cam
from ...errors import SceneError


@dataclass(frozen=True)
class CamDrive:
    """DC motor on the cam shaft (seed 002), SI units.

    Parameters
    ----------
    cam : Cam
    rotor_inertia : float
        J_m (kg*m^2): rotor, encoder and cam.
    shaft_friction : float
        M_f (N*m), Coulomb.
    resistance, torque_constant, back_emf_constant : float
        R (ohm), c_m (N*m/A), c_e (V*s/rad).
    """

    cam: Cam
    rotor_inertia: float
    shaft_friction: float
    resistance: float
    torque_constant: float
    back_emf_constant: float

    @classmethod
    def from_scene(cls, scene) -> "CamDrive":
        """The cam drive of a scene whose drivetrain is a single cam stage."""
        cams = [s for s in scene.stages if isinstance(s, Cam)]
        if not cams or scene.motor is None:
            raise SceneError("drivetrain", "this scene has no motor-driven cam")
        if len(scene.stages) != 1:
            raise SceneError("drivetrain", "the cam-drive model needs the cam on the motor shaft "
                             "(a single [[drivetrain]] stage of kind 'cam')")
        m = scene.motor
        return cls(cams[0], m.rotor_inertia, m.coulomb_friction, m.resistance, m.torque_constant,
                   m.back_emf_constant)

    def without_follower(self) -> "CamDrive":
        """The same drive with the follower removed (m = 0, G = 0)."""
        return replace(self, cam=replace(self.cam, follower_mass=0.0, follower_weight=0.0))

    def law(self, theta):
        """Cam law jet: s (m), ds/dtheta (m/rad), d2s/dtheta2 (m/rad^2)."""
        return self.cam.map(theta)

    def inertia(self, theta) -> tuple[np.ndarray, np.ndarray]:
        """Equivalent inertia J = J_m + m (ds/dtheta)^2 (eq 4) and dJ/dtheta."""
        jet = self.law(theta)
        m = self.cam.follower_mass
        return self.rotor_inertia + m * jet.d1**2, 2 * m * jet.d1 * jet.d2

    def gravity(self, tilt=None, heading=None) -> tuple[float, float, float]:
        """Weight components (G_x, G_y, G_z) in N for a tilt gamma and heading beta (rad)."""
        c = self.cam
        g = c.follower_weight
        tilt = c.gravity_tilt if tilt is None else tilt
        heading = c.gravity_heading if heading is None else heading
        return (g * math.sin(tilt) * math.cos(heading), g * math.sin(tilt) * math.sin(heading),
                -g * math.cos(tilt))

    def pressure_tangent(self, theta, cam_force) -> np.ndarray:
        """tan(alpha) of the roller carrying ``cam_force`` (signed, see the module notes)."""
        jet = self.law(theta)
        r0 = self.cam.pitch_base_radius
        rho = np.where(np.asarray(cam_force) >= 0, r0 + jet.value, r0 + self.cam.stroke_length - jet.value)
        return jet.d1 / rho

    def follower_force(self, theta, velocity, acceleration, tilt=None, heading=None,
                       tol: float = 1e-13, max_iter: int = 60):
        """Cam force on the follower along X and the guide friction (N).

        The friction depends on the cam force through the side reaction; the fixed point is
        a contraction with factor ``mu tan(alpha)`` and is iterated to ``tol``.

        Returns
        -------
        force, friction : numpy.ndarray
            ``P`` (N, along X) and the friction magnitude ``f`` (N).
        """
        c = self.cam
        gx, gy, gz = self.gravity(tilt, heading)
        sigma = np.sign(velocity)
        frictionless = c.follower_mass * np.asarray(acceleration, dtype=float) - gx
        f = np.zeros_like(frictionless)
        for _ in range(max_iter):
            p = frictionless + sigma * f
            side = np.abs(p) * self.pressure_tangent(theta, p) + gy
            new = c.guide_friction_coefficient * (np.abs(side) + abs(gz))
            done = np.max(np.abs(new - f), initial=0.0) <= tol * (1.0 + np.max(np.abs(new), initial=0.0))
            f = new
            if done:
                break
        return frictionless + sigma * f, f

    def load_torque(self, theta, velocity, acceleration, tilt=None, heading=None) -> np.ndarray:
        """Follower load torque on the shaft M_l = P ds/dtheta (eq 3), N*m."""
        p, _ = self.follower_force(theta, velocity, acceleration, tilt, heading)
        return p * self.law(theta).d1


def clearance_hysteresis(s_in, c: float, s0: float | None = None) -> np.ndarray:
    """Follower travel through a play of half-width ``c`` (seed 002, eqs 6-8).

    Parameters
    ----------
    s_in : array_like
        Travel without clearance, sampled in time.
    c : float
        Half the play (m).
    s0 : float, optional
        Initial output; defaults to ``s_in[0]``.

    Returns
    -------
    numpy.ndarray
        The follower travel s_o (the play operator of ``s_in``).
    """
    s_in = np.asarray(s_in, dtype=float)
    out = np.empty_like(s_in)
    prev_in = s_in[0]
    prev_out = s_in[0] if s0 is None else s0
    for k, s in enumerate(s_in):
        out[k] = prev_out = clearance_step(s, prev_in, prev_out, c)
        prev_in = s
    return out


def clearance_step(s_in: float, prev_in: float, prev_out: float, c: float) -> float:
    """One step of eqs 6-8."""
    if s_in > prev_in and s_in > prev_out + c:
        return s_in - c
    if s_in < prev_in and s_in < prev_out - c:
        return s_in + c
    return prev_out
