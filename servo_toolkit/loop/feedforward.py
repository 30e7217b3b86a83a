"""Designed velocity and acceleration feedforward gains, and the command options of a
controller (feedforward, gain schedule, command shaper) by name.

The gains are the rigid drivetrain's inverse dynamics frozen at the operating point q0: the
current that accelerates the reflected inertia and the one that overcomes the viscous
friction along a commanded output trajectory r(t)::

    Ka = J(q0) / (N(q0) Kt)                    A per output rad/s^2 (per m/s^2 for a travel)
    Kv = (b N(q0)^2 + c_L) / (N(q0) Kt)        A per output rad/s

with J the inertia reflected to the output, N the ratio (motor rad per output rad), Kt the
torque constant, b the motor's viscous friction and c_L the load's damping. The back EMF
needs no feedforward: the current loop sets the current whatever the speed (its voltage
does the work, up to the voltage limit). What they leave out, the model-based feedforward
(:class:`~.controller.Feedforward` with ``model=True``) adds: J(q) and its velocity term
J'(q) r'^2 / 2 along the stroke, the drivetrain's loss by the direction of the power flow,
the hinge moment and the Coulomb friction.
"""

from __future__ import annotations

from dataclasses import replace

from ..errors import SceneError
from .controller import FEEDFORWARD_KINDS, Feedforward


def feedforward_gains(scene, q0: float | None = None) -> dict:
    """The designed gains at ``q0`` (default: the design's operating point), with what they
    are made of.

    Returns
    -------
    dict
        ``velocity`` (Kv, A*s/rad), ``acceleration`` (Ka, A*s^2/rad), ``q0``, ``inertia``
        J(q0), ``ratio`` N(q0), ``torque_constant``, ``motor_viscous``, ``load_damping``.
    """
    from ..drivetrain.operating_point import operating_point
    drive, motor = scene.drivetrain, scene.motor
    if motor is None:
        raise SceneError("motor", "feedforward gains need a motor-driven drivetrain")
    q0, _ = operating_point(scene, q0)
    n = abs(float(drive.ratio([q0])[0][0]))
    j = float(drive.inertia([q0])[0][0])
    kt = motor.torque_constant
    return {"velocity": (motor.viscous_friction * n * n + scene.load.damping) / (n * kt),
            "acceleration": j / (n * kt), "q0": float(q0), "inertia": j, "ratio": n, "torque_constant": kt,
            "motor_viscous": motor.viscous_friction, "load_damping": scene.load.damping}


def designed_feedforward(scene, kind: str, q0: float | None = None) -> Feedforward | None:
    """The feedforward of ``kind``: ``"off"`` (None), ``"gains"`` (:func:`feedforward_gains`)
    or ``"model"`` (the model-based torque feedforward)."""
    if kind not in FEEDFORWARD_KINDS:
        raise SceneError("feedforward", f"must be one of {', '.join(FEEDFORWARD_KINDS)} (got {kind!r})")
    if kind == "gains":
        g = feedforward_gains(scene, q0)
        return Feedforward(velocity=g["velocity"], acceleration=g["acceleration"])
    return Feedforward.from_kind(kind)


def with_command(controller, scene, *, feedforward=None, schedule=None, shaper=None):
    """The controller with its command options replaced (None keeps each as it is).

    Parameters
    ----------
    controller : CascadeController
    scene : Scene
        For the designed gains, the schedule and the shaper's mode.
    feedforward : Feedforward or {"off", "gains", "model"}, optional
    schedule : bool or GainSchedule, optional
        True: :func:`~.schedule.gain_schedule` of the scene; False: none.
    shaper : InputShaper or {"off", "zv", "zvd"}, optional
        ``"zv"`` / ``"zvd"``: :func:`~.shaper.shaper_for` the scene and this controller.

    Raises
    ------
    SceneError
        An unknown name (key ``feedforward``, ``schedule`` or ``shaper``).
    """
    from .schedule import GainSchedule, gain_schedule
    from .shaper import SHAPER_KINDS, InputShaper, shaper_for
    if feedforward is not None:
        if isinstance(feedforward, str):
            feedforward = designed_feedforward(scene, feedforward)
        elif not isinstance(feedforward, Feedforward):
            raise SceneError("feedforward", f"must be a Feedforward or one of {', '.join(FEEDFORWARD_KINDS)} "
                                            f"(got {feedforward!r})")
        controller = replace(controller, feedforward=feedforward)
    if schedule is not None:
        if schedule is True:
            schedule = gain_schedule(scene)
        elif schedule is False:
            schedule = None
        elif not isinstance(schedule, GainSchedule):
            raise SceneError("schedule", f"must be True, False or a GainSchedule (got {schedule!r})")
        controller = replace(controller, schedule=schedule)
    if shaper is not None:
        if isinstance(shaper, str):
            if shaper not in ("off",) + SHAPER_KINDS:
                raise SceneError("shaper", f"must be one of off, {', '.join(SHAPER_KINDS)} (got {shaper!r})")
            shaper = None if shaper == "off" else shaper_for(scene, shaper, controller=controller)
        elif not isinstance(shaper, InputShaper):
            raise SceneError("shaper", f"must be an InputShaper or one of off, {', '.join(SHAPER_KINDS)} "
                                       f"(got {shaper!r})")
        controller = replace(controller, shaper=shaper)
    return controller


__all__ = ["designed_feedforward", "feedforward_gains", "with_command"]
