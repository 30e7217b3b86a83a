"""Constant armature voltage on the cam drive: the seed's discrete scheme and an accurate solver.

The continuous model (inductance neglected, seed 002 eqs 9-12) is

    J(theta) w' + (1/2) J'(theta) w^2 = c_m i - M_f - M_g,   i = (u - c_e w) / R,

where ``M_g = (sign(v) f - G_x) ds/dtheta`` holds the guide friction and gravity (the
inertial part ``m a ds/dtheta`` of eq 3 is the variable-inertia term on the left). The guide
friction depends on the follower acceleration, hence on w'; the right-hand side resolves
that with the same contraction as :meth:`CamDrive.follower_force`.

The seed's scheme (section 3) instead steps w by RK4 with J and M frozen at step k, sums
theta, takes s from the law and eqs 6-8, v and a by backward differences, and recomputes M
and J = J_m + m (v/w)^2 for the next step. As printed it counts the follower inertia twice
(m (ds/dtheta)^2 in J *and* m a in M), so as T shrinks it converges, at first order, to a
different continuous model ((J_m + 2 m s'^2) w' + m s' s'' w^2 = ...); the ``"corrected"``
scheme keeps only the velocity-squared part of m a s' and converges to the model above.
:func:`constant_voltage` reports both against the accurate solution for halved steps.

The differenced v and a can be replaced by a Kalman filter on the shaft encoder's counts
(``speed_estimator="kalman"``, :mod:`.cam_estimation`); the default is the seed's
differences. Either way the study compares both estimators with the accurate solution's true
speed and acceleration.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp

from ...errors import SimulationError
from ...components.cam import kernels
from ...components.cam.drive import CamDrive
from .estimation import DEFAULT_ENCODER_COUNTS, ESTIMATORS, compare_on_reference, kalman_scheme
from .voltage_result import CamVoltageResult, Trajectory


def steady_speed_without_follower(drive: CamDrive, voltage: float) -> float:
    """Closed form (c_m u - R M_f) / (c_e c_m): the speed with the follower removed (rad/s)."""
    return ((drive.torque_constant * voltage - drive.resistance * drive.shaft_friction)
            / (drive.back_emf_constant * drive.torque_constant))


SCHEMES = ("seed", "corrected")


def discrete_scheme(drive: CamDrive, voltage: float, duration: float, step: float,
                    scheme: str = "seed", speed_estimator: str = "difference",
                    encoder_counts: int | None = None, jerk: float | None = None) -> Trajectory:
    """The seed's fixed-step scheme (section 3), started from rest at theta = 0.

    Parameters
    ----------
    drive : CamDrive
    voltage : float
        Armature voltage u (V).
    duration, step : float
        Run length and step T (s).
    scheme : {"seed", "corrected"}
        ``"seed"`` as printed: J of eq 4 on the left of eq 12 *and* ``m a`` in the load of
        eq 3, which counts the follower inertia twice; ``"corrected"`` keeps only the
        velocity-squared part ``m s' s'' w^2`` of ``m a s'`` (``a`` minus ``s' dw/dt``, both
        by backward differences), so that the scheme converges to the continuous model.
    speed_estimator : {"difference", "kalman"}
        ``"difference"`` (the seed's): v and a by backward differences of the follower
        travel; ``"kalman"``: a Kalman filter on the shaft encoder's counts of the cam angle
        (:func:`~.cam_estimation.kalman_scheme`, which needs ``encoder_counts`` (default
        4096 per revolution) and the jerk level ``jerk`` in rad/s^3).

    Raises
    ------
    SimulationError
        Non-finite speed, or the cam reversing (the shaft-friction model assumes w >= 0).
    """
    if scheme not in SCHEMES:
        raise ValueError(f"scheme must be one of {SCHEMES} (got {scheme!r})")
    if speed_estimator not in ESTIMATORS:
        raise ValueError(f"speed_estimator must be one of {ESTIMATORS} (got {speed_estimator!r})")
    if speed_estimator == "kalman":
        return kalman_scheme(drive, voltage, duration, step, scheme, encoder_counts or DEFAULT_ENCODER_COUNTS,
                             jerk)
    n = int(round(duration / step))
    if n < 1 or not step > 0:
        raise SimulationError(f"step {step} s does not fit in a run of {duration} s")
    theta, omega, status = kernels.discrete(kernels.pack(drive), float(voltage), n, float(step),
                                            scheme == "corrected")
    if status:
        k = int(np.flatnonzero(omega)[-1]) + 1 if np.any(omega) else 1
        what = "non-finite speed" if status == 1 else ("the cam reversed (w < 0; the shaft-friction "
                                                       "model assumes forward rotation)")
        raise SimulationError(f"discrete cam scheme ({scheme}, T = {step:.4g} s): {what} "
                              f"at t = {k * step:.4g} s")
    t = np.arange(n + 1) * step
    return Trajectory(f"discrete ({scheme})", t, theta, omega,
                      (voltage - drive.back_emf_constant * omega) / drive.resistance)


def accurate(drive: CamDrive, voltage: float, duration: float, t_eval=None, rtol: float = 1e-10,
             double_count: bool = False) -> Trajectory:
    """The continuous model by scipy ``solve_ivp`` (DOP853), started from rest at theta = 0.

    ``double_count=True`` integrates the continuous limit of the seed's printed scheme
    (follower inertia in both J and m a), to separate its modelling error from its
    discretization error.

    Raises
    ------
    SimulationError
        With clearance (its continuous limit is an impact, which this rigid model does not
        describe; the discrete scheme handles clearance), when the cam reverses, or when the
        solver fails.
    """
    if drive.cam.clearance > 0:
        raise SimulationError("the accurate cam solver assumes rigid contact (clearance = 0); "
                              "use the discrete scheme for a cam with clearance")
    p = kernels.pack(drive)
    u = float(voltage)

    def fun(_t, y):
        return kernels.rhs(p, u, y[0], y[1], double_count)

    def reversed_(_t, y):
        return y[1] + 1e-9
    reversed_.terminal = True
    sol = solve_ivp(fun, (0.0, duration), [0.0, 0.0], method="DOP853", rtol=rtol, atol=1e-12,
                    t_eval=t_eval, events=reversed_)
    if sol.status == 1:
        raise SimulationError(f"the cam reversed at t = {sol.t_events[0][0]:.4g} s; the shaft-friction "
                              "model assumes forward rotation")
    if not sol.success or not np.all(np.isfinite(sol.y)):
        raise SimulationError(f"accurate cam solver failed: {sol.message}")
    omega = sol.y[1]
    return Trajectory("accurate", sol.t, sol.y[0], omega,
                      (voltage - drive.back_emf_constant * omega) / drive.resistance)


def constant_voltage(drive: CamDrive, voltage: float, duration: float, step: float,
                     refinements: int = 3, method: str | None = None,
                     window: float | None = None, speed_estimator: str = "difference",
                     encoder_counts: int | None = None, kalman_jerk: float | None = None) -> CamVoltageResult:
    """Run the constant-voltage study by every method and check convergence.

    Parameters
    ----------
    drive : CamDrive
    voltage, duration, step : float
        u (V), run length (s) and the study's step T (s).
    refinements : int
        The convergence check uses steps ``4 T, 2 T, T, T/2, ...`` (``refinements`` halvings
        below 4 T). A run of the check that stops (a large step can make the explicit scheme
        reverse the cam) is recorded in ``ladder_failures`` with NaN errors; the study goes on.
    method : str, optional
        Recorded in the result; every method always runs.
    window : float, optional
        Start-up window of the pointwise speed error (s); default a tenth of the run.
    speed_estimator : {"difference", "kalman"}
        What the scheme uses for the follower speed and acceleration; ``"difference"`` is
        the seed's. With ``"kalman"`` the seed and corrected schemes also run with the
        Kalman filter (result field ``kalman``); the convergence ladder always uses the
        seed's differences. Both estimators are compared on the accurate solution either way.
    encoder_counts : int, optional
        Shaft encoder counts per revolution (default 4096).
    kalman_jerk : float, optional
        Kalman jerk level (rad/s^3); default the RMS jerk of the accurate solution.

    Notes
    -----
    With clearance (``drive.cam.clearance > 0``) the seed and corrected schemes run with
    the hysteresis of eqs 6-8 at the study step, and the accurate comparison (reference,
    continuous limit, convergence check, estimator comparison) is skipped: the rigid
    accurate model has no clearance. The result's ``skipped`` says so.

    Raises
    ------
    SimulationError
        When a scheme stops at the study step itself (the message names the scheme, the
        step and the time), or the accurate solver fails.
    """
    if speed_estimator not in ESTIMATORS:
        raise ValueError(f"speed_estimator must be one of {ESTIMATORS} (got {speed_estimator!r})")
    encoder_counts = encoder_counts or DEFAULT_ENCODER_COUNTS
    window = 0.1 * duration if window is None else min(window, duration)
    clearance = drive.cam.clearance
    if clearance > 0:
        if speed_estimator == "kalman":
            raise SimulationError("the Kalman option estimates the follower motion from the cam angle; with "
                                  "clearance the travel is not a function of the angle (use differences)")
        return _with_clearance(drive, voltage, duration, step, window, method)
    seed = discrete_scheme(drive, voltage, duration, step, "seed")
    corr = discrete_scheme(drive, voltage, duration, step, "corrected")
    steps = 4 * step / 2.0 ** np.arange(refinements + 1)
    times = np.arange(int(round(duration / steps[-1])) + 1) * steps[-1]
    times = times[times <= duration]
    ref = accurate(drive, voltage, duration, t_eval=times)
    limit = accurate(drive, voltage, duration, t_eval=times, double_count=True)
    errors = {"seed": [], "corrected": [], "seed_vs_limit": []}
    angles = {"seed": [], "corrected": [], "seed_vs_limit": []}
    ladder_failures = []
    for h in steps:
        runs = {}
        for name in SCHEMES:
            try:
                runs[name] = discrete_scheme(drive, voltage, duration, h, name)
            except SimulationError as exc:
                runs[name] = None
                ladder_failures.append((float(h), name, str(exc)))
        for key, name, against in (("seed", "seed", ref), ("corrected", "corrected", ref),
                                   ("seed_vs_limit", "seed", limit)):
            run = runs[name]
            errors[key].append(math.nan if run is None else _error(run, against, window))
            angles[key].append(math.nan if run is None else
                               abs(run.theta[-1] - np.interp(run.t[-1], against.t, against.theta)))
    estimation = compare_on_reference(drive, voltage, accurate(drive, voltage, duration, t_eval=seed.t),
                                      encoder_counts, kalman_jerk)
    kalman, failures = None, None
    if speed_estimator == "kalman":
        kalman, failures = {}, {}
        for name in SCHEMES:
            try:
                kalman[name] = kalman_scheme(drive, voltage, duration, step, name, encoder_counts,
                                             estimation.comparison.jerk)
            except SimulationError as exc:
                failures[name] = str(exc)
    return CamVoltageResult(voltage, _at(ref, seed.t), seed, corr, _at(limit, seed.t), steps,
                            {k: np.array(v) for k, v in errors.items()},
                            {k: np.array(v) for k, v in angles.items()}, window,
                            steady_speed_without_follower(drive, voltage), method or "both",
                            estimation, speed_estimator, kalman, failures or None, tuple(ladder_failures))


#: relative changes of the voltage that probe a scheme's conditioning
CONDITION_PROBES = (1e-12, -1e-12)
#: a scheme is ill-conditioned when its relative condition number (relative change of the
#: speed trace over the relative change of the voltage) exceeds this: a voltage known to
#: nine digits then leaves the speed uncertain in its third
ILL_CONDITIONED = 1e6


def _with_clearance(drive: CamDrive, voltage: float, duration: float, step: float, window: float,
                    method: str | None) -> CamVoltageResult:
    """Both discrete schemes with the clearance hysteresis of eqs 6-8, each kept on its own: a
    scheme that stops (the cam reverses) gives its trajectory up to the stop and the reason,
    the other its whole run. Each scheme that ran through is probed for its conditioning
    (:func:`_conditioning`): with a large clearance the impacts make the seed's scheme
    chaotic, and its speed is then not determined by the inputs."""
    runs, failures, conditioning = {}, {}, {}
    for name in SCHEMES:
        runs[name], failures[name] = _scheme_until_stop(drive, voltage, duration, step, name)
        if failures[name] is None:
            conditioning[name] = _conditioning(drive, voltage, duration, step, name, runs[name])
    why = (f"the cam has clearance c = {drive.cam.clearance:.4g} m; its continuous limit is an impact, which the "
           "rigid accurate model does not describe, so only the discrete schemes (eqs 6-8) ran")
    empty = {k: np.array([]) for k in ("seed", "corrected", "seed_vs_limit")}
    return CamVoltageResult(voltage, None, runs["seed"], runs["corrected"], None, np.array([]), empty, dict(empty),
                            window, steady_speed_without_follower(drive, voltage), method or "both",
                            skipped=why, clearance=drive.cam.clearance,
                            scheme_failures={k: v for k, v in failures.items() if v},
                            conditioning=conditioning)


def _scheme_until_stop(drive, voltage, duration, step, name):
    """``(trajectory, None)`` of a whole run, or ``(trajectory up to the stop, reason)``."""
    try:
        return discrete_scheme(drive, voltage, duration, step, name), None
    except SimulationError as exc:
        n = int(round(duration / step))
        theta, omega, _ = kernels.discrete(kernels.pack(drive), float(voltage), n, float(step), name == "corrected")
        k = max(1, int(np.flatnonzero(omega)[-1]) if np.any(omega) else 1)
        t = np.arange(k + 1) * step
        return (Trajectory(f"discrete ({name}, stopped)", t, theta[:k + 1], omega[:k + 1],
                           (voltage - drive.back_emf_constant * omega[:k + 1]) / drive.resistance), str(exc))


def _conditioning(drive, voltage, duration, step, name, run) -> dict:
    """The relative condition number of a scheme's speed trace with respect to the voltage,
    probed by the relative changes :data:`CONDITION_PROBES`: max |w' - w| / max |w| over
    |du / u| (a smooth, well-posed run gives a number of order one)."""
    scale = max(float(np.max(np.abs(run.omega))), 1e-300)
    change, rel = 0.0, abs(CONDITION_PROBES[0])
    for d in CONDITION_PROBES:
        try:
            probe = discrete_scheme(drive, voltage * (1 + d), duration, step, name)
            change = max(change, float(np.max(np.abs(probe.omega - run.omega))))
        except SimulationError:
            change = math.inf
    number = change / scale / rel
    return {"relative_voltage_change": rel, "max_speed_change_rad_s": change, "condition_number": number,
            "ill_conditioned": bool(number > ILL_CONDITIONED)}


def _at(traj: Trajectory, t) -> Trajectory:
    return Trajectory(traj.method, t, np.interp(t, traj.t, traj.theta), np.interp(t, traj.t, traj.omega),
                      np.interp(t, traj.t, traj.current))


def _error(run: Trajectory, ref: Trajectory, window: float) -> float:
    keep = run.t <= window + 1e-12
    return float(np.abs(run.omega[keep] - np.interp(run.t[keep], ref.t, ref.omega)).max())
