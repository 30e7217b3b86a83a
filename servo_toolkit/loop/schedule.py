"""Gains scheduled along the stroke: the loop's crossover and margins kept as designed at q0.

A linkage changes the ratio N(q) and the reflected inertia J(q) along the stroke, so a loop
designed at q0 sees another plant elsewhere (:mod:`.stroke`). In the cascade
``i_ref = Cv (Cp (theta_ref - theta) - omega_m / N0)`` the speed loop's gain is
``Cv N(q) Kt / (N0 J(q) s) = Cv Kt / (N0 J_m(q) s)`` (J_m = J / N^2 the inertia reflected to
the motor) and the position loop's, around the closed speed loop, ``Cp N0 / (N(q) s)``. Scaling
the speed gains by ``J_m(q) / J_m(q0)`` and the position gain by ``N(q) / N(q0)`` keeps both
loops' gains, and so their crossovers and margins, at their q0 values on the rigid-body part of
the plant. A gain scale is applied to the controller's inputs (the integrator sums the scaled
error, so a change of the factor never steps the output)::

    g_w(q) = J_m(q) / J_m(q0)                        on omega_m (the speed loop)
    g_e(q) = g_w(q) N(q) / N(q0) = (J(q) / N(q)) / (J(q0) / N(q0))
                                                     on theta_ref and theta

For a single compensator on the position error (pid, lead-lag, pi), whose loop gain is
``C Kt / (N J_m s^2)``, the same ``g_e`` keeps it. The schedule is a table over the stroke,
linear between its points and held beyond its ends: the table the drive interpolates at its
measured output position once per sample (the simulation interpolates the same table,
:func:`servo_toolkit.sim.kernel.schedule_factors`). What it does not keep: the
drivetrain mode's own walk along the stroke (stiffness K(q) and the load-to-motor split), so
the margins it leaves are the mode's; :func:`~.stroke.stroke_check` shows the spread with and
without it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..errors import SceneError
from ..lti.system import ss

#: points of the schedule table over the stroke (ends included)
SCHEDULE_POINTS = 17


@dataclass(frozen=True)
class GainSchedule:
    """The gain factors along the stroke.

    Attributes
    ----------
    q : tuple of float
        Evenly spaced points (rad, or m for an output travel), ends of the stroke included.
    error_factor : tuple of float
        ``g_e``: the factor on the position-error inputs (theta_ref, theta) at each point.
    speed_factor : tuple of float
        ``g_w``: the factor on the motor-speed input at each point.
    q0 : float
        The design's operating point (both factors 1 there).
    ratio : tuple of float
        N(q) at the points (motor rad per output rad or m).
    motor_inertia : tuple of float
        J(q) / N(q)^2 at the points (kg*m^2).
    output_unit : {"rad", "m"}
    """

    q: tuple
    error_factor: tuple
    speed_factor: tuple
    q0: float
    ratio: tuple = ()
    motor_inertia: tuple = ()
    output_unit: str = "rad"

    def __post_init__(self):
        n = len(self.q)
        if n < 2 or len(self.error_factor) != n or len(self.speed_factor) != n:
            raise SceneError("schedule", f"needs at least 2 points with one factor of each kind per point (got {n})")
        vals = np.array([self.q, self.error_factor, self.speed_factor], float)
        if not np.all(np.isfinite(vals)) or np.any(vals[1:] <= 0):
            raise SceneError("schedule", "points must be finite and factors positive and finite")
        steps = np.diff(vals[0])
        if np.any(steps <= 0) or np.ptp(steps) > 1e-9 * abs(steps[0]):
            raise SceneError("schedule", "points must be evenly spaced and increasing")

    @property
    def points(self) -> int:
        return len(self.q)

    def factors(self, q):
        """``(g_e, g_w)`` at ``q`` (arrays): linear between the points, the end values held
        beyond them (what the kernel and the drive compute)."""
        q = np.asarray(q, float)
        return np.interp(q, self.q, self.error_factor), np.interp(q, self.q, self.speed_factor)

    def block(self) -> np.ndarray:
        """The kernel's block: [points, first point, 1 / step, g_e..., g_w...]."""
        h = (self.q[-1] - self.q[0]) / (self.points - 1)
        return np.concatenate([[self.points, self.q[0], 1.0 / h], self.error_factor, self.speed_factor])

    def scaled(self, controller, q: float):
        """The controller with its motion controller's inputs scaled by the factors at ``q``
        (frozen there: the linear loop at that operating point); no schedule on it."""
        ge, gw = (float(f) for f in self.factors(q))
        m = controller.motion_block
        scale = np.diag([ge, ge, gw])
        motion = ss(m.A, m.B @ scale, m.C, m.D @ scale, inputs=m.inputs, outputs=m.outputs, states=m.states,
                    name=m.name)
        return replace(controller, motion=motion, schedule=None)

    def describe(self) -> str:
        """One line."""
        ge, gw = np.array(self.error_factor), np.array(self.speed_factor)
        return (f"gain schedule over {self.points} stroke points: position-error factor {ge.min():.3g}..{ge.max():.3g}, "
                f"speed factor {gw.min():.3g}..{gw.max():.3g} (1 at q0)")

    def to_dict(self) -> dict:
        """JSON-ready (SI positions)."""
        key = "q_m" if self.output_unit == "m" else "q_rad"
        return {"points": self.points, key: list(map(float, self.q)), "q0": float(self.q0),
                "error_factor": list(map(float, self.error_factor)),
                "speed_factor": list(map(float, self.speed_factor)), "ratio": list(map(float, self.ratio)),
                "motor_inertia_kg_m2": list(map(float, self.motor_inertia)), "interpolation": "linear, ends held",
                "output_unit": self.output_unit}

    @classmethod
    def from_dict(cls, data: dict) -> "GainSchedule":
        """Inverse of :meth:`to_dict` (fields checked by the constructor)."""
        key = "q_m" if data.get("output_unit") == "m" else "q_rad"
        return cls(tuple(map(float, data[key])), tuple(map(float, data["error_factor"])),
                   tuple(map(float, data["speed_factor"])), float(data["q0"]),
                   tuple(map(float, data.get("ratio", ()))), tuple(map(float, data.get("motor_inertia_kg_m2", ()))),
                   "m" if data.get("output_unit") == "m" else "rad")


def gain_schedule(scene, q0: float | None = None, points: int = SCHEDULE_POINTS) -> GainSchedule:
    """The gain schedule of ``scene`` about the operating point ``q0`` (default: the
    design's, :func:`~.stroke.operating_point`), over ``points`` points of the stroke.

    Raises
    ------
    SceneError
        ``schedule_points`` below 2; a ratio or inertia that is not positive and finite.
    """
    from ..drivetrain.operating_point import operating_point
    if int(points) != points or points < 2:
        raise SceneError("schedule_points", f"must be an integer of at least 2 (got {points!r})")
    drive = scene.drivetrain
    q0, _ = operating_point(scene, q0)
    lo, hi = drive.stroke
    q = np.linspace(lo, hi, int(points))
    n = np.abs(drive.ratio(np.append(q, q0))[0])
    j = drive.inertia(np.append(q, q0))[0]
    if not (np.all(np.isfinite(n)) and np.all(n > 0) and np.all(np.isfinite(j)) and np.all(j > 0)):
        raise SceneError("drivetrain", "the gain schedule needs a positive, finite ratio and inertia along the stroke")
    jm = j / n**2
    gw = jm[:-1] / jm[-1]
    ge = (j[:-1] / n[:-1]) / (j[-1] / n[-1])
    return GainSchedule(tuple(q), tuple(ge), tuple(gw), float(q0), tuple(n[:-1]), tuple(jm[:-1]), drive.output_unit)


def crossover_hz(w, L) -> np.ndarray:
    """The gain crossover (Hz) of loop responses ``L`` (..., len(w)) on angular frequencies
    ``w``: the first fall of |L| through 1, log-interpolated; ``nan`` without one."""
    mag = np.log(np.abs(np.asarray(L, complex)))
    down = (mag[..., :-1] >= 0) & (mag[..., 1:] < 0)
    k = np.argmax(down, axis=-1)
    a = np.take_along_axis(mag, k[..., None], -1)[..., 0]
    b = np.take_along_axis(mag, (k + 1)[..., None], -1)[..., 0]
    lw = np.log(w)
    with np.errstate(divide="ignore", invalid="ignore"):
        f = np.clip(a / (a - b), 0.0, 1.0)
    out = np.exp(lw[k] + f * (lw[k + 1] - lw[k])) / (2 * math.pi)
    return np.where(down.any(axis=-1), out, np.nan)


__all__ = ["GainSchedule", "SCHEDULE_POINTS", "crossover_hz", "gain_schedule"]
