"""The closed loop's right-hand side and the controller's sample, compiled (C99).

One physics, used by every integrator (fixed-step RK4, the cam paper's scheme, scipy's
``solve_ivp``, python-control and the Jacobian estimate): :func:`rhs` and
:func:`controller_sample`. Layout of ``x`` and ``P`` in :mod:`servo_toolkit.sim.layout`; the
sources, one header per concern with their equations, in ``servo_toolkit/_physics``:

==================  ================================================================
``rhs.h``           the right-hand side: armature and current loop, the motor's and
                    the load's friction, rigid, two-mass, full-chain and cam models
``compliance.h``    the elasto-backlash contact, the drivetrain's loss, the full chain
``friction.h``      friction that holds: the Stribeck sliding law, the stick law
``control.h``       encoders, speed estimators, the motion controller and its sample
``command.h``       the commands (sine, step, ramp, sampled, jerk-limited), shaper,
                    gain schedule
``feedforward.h``   the reference's derivatives and the chain's inverse dynamics
``cam.h``           the cam drive of seed 002 (its law, guide friction, schemes)
``integrate.h``     fixed-step RK4 with located friction switches, the paper's scheme
``vmath.h``         the friction's smooth sign (tanh within 1 ulp of the C library's)
==================  ================================================================

Equations (generalized coordinates p, q at the output; N(p) motor rad per output rad)::

    J_d(p) p'' + J_d'(p) p'^2 / 2 = N(p) tau_m - f - K'(p) z^2 / 2
    J_L q''                       = f + M_hinge(q, q') + M_stop(q, q')
    tau_m = Kt i - b omega_m - Tc tanh(omega_m / w_s),   omega_m = N(p) p'
    L i' = v - R i - Ke omega_m                          (or i = (v - Ke omega_m) / R, L = 0)

with Modelica's ``ElastoBacklash`` contact law between p and q (``rhs.h`` states it in full,
with the cam's follower load, the drivetrain's loss and the full chain's nodes).

Every function here is the compiled one; arrays are float64 and C-contiguous, the tables a
2-D array ``(rows, n)`` (:func:`servo_toolkit.sim.tables.frozen_tables`).
"""

from __future__ import annotations

from .._physics._kernels import (TANH_ONE, TANH_SMALL, command, contact, continuous_command,  # noqa: F401
                                 controller_sample, controller_update, exp_neg, exp_pos, feedforward, gear_at_rest,
                                 hermite, measured_angle, measured_motor_angle, motion, motor_angle, reference, rhs,
                                 rhs_phys, schedule_factors, slip_friction, speed_sign, stuck_or_breaking, tanh)

__all__ = ["TANH_ONE", "TANH_SMALL", "command", "contact", "continuous_command", "controller_sample",
           "controller_update", "exp_neg", "exp_pos", "feedforward", "gear_at_rest", "hermite", "measured_angle",
           "measured_motor_angle", "motion", "motor_angle", "reference", "rhs", "rhs_phys", "schedule_factors",
           "slip_friction", "speed_sign", "stuck_or_breaking", "tanh"]
