"""Crossed-arch deflection platform of seed 003: kinematics, Lagrange dynamics (its ramp
study is :mod:`servo_toolkit.studies.mechanisms.platform`).

Generalized coordinates q = (alpha, beta): platform tilts about X and Y. Motor angles
(eq 5): ``theta1 = rx alpha``, ``theta2 = ry atan(tan(beta) / cos(alpha))`` with
``rx = z4/z3``, ``ry = z2/z1``. The Jacobian is the *correct* derivative of eq 5 (the seed's
eq 7 has misprinted cos^2 and cos^3 factors).

Kinetic energy (eq 14) is ``T = 1/2 I1 theta1'^2 + 1/2 I2 theta2'^2 + 1/2 q' I9 q'`` with the
inertias reflected to the motor shafts ``I1 = 2 A = (z3/z4)^2 (I4 + 2 I8 + 2 I11 + I12) + I16``
and ``I2 = 2 B = (z1/z2)^2 (I5 + I7 + 2 I11o) + I15``. (Like the seed, the platform's own
term uses (alpha', beta') as its angular velocity.) Lagrange's equations then read

    Q = M(q) q'' + h(q, q'),  M = I9 + I1 J1' J1 + I2 J2' J2,  h = I2 J2' (q'' H2 q'),

with J_k the rows of the Jacobian and H2 the Hessian of theta2(q) (theta1 is linear).

External moments: ``external_moments`` (Mx, My) are *load* moments the platform has to
overcome (a positive Mx resists a positive alpha). By virtual work
``J' tau = Q + M_load``, so ``tau = J^-T (Q + M_load)``; the power balance is
``tau . theta' = dT/dt + M_load . q'``. The seed's tables instead scale the moment up by the
ratio (M1 = 6.36 Mx) and are not used as a check.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .geometry import CrossedArchPlatform
from ...errors import SceneError


@dataclass(frozen=True)
class PlatformModel:
    """Kinematics and dynamics of a :class:`CrossedArchPlatform` (vectorized over q)."""

    platform: CrossedArchPlatform

    @classmethod
    def from_scene(cls, scene) -> "PlatformModel":
        """The platform model of a scene with ``[mechanism] kind = "crossed_arch_platform"``."""
        if not isinstance(scene.mechanism, CrossedArchPlatform):
            raise SceneError("mechanism", "this scene has no crossed-arch platform")
        return cls(scene.mechanism)

    @property
    def motor_inertias(self) -> tuple[float, float]:
        """I1 = 2A and I2 = 2B (kg*m^2), the part inertias reflected to the motor shafts."""
        p, i = self.platform, self.platform.inertias
        i1 = (i["inertia_large_arch"] + 2 * i["inertia_pin_8"] + 2 * i["inertia_pin_11_spin"]
              + i["inertia_large_guide"]) / p.ratio_x**2 + i["inertia_pinion_16"]
        i2 = (i["inertia_small_arch"] + i["inertia_small_guide"] + 2 * i["inertia_pin_11_about_o"]) / p.ratio_y**2 \
            + i["inertia_pinion_15"]
        return i1, i2

    def inverse(self, alpha, beta) -> np.ndarray:
        """Motor angles (theta1, theta2) of eq 5, shape (2, ...)."""
        alpha, beta = np.asarray(alpha, dtype=float), np.asarray(beta, dtype=float)
        return np.array([self.platform.ratio_x * alpha,
                         self.platform.ratio_y * np.arctan2(np.tan(beta), np.cos(alpha))])

    def jacobian(self, alpha, beta) -> np.ndarray:
        """d(theta)/dq, shape (2, 2, ...): the correct derivative of eq 5."""
        alpha, beta = np.asarray(alpha, dtype=float), np.asarray(beta, dtype=float)
        ry = self.platform.ratio_y
        c, t = np.cos(alpha), np.tan(beta)
        d = c**2 + t**2
        zero = np.zeros(np.broadcast(alpha, beta).shape)
        return np.array([[self.platform.ratio_x + zero, zero],
                         [ry * np.sin(alpha) * t / d, ry * c / (np.cos(beta) ** 2 * d)]])

    def hessian2(self, alpha, beta) -> np.ndarray:
        """Hessian of theta2(alpha, beta), shape (2, 2, ...)."""
        alpha, beta = np.asarray(alpha, dtype=float), np.asarray(beta, dtype=float)
        ry = self.platform.ratio_y
        c, s, t = np.cos(alpha), np.sin(alpha), np.tan(beta)
        sec2 = 1.0 / np.cos(beta) ** 2
        d = c**2 + t**2
        # J21 = ry s t / d, J22 = ry c sec2 / d; d_alpha d = -2 c s, d_beta d = 2 t sec2
        j21_a = ry * t * (c * d + 2 * s**2 * c) / d**2
        j21_b = ry * s * sec2 * (d - 2 * t**2) / d**2
        j22_b = ry * c * sec2 * (2 * t * d - 2 * t * sec2) / d**2
        return np.array([[j21_a, j21_b], [j21_b, j22_b]])

    def mass_matrix(self, alpha, beta) -> np.ndarray:
        """Generalized mass matrix M(q) (kg*m^2), shape (2, 2, ...)."""
        i1, i2 = self.motor_inertias
        jac = self.jacobian(alpha, beta)
        i9 = self.platform.platform_inertia.reshape((2, 2) + (1,) * (jac.ndim - 2))
        return (i9 + i1 * jac[0][:, None] * jac[0][None, :] + i2 * jac[1][:, None] * jac[1][None, :])

    def coriolis(self, alpha, beta, rate_alpha, rate_beta) -> np.ndarray:
        """Velocity-product terms h(q, q') of Lagrange's equations (N*m), shape (2, ...)."""
        _, i2 = self.motor_inertias
        jac = self.jacobian(alpha, beta)
        h = self.hessian2(alpha, beta)
        qd = np.array([np.asarray(rate_alpha, dtype=float), np.asarray(rate_beta, dtype=float)])
        quad = np.einsum("i...,ij...,j...->...", qd, h, qd)
        return i2 * jac[1] * quad

    def kinetic_energy(self, alpha, beta, rate_alpha, rate_beta) -> np.ndarray:
        """T(q, q') of eq 14 (J)."""
        qd = np.array([np.asarray(rate_alpha, dtype=float), np.asarray(rate_beta, dtype=float)])
        return 0.5 * np.einsum("i...,ij...,j...->...", qd, self.mass_matrix(alpha, beta), qd)

    def generalized_forces(self, q, qd, qdd) -> np.ndarray:
        """Q = M q'' + h (N*m) for arrays of shape (2, n)."""
        m = self.mass_matrix(q[0], q[1])
        return np.einsum("ij...,j...->i...", m, qdd) + self.coriolis(q[0], q[1], qd[0], qd[1])

    def motor_torques(self, q, qd, qdd, load_moments) -> np.ndarray:
        """tau = J^-T (Q + M_load) (N*m), shape (2, n); ``load_moments`` (Mx, My) broadcast."""
        jac = self.jacobian(q[0], q[1])
        rhs = self.generalized_forces(q, qd, qdd) + np.asarray(load_moments, dtype=float).reshape(2, -1)
        # J' tau = rhs with J lower triangular: tau2 = rhs2 / J22, tau1 = (rhs1 - J21 tau2) / J11
        tau2 = rhs[1] / jac[1, 1]
        tau1 = (rhs[0] - jac[1, 0] * tau2) / jac[0, 0]
        return np.array([tau1, tau2])
