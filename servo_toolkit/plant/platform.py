"""The crossed-arch deflection platform (seed 003) as a linear MIMO plant.

Lagrange's equations of :mod:`.platform` with the motor torques as inputs read

    M(q) q'' + h(q, q') = J(q)' tau - M_load,

where ``J = d(theta1, theta2)/d(alpha, beta)`` (eq 5 differentiated), ``M`` the generalized
mass matrix (eq 14) and ``h`` the velocity-product terms (quadratic in q'). Linearized at
rest at ``q0 = (alpha0, beta0)`` the velocity terms vanish, and the model holds no gravity
(the seed gives no platform mass or centre of mass), so there is no stiffness: each axis is
a double integrator coupled through ``M(q0)^-1 J(q0)'``,

    x = (alpha, beta, alpha_dot, beta_dot) - (alpha0, beta0, 0, 0),
    x' = [[0, I], [0, 0]] x + [[0], [M^-1 J']] tau,
    (alpha, beta, theta1, theta2) = [[I, 0], [J, 0]] x   (deviations from the operating point).

At ``alpha0 = 0`` or ``beta0 = 0`` J is diagonal and (with the platform's product of inertia
zero) so is M: the axes decouple. Elsewhere motor 2 also accelerates alpha and motor 1 beta,
through the platform inertia seen from the small arch.
"""

from __future__ import annotations

import numpy as np

from ..components.platform.model import PlatformModel
from ..lti.system import ss

#: Signals of :func:`platform_plant` and their SI units (all deviations from q0).
PLATFORM_PLANT_UNITS = {
    "tau1": "N*m", "tau2": "N*m", "Mx": "N*m", "My": "N*m",
    "alpha": "rad", "beta": "rad", "alpha_dot": "rad/s", "beta_dot": "rad/s",
    "theta1": "rad", "theta2": "rad",
}


def platform_plant(scene, q0=(0.0, 0.0), loads: bool = False, name: str = "platform") -> "control.StateSpace":
    """Linear plant of the deflection platform at rest at ``q0``, motor torques in.

    Parameters
    ----------
    scene : Scene or PlatformModel
        A scene with ``[mechanism] kind = "crossed_arch_platform"`` (or its model).
    q0 : tuple of float
        Operating point (alpha0, beta0) in rad; |beta0| < pi/2.
    loads : bool
        Also take the external load moments ``Mx``, ``My`` (N*m, resisting positive alpha,
        beta) as inputs 3 and 4.
    name : str
        System name for ``control.interconnect``.

    Returns
    -------
    control.StateSpace
        Inputs ``tau1``, ``tau2`` (motor torques, N*m) [, ``Mx``, ``My``]; states ``alpha``,
        ``beta`` (rad), ``alpha_dot``, ``beta_dot`` (rad/s); outputs ``alpha``, ``beta``,
        ``theta1``, ``theta2`` (rad). States and outputs are deviations from q0 and from the
        motor angles there (``PLATFORM_PLANT_UNITS`` lists the units).

    Raises
    ------
    SceneError
        When the scene has no crossed-arch platform.
    ValueError
        When q0 is not two finite angles with |beta0| < pi/2.
    """
    model = scene if isinstance(scene, PlatformModel) else PlatformModel.from_scene(scene)
    q0 = np.asarray(q0, dtype=float)
    if q0.shape != (2,) or not np.all(np.isfinite(q0)) or not abs(q0[1]) < np.pi / 2:
        raise ValueError(f"q0 must be (alpha0, beta0) in rad with |beta0| < pi/2 (got {q0.tolist()})")
    m, jac = matrices(model, q0)
    gain = np.linalg.solve(m, jac.T)                 # q'' per unit motor torque
    zero, eye = np.zeros((2, 2)), np.eye(2)
    a = np.block([[zero, eye], [zero, zero]])
    b = np.vstack([zero, gain])
    inputs = ["tau1", "tau2"]
    if loads:
        b = np.hstack([b, np.vstack([zero, -np.linalg.inv(m)])])
        inputs += ["Mx", "My"]
    c = np.block([[eye, zero], [jac, zero]])
    return ss(a, b, c, np.zeros((4, len(inputs))), inputs=inputs, outputs=["alpha", "beta", "theta1", "theta2"],
              states=["alpha", "beta", "alpha_dot", "beta_dot"], name=name).to_control()


def matrices(model: PlatformModel, q0) -> tuple[np.ndarray, np.ndarray]:
    """``M(q0)`` (kg*m^2) and ``J(q0)`` (rad/rad) of the platform, each 2x2."""
    alpha, beta = float(q0[0]), float(q0[1])
    return np.asarray(model.mass_matrix(alpha, beta), dtype=float), \
        np.asarray(model.jacobian(alpha, beta), dtype=float)


__all__ = ["platform_plant", "matrices", "PLATFORM_PLANT_UNITS"]
