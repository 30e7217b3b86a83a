"""Compiled scalar kernels of the cam drive (C, ``servo_toolkit/_physics/cam.h``), for the
time-stepping loops, and their flat parameter array.

They evaluate exactly the physics of :mod:`servo_toolkit.components.cam.drive` (the tests check
the kernels against the vectorized component law and :meth:`CamDrive.follower_force`).
``p`` is the flat parameter array built by :func:`pack`:

    [A, m, mu, G_x, G_y, |G_z|, r0, stroke, J_m, M_f, R, c_m, c_e, clearance]
"""

from __future__ import annotations

import numpy as np

# the cam drive's kernels, compiled (servo_toolkit/_physics/cam.h): the profile's law (s, s', s''
# at an angle), the guide's friction (seed 002 eq 1), one speed step, the paper's discrete
# scheme over n steps, the cam shaft's acceleration with the follower's load (eqs 1, 3) and the
# continuous right-hand side
from ..._physics._kernels import (cam_discrete as discrete, cam_friction as friction, cam_law as law,  # noqa: F401
                                  cam_rhs as rhs, cam_shaft_acceleration as shaft_acceleration,
                                  cam_speed_step as speed_step)


def pack(drive) -> np.ndarray:
    """Flat parameter array of a :class:`CamDrive`."""
    c = drive.cam
    gx, gy, gz = drive.gravity()
    return np.array([c.profile_constant, c.follower_mass, c.guide_friction_coefficient, gx, gy, abs(gz),
                     c.pitch_base_radius, c.stroke_length, drive.rotor_inertia, drive.shaft_friction,
                     drive.resistance, drive.torque_constant, drive.back_emf_constant, c.clearance])


def pack_cam(cam) -> np.ndarray:
    """:func:`pack` array of a bare :class:`~servo_toolkit.components.cam.geometry.Cam` stage (the
    motor entries zero), for :func:`shaft_acceleration` inside another model's kernel."""
    from .drive import CamDrive
    return pack(CamDrive(cam, 0.0, 0.0, 1.0, 1.0, 0.0))

