"""Multi-stage planetary roller screw of seed 004: carrier dynamics (its studies are in
:mod:`servo_toolkit.studies.mechanisms.roller_screw`).

Reduced rigid-body model (stated, and checked by a power balance in the tests):

* Every screw turns at theta_S' (eq 1); nut k travels at sum(L_1..L_k) theta_S' / (2 pi)
  (eq 3, magnitude); rollers move axially with their nut (eq 7) and spin at
  -(n_S - 1) theta_P' (eq 8), rolling on the nut; so each stage has one dynamic degree of
  freedom, its carrier speed theta_P'.
* The screw/roller contact is taken at the pitch circles with zero offset angle. Its slip
  velocity (eq 13 with phi = 0) has a tangential part ``r_S theta_S' - 2 (r_S + r_R)
  theta_P'`` and an axial part ``L theta_S' / (2 pi)``. Friction on the roller follows the
  slip: Coulomb ``mu_RS F_RS slip/|slip|`` (eq 14) or viscous ``mu'_RS slip`` (eq 29).
* The normal force carries the nut load plus the axial friction: per roller
  ``F_RS / |n| = F_N / n + f_z`` with ``|n| / n_z`` of eq 9 at phi = 0.
* The tangential friction drives the carrier, ``J_P,eff theta_P'' = n f_t 2 (r_S + r_R)``,
  and resists the screw, ``M_thread = (F_N + n f_z) L / (2 pi) + n f_t r_S``.
* Stages are joined by the spline (eq 4) and the nut/screw thrust bearing (eq 5) and solved
  from the last stage back to the first; the axial load a screw passes to the previous nut
  is its nut load plus the spline friction (eq 21: the friction's reaction on the screw
  cancels the rise of the normal force). Efficiency is eq 32.

At steady state the tangential slip vanishes, the carrier turns at r_S / (2 (r_S + r_R))
of the screw speed, and the efficiency is
:func:`~servo_toolkit.components.roller_screw.stages.steady_efficiency` (eq 35 when only the
spline rubs). The seed's contact geometry (mesh radii and offset angles from its ref. [2])
is not printed, so its curves are matched in trend and order of magnitude, not in value.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from .stages import (bearing_friction, carrier_inertia_total, carrier_ratio, joint_loads,
                     nut_travel_per_screw_radian, roller_spin_ratio, spline_friction, steady_efficiency,
                     thread_normal_norm)
from ...errors import SceneError, SimulationError


@dataclass(frozen=True)
class RollerScrewModel:
    """The stages of a roller-screw scene with one set of friction coefficients.

    Parameters
    ----------
    stages : tuple of RollerScrewStage
    mu_rs : float
        Screw/roller friction: Coulomb coefficient, or N*s/m when ``viscous``.
    mu_ss, mu_ns : float
        Spline (eq 4) and thrust-bearing (eq 5) coefficients.
    viscous : bool
        Viscous screw/roller friction (eq 29) instead of Coulomb (eq 14).
    """

    stages: tuple
    mu_rs: float
    mu_ss: float = 0.0
    mu_ns: float = 0.0
    viscous: bool = False

    @classmethod
    def from_scene(cls, scene, mu_ss=None, mu_ns=None, stages=None, viscous_mu_rs=None) -> "RollerScrewModel":
        """Model of a roller-screw scene; the first listed mu_SS / mu_NS unless given."""
        if not scene.roller_screw:
            raise SceneError("stages", "this scene has no roller-screw [[stages]]")
        op = scene.operating
        st = scene.roller_screw if stages is None else scene.roller_screw[:stages]
        if viscous_mu_rs is not None:
            return cls(st, viscous_mu_rs, 0.0, 0.0, viscous=True)
        return cls(st, op.roller_screw_friction if op else 0.0,
                   (op.screw_screw_friction[0] if op else 0.0) if mu_ss is None else mu_ss,
                   (op.nut_screw_friction[0] if op else 0.0) if mu_ns is None else mu_ns)

    # --- kinematics (eqs 1, 3, 8) ---
    def nut_speeds(self, screw_speed: float) -> np.ndarray:
        """v_Nk of eq 3 (m/s, signed: right-hand threads, nut moves towards -Z)."""
        return -screw_speed * nut_travel_per_screw_radian(self.stages)

    def roller_spins(self, carrier_speeds) -> np.ndarray:
        """theta_Rk' of eq 8 (rad/s)."""
        return np.array([roller_spin_ratio(s) for s in self.stages]) * np.asarray(carrier_speeds)

    @property
    def steady_carrier_ratios(self) -> np.ndarray:
        """zeta_PSk at steady state (pure rolling)."""
        return np.array([carrier_ratio(s) for s in self.stages])

    def reflected_inertia(self) -> float:
        """Inertia of every moving part reflected to the first screw at steady carriers (kg*m^2)."""
        lam = nut_travel_per_screw_radian(self.stages)
        total = 0.0
        for k, s in enumerate(self.stages):
            total += s.screw_inertia + carrier_ratio(s) ** 2 * carrier_inertia_total(s)
            total += (s.nut_mass + s.rollers * s.roller_mass) * lam[k] ** 2
            if k > 0:
                total += s.screw_mass * lam[k - 1] ** 2
        return total

    # --- joint friction (eqs 4, 5) ---
    def spline_friction(self, k: int, screw_torque: float, screw_axial_speed: float) -> float:
        """f_Sk of eq 4 (N) on screw k (0-based, k >= 1); :meth:`forces` uses it."""
        return spline_friction(self.mu_ss, screw_torque, self.stages[k].screw_spline_radius, screw_axial_speed)

    def bearing_friction(self, k: int, nut_load: float, screw_speed: float) -> float:
        """M_N of eq 5 (N*m): thrust bearing between nut k-1 and screw k (0-based, k >= 1);
        :meth:`forces` uses it."""
        return bearing_friction(self.mu_ns, nut_load, self.stages[k].nut_screw_joint_radius, screw_speed)

    # --- contact forces for given carrier speeds ---
    def _contact(self, k: int, screw_speed: float, carrier_speed: float, nut_load: float):
        """(axial friction n f_z, thread torque, carrier drive n f_t 2 (r_S + r_R), dissipation)."""
        s = self.stages[k]
        slip_t = s.screw_radius * screw_speed - 2 * (s.screw_radius + s.roller_radius) * carrier_speed
        slip_z = s.lead * screw_speed / (2 * math.pi)
        if self.viscous:
            ft, fz = self.mu_rs * slip_t, self.mu_rs * slip_z
        else:
            mag = math.hypot(slip_t, slip_z)
            if mag == 0:
                return 0.0, nut_load * s.lead / (2 * math.pi), 0.0, 0.0
            normal = (nut_load / s.rollers) / (1.0 / thread_normal_norm(s) - self.mu_rs * slip_z / mag)
            ft, fz = self.mu_rs * normal * slip_t / mag, self.mu_rs * normal * slip_z / mag
        n = s.rollers
        torque = (nut_load + n * fz) * s.lead / (2 * math.pi) + n * ft * s.screw_radius
        drive = n * ft * 2 * (s.screw_radius + s.roller_radius)
        return n * fz, torque, drive, n * (ft * slip_t + fz * slip_z)

    def forces(self, screw_speed: float, carrier_speeds, load: float) -> dict:
        """Screw torque, nut loads, carrier drive torques and losses at one instant."""
        drives, losses = [0.0] * len(self.stages), [0.0] * len(self.stages)

        def thread(k, nut_load):
            _, torque, drive, loss = self._contact(k, screw_speed, carrier_speeds[k], nut_load)
            drives[k], losses[k] = drive, loss
            return torque
        nut_speeds = self.nut_speeds(screw_speed)  # screw k rides on nut k - 1: v_Sk = v_N(k-1) (eq 2)
        torque, nut_loads = joint_loads(
            self.stages, load, thread, [], self.mu_ss, self.mu_ns,
            spline=lambda k, m_s: self.spline_friction(k, m_s, nut_speeds[k - 1]),
            bearing=lambda k, f_n: self.bearing_friction(k, f_n, screw_speed))
        return {"screw_torque": torque, "nut_loads": np.array(nut_loads), "carrier_drive": np.array(drives),
                "contact_loss": np.array(losses)}

    def efficiency(self, screw_torque: float, load: float) -> float:
        """Eq 32: F_N,last * sum(L) / (2 pi M_S1)."""
        return load * sum(s.lead for s in self.stages) / (2 * math.pi * screw_torque)

    def steady_efficiency(self) -> float:
        """Efficiency at steady carrier speed (Coulomb model)."""
        return steady_efficiency(self.stages, self.mu_rs, self.mu_ss, self.mu_ns)

    def step_response(self, screw_speed: float, load: float, duration: float, samples: int = 400):
        """Carrier speeds after a screw-speed step from rest (stiff solver, Radau).

        Returns
        -------
        t : numpy.ndarray
        carrier : numpy.ndarray
            theta_Pk' (rad/s), shape (n_stages, n).
        """
        if not screw_speed > 0:
            raise SceneError("operating.screw_speed", "the step response needs a positive screw speed")
        inertia = np.array([carrier_inertia_total(s) for s in self.stages])

        def rhs(_t, w):
            return self.forces(screw_speed, w, load)["carrier_drive"] / inertia
        t = np.geomspace(duration * 1e-6, duration, samples - 1)
        t = np.concatenate([[0.0], t])
        sol = solve_ivp(rhs, (0.0, duration), np.zeros(len(self.stages)), method="Radau", t_eval=t,
                        rtol=1e-9, atol=1e-9 * screw_speed)
        if not sol.success or not np.all(np.isfinite(sol.y)):
            raise SimulationError(f"roller-screw carrier dynamics failed: {sol.message}")
        return sol.t, sol.y

    def time_constants(self, screw_speed: float, load: float) -> np.ndarray:
        """Linearized carrier time constants near steady state (s)."""
        out = []
        for k, s in enumerate(self.stages):
            g = 2 * (s.screw_radius + s.roller_radius)
            if self.viscous:
                gain = s.rollers * self.mu_rs * g * g
            else:
                slip_z = s.lead * screw_speed / (2 * math.pi)
                normal = (load / s.rollers) / (1.0 / thread_normal_norm(s) - self.mu_rs)
                gain = s.rollers * self.mu_rs * normal * g * g / slip_z
            out.append(carrier_inertia_total(s) / gain)
        return np.array(out)

    def settling_time(self, screw_speed: float, load: float) -> float:
        """Estimate of the carriers' settling time (s): the saturated Coulomb ramp to the
        steady speed plus ten linearized time constants."""
        ramp = 0.0
        if not self.viscous:
            for s in self.stages:
                g = 2 * (s.screw_radius + s.roller_radius)
                drive = s.rollers * self.mu_rs * load / s.rollers * thread_normal_norm(s) * g
                ramp = max(ramp, carrier_inertia_total(s) * carrier_ratio(s) * screw_speed / drive)
        return 2 * ramp + 10 * float(self.time_constants(screw_speed, load).max())
