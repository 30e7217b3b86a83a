"""The cam drive's constant-speed study (seed 002, section 4.1): equivalent inertia and
shaft torque over one turn, with gravity at several tilts and the follower clearance."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...components.cam.drive import CamDrive, clearance_hysteresis
from ...errors import SceneError


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
