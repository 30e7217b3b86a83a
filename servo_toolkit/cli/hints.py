"""One-line hints: what to run instead when a command does not apply to a scene.

The seed-mechanism scenes without a motor-driven drivetrain (the crossed-arch platform,
the two-stage roller screw) have no loop to design, check, export or sweep; their studies
run through ``simulate --study NAME``. The commands that run studies (``simulate``,
``sweep``, ``kv``, ``accuracy``) run such a scene's first study by default; the others say
what to run instead.
"""

from __future__ import annotations

from ..errors import SceneError
from . import mechanism_dispatch as dispatch


def has_motor_drivetrain(scene) -> bool:
    """True when the scene has a motor-driven drivetrain (a loop to design)."""
    try:
        scene.drivetrain  # noqa: B018 - raises for a mechanism-only scene
    except SceneError:
        return False
    return True


def mechanism_studies(scene) -> list:
    """Names of the scene's studies the seed-mechanism module runs (file order, then built-in)."""
    names = [name for name, study in scene.studies.items() if dispatch.handled(scene, study)]
    return names + [s for s in dispatch.builtin_studies(scene) if s not in names]


def default_mechanism_study(scene):
    """The study a study-running command runs by default on a scene without a motor-driven
    drivetrain (its first mechanism study), else None."""
    if has_motor_drivetrain(scene):
        return None
    found = mechanism_studies(scene)
    return found[0] if found else None


def what_to_run(scene, path) -> str:
    """``run `servo-toolkit simulate PATH --study NAME` (studies: ...)`` for a mechanism scene."""
    found = mechanism_studies(scene)
    if not found:
        return "the scene has no study to run"
    return (f"run `servo-toolkit simulate {path} --study {found[0]}`"
            + (f" (its studies: {', '.join(found)})" if len(found) > 1 else ""))


def no_drivetrain_hint(command: str, scene_path) -> str | None:
    """The hint for ``command`` on a scene without a motor-driven drivetrain (None when the
    scene cannot be read or does have one)."""
    from ..scene import load_scene
    try:
        scene = load_scene(scene_path) if scene_path is not None else None
    except (SceneError, OSError):
        return None
    if scene is None or has_motor_drivetrain(scene):
        return None
    return f"`{command}` needs a motor-driven drivetrain; for this scene {what_to_run(scene, scene_path)}"


__all__ = ["default_mechanism_study", "has_motor_drivetrain", "mechanism_studies", "no_drivetrain_hint",
           "what_to_run"]
