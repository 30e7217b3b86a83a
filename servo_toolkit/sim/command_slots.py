"""The parameter slots of what a controller adds around its feedback: the feedforward, the
command shaper and the gain schedule along the stroke (:class:`servo_toolkit.loop.controller.
CascadeController`; slots in :mod:`servo_toolkit.sim.layout`)."""

from __future__ import annotations

import numpy as np

from ..errors import SceneError
from . import layout as lo


def pack_feedforward(P, controller, scene, sample_time: float, notes: list) -> None:
    """Fill the feedforward slots from ``controller.feedforward`` (all 0 without one: the
    controller's output alone, every result as before). Velocity and acceleration gains and
    the model-based feedforward all give the speed loop the motor speed along the command as
    its reference (it would otherwise oppose the commanded motion)."""
    ff = getattr(controller, "feedforward", None)
    if ff is None or not ff.active:
        return
    P[lo.FF_ON] = 1.0
    P[lo.FF_KV], P[lo.FF_KA] = ff.velocity, ff.acceleration
    P[lo.FF_MODEL] = 1.0 if ff.model else 0.0
    P[lo.FF_JSCALE] = ff.inertia_scale
    P[lo.FF_SPEED] = 1.0
    P[lo.FF_LEAD] = 0.5 * sample_time
    unit = "m" if scene.drivetrain.output_unit == "m" else "rad"
    parts = [f"velocity {ff.velocity:.4g} A*s/{unit}"] if ff.velocity else []
    parts += [f"acceleration {ff.acceleration:.4g} A*s^2/{unit}"] if ff.acceleration else []
    if ff.model:
        if ff.load_inertia is not None:
            P[lo.FF_DJ] = ff.load_inertia - scene.load.inertia
        parts.append("model-based torque (rigid-chain inverse dynamics along the stroke"
                     + (f", inertia x{ff.inertia_scale:.3g}" if ff.inertia_scale != 1.0 else "")
                     + (f", load inertia {ff.load_inertia:.4g} assumed (the model's {scene.load.inertia:.4g})"
                        if ff.load_inertia is not None and P[lo.FF_DJ] != 0.0 else "") + ")")
    notes.append("feedforward from the reference and its derivatives, once per controller sample"
                 + (f" (current at half a sample ahead, {0.5 * sample_time:.3g} s, the hold's delay)"
                    if sample_time > 0 else "") + ": " + ", ".join(parts)
                 + "; the speed loop's reference is the motor speed along the command")


def pack_shaper(P, controller, notes: list) -> None:
    """Fill the command shaper's slots from ``controller.shaper`` (up to three impulses)."""
    shaper = getattr(controller, "shaper", None)
    if shaper is None:
        return
    amps, times = list(shaper.amplitudes), list(shaper.times)
    if len(amps) > 3 or times[0] != 0.0:
        raise SceneError("shaper", f"the kernel takes up to 3 impulses, the first at t = 0 (got {len(amps)})")
    amps += [0.0] * (3 - len(amps))
    times += [0.0] * (3 - len(times))
    P[[lo.SHAPE_A0, lo.SHAPE_A1, lo.SHAPE_A2]] = amps
    P[lo.SHAPE_T1], P[lo.SHAPE_T2] = times[1], times[2]
    notes.append(f"command shaped: {shaper.describe()} (outside the loop; the reference and its derivatives)")


def with_schedule(P, controller, mode: int, notes: list):
    """Append ``controller.schedule``'s block (its index in ``SCHED``); ``FF_ON`` marks the
    sample as more than the state-space update. Returns P.

    Raises
    ------
    SceneError
        A schedule on a continuous controller (key ``schedule``): it is applied per sample.
    """
    schedule = getattr(controller, "schedule", None)
    if schedule is None:
        return P
    if mode != lo.SAMPLED:
        raise SceneError("schedule", "a gain schedule is applied once per controller sample: it needs a sampled "
                                     "controller (the scene's sensors.sample_time, controller_mode 'sampled')")
    P[lo.FF_ON] = 1.0
    P[lo.SCHED] = P.size
    notes.append(schedule.describe() + ", interpolated at the measured output position once per sample")
    return np.concatenate([P, schedule.block()])


def _integrator(a, c, at: float):
    """``(v / C v, v)`` of the controller's integrator (the eigenvector
    v of ``a`` at the eigenvalue ``at``: z = 1 sampled, s = 0 continuous, within 1e-9, the
    continuous one relative to the largest eigenvalue's magnitude); None without one or when
    it does not reach the output."""
    if a.shape[0] == 0:
        return None
    ev, vec = np.linalg.eig(a)
    k = int(np.argmin(np.abs(ev - at)))
    v = np.real(vec[:, k])
    gain = float(np.ravel(c) @ v)
    scale = 1.0 if at != 0.0 else max(1.0, float(np.max(np.abs(ev))))
    if abs(ev[k] - at) > 1e-9 * scale or not abs(gain) > 1e-300:
        return None
    return v / gain, v


def tracking_rate(a, b, c, d) -> float:
    """Kaw (1/s) of a continuous controller with an integrator: 1 / its integral time, the
    tracking time Astrom & Hagglund take for a PI's back-calculation. The error-to-i_ref path
    (input ``theta_ref``) near s = 0 is ``Ki / s + K0``: ``Ki = (C v)(w B)`` and
    ``K0 = D - C A# B`` (``v``, ``w`` the right and left eigenvectors at 0 with ``w v = 1``,
    ``A#`` the group inverse ``(A + v w)^-1 - v w``), and Kaw = Ki / K0. NaN when either is not
    positive (no integral time to track with)."""
    found = _integrator(a, c, 0.0)
    if found is None:
        return float("nan")
    _, v = found
    ev, left = np.linalg.eig(a.T)
    w = np.real(left[:, int(np.argmin(np.abs(ev)))])
    w = w / float(w @ v)
    vw = np.outer(v, w)
    col = np.asarray(b, float)[:, 0]
    ki = float(np.ravel(c) @ v) * float(w @ col)
    k0 = float(np.asarray(d, float)[0, 0]) - float(np.ravel(c) @ ((np.linalg.inv(a + vw) - vw) @ col))
    return ki / k0 if ki > 0 and k0 > 0 else float("nan")


def with_back_calculation(P, a, b, c, d, mode: int, notes: list):
    """Append the clamp's back-calculation of a motion controller with an integrator: its
    direction v (the eigenvector at z = 1 sampled, at s = 0 continuous) over its output gain
    C v. A clamped sample of a sampled controller moves the integrator by the excess, so
    that the next output starts at the limit; a continuous controller's integrator bleeds
    it, ``x' += Kaw g (clamped - unclamped)``, at ``Kaw`` = 1 / its integral time
    (:func:`tracking_rate`, appended after the gains). Either way the integrator does not
    wind up against the current limit, with or without a feedforward. A controller without
    an integrator gets none. Returns P."""
    if mode not in (lo.SAMPLED, lo.CONTINUOUS):
        return P
    found = _integrator(a, c, 1.0 if mode == lo.SAMPLED else 0.0)
    if found is None:
        return P
    g = found[0]
    if mode == lo.SAMPLED:
        P[lo.AW] = P.size
        notes.append("anti-windup: at the current limit the motion controller's integrator takes the clamp's "
                     "excess (back-calculation, its next output starts at the limit)")
        return np.concatenate([P, g])
    kaw = tracking_rate(a, b, c, d)
    if not np.isfinite(kaw):
        return P
    P[lo.AW] = P.size
    notes.append(f"anti-windup: at the current limit the continuous motion controller's integrator bleeds the "
                 f"clamp's excess (back-calculation, tracking time {1 / kaw:.4g} s, its integral time)")
    return np.concatenate([P, g, [kaw]])


__all__ = ["pack_feedforward", "pack_shaper", "tracking_rate", "with_back_calculation", "with_schedule"]
