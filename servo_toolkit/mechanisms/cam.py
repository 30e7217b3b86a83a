"""Cam drive of seed 002: follower load, equivalent inertia, clearance, constant-speed study.

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

from ..components.cam import Cam
from ..errors import SceneError


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


@dataclass(frozen=True)
class CamSweepResult:
    """Inertia and shaft torque over one cam turn at constant speed (seed 002, section 4.1).

    Attributes
    ----------
    theta : numpy.ndarray
        Cam angle (rad).
    speed : float
        Cam speed (rad/s).
    inertia : numpy.ndarray
        J(theta) (kg*m^2).
    tilts, headings : numpy.ndarray
        gamma and beta of each case (rad).
    torque : numpy.ndarray
        Total shaft torque M_f + M_l per case, shape (n_cases, n_theta) (N*m).
    inertial, gravity, friction : numpy.ndarray
        Parts of M_l per case: m a s', -G_x s', sign(v) f s' (N*m).
    pressure_angle : numpy.ndarray
        Pressure angle of the roller in contact, first case (rad).
    travel : numpy.ndarray, optional
        Follower travel s_o (m): the cam law's s, or with clearance its play operator
        (eqs 6-8), which lags the law by c after every reversal.
    clearance : float
        Half the cam/roller play c (m).
    """

    theta: np.ndarray
    speed: float
    inertia: np.ndarray
    tilts: np.ndarray
    headings: np.ndarray
    torque: np.ndarray
    inertial: np.ndarray
    gravity: np.ndarray
    friction: np.ndarray
    pressure_angle: np.ndarray
    travel: np.ndarray | None = None
    clearance: float = 0.0

    def to_dict(self) -> dict:
        """JSON-ready dictionary."""
        return {
            "study": "constant_speed", "speed_rad_s": self.speed,
            "theta_deg": np.degrees(self.theta).tolist(),
            "inertia_kg_m2": self.inertia.tolist(),
            "inertia_min_kg_m2": float(self.inertia.min()), "inertia_max_kg_m2": float(self.inertia.max()),
            "cases": [{"gravity_tilt_deg": math.degrees(g), "gravity_heading_deg": math.degrees(b),
                       "torque_Nm": t.tolist(), "torque_min_Nm": float(t.min()),
                       "torque_max_Nm": float(t.max())}
                      for g, b, t in zip(self.tilts, self.headings, self.torque)],
            "max_pressure_angle_deg": float(np.degrees(np.abs(self.pressure_angle)).max()),
            "clearance_m": self.clearance,
            **({"travel_m": self.travel.tolist()} if self.travel is not None else {}),
        }

    def table(self) -> str:
        """Plain-text summary."""
        lines = [f"cam at {self.speed:g} rad/s, {self.theta.size} samples over one turn",
                 f"equivalent inertia J: {self.inertia.min():.4g} .. {self.inertia.max():.4g} kg*m^2 "
                 f"({self.inertia.max() / self.inertia.min():.1f}x)",
                 f"max pressure angle: {np.degrees(np.abs(self.pressure_angle)).max():.2f} deg",
                 *([f"clearance c = {self.clearance * 1e3:.4g} mm: follower travel through eqs 6-8, "
                    "v and a by backward differences"] if self.clearance > 0 else []),
                 f"{'tilt [deg]':>10s} {'heading [deg]':>14s} {'M min [N*m]':>12s} {'M max [N*m]':>12s} "
                 f"{'ripple [N*m]':>13s}"]
        for g, b, t in zip(self.tilts, self.headings, self.torque):
            lines.append(f"{math.degrees(g):10.1f} {math.degrees(b):14.1f} {t.min():12.5f} {t.max():12.5f} "
                         f"{t.max() - t.min():13.5f}")
        return "\n".join(lines)

    def plot(self, ax=None):
        """Inertia and torque over the turn (two axes); returns the axes."""
        import matplotlib.pyplot as plt
        if ax is None:
            _, ax = plt.subplots(1, 2, figsize=(10, 3.5))
        deg = np.degrees(self.theta)
        ax[0].plot(deg, self.inertia * 1e3)
        ax[0].set_xlabel("cam angle [deg]")
        ax[0].set_ylabel("J [g*m^2]")
        ax[0].set_title("Equivalent inertia (eq 4)")
        for g, b, t in zip(self.tilts, self.headings, self.torque):
            ax[1].plot(deg, t, label=f"gamma {math.degrees(g):.0f} deg, beta {math.degrees(b):.0f} deg")
        ax[1].set_xlabel("cam angle [deg]")
        ax[1].set_ylabel("shaft torque [N*m]")
        ax[1].set_title("Load torque M_f + M_l")
        ax[1].legend(fontsize="small")
        return ax


def constant_speed(drive: CamDrive, speed: float = 1.0, sample_time: float = 0.01, tilts=(0.0,),
                   headings=None) -> CamSweepResult:
    """J(theta) and the shaft torque over one turn at constant speed.

    Without clearance the follower velocity and acceleration are exact (``v = s' w``,
    ``a = s'' w^2``); with clearance the travel goes through eqs 6-8 and v, a are backward
    differences at ``sample_time``, as in the seed.
    """
    if not speed > 0:
        raise SceneError("studies.constant_speed.speed", f"must be positive (got {speed})")
    n = max(int(round(2 * math.pi / (speed * sample_time))), 8)
    t = np.arange(n + 1) * sample_time
    theta = speed * t
    jet = drive.law(theta)
    if drive.cam.clearance > 0:
        s = clearance_hysteresis(jet.value, drive.cam.clearance)
        v = np.concatenate([[0.0], np.diff(s) / sample_time])
        a = np.concatenate([[0.0], np.diff(v) / sample_time])
    else:
        s = jet.value
        v, a = jet.d1 * speed, jet.d2 * speed**2
    tilts = np.atleast_1d(np.asarray(tilts, dtype=float))
    headings = (np.full_like(tilts, drive.cam.gravity_heading) if headings is None
                else np.broadcast_to(np.asarray(headings, dtype=float), tilts.shape))
    m = drive.cam.follower_mass
    torque, inertial, grav, fric = [], [], [], []
    for g, b in zip(tilts, headings):
        p, f = drive.follower_force(theta, v, a, g, b)
        gx = drive.gravity(g, b)[0]
        inertial.append(m * a * jet.d1)
        grav.append(-gx * jet.d1)
        fric.append(np.sign(v) * f * jet.d1)
        torque.append(drive.shaft_friction * np.sign(speed) + p * jet.d1)
    p0, _ = drive.follower_force(theta, v, a, tilts[0], headings[0])
    return CamSweepResult(theta, speed, drive.inertia(theta)[0], tilts, np.asarray(headings), np.array(torque),
                          np.array(inertial), np.array(grav), np.array(fric),
                          np.arctan(drive.pressure_tangent(theta, p0)), s, drive.cam.clearance)
