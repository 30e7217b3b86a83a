"""One-line hints: what to run instead when a command does not apply to a scene.

The seed-mechanism scenes without a motor-driven drivetrain (the crossed-arch platform,
the two-stage roller screw) have no loop to design, check, export or sweep; their studies
run through ``simulate --study NAME``. The commands that run studies (``simulate``,
``sweep``, ``kv``, ``accuracy``) run such a scene's first study by default; the others say
what to run instead.
"""

from __future__ import annotations

from ..errors import SceneError


def what_to_run(scene, path) -> str:
    """``run `servo-toolkit simulate PATH --study NAME` (studies: ...)`` for a mechanism scene."""
    from ..studies.run import mechanism_studies
    found = mechanism_studies(scene)
    if not found:
        return "the scene has no study to run"
    return (f"run `servo-toolkit simulate {path} --study {found[0]}`"
            + (f" (its studies: {', '.join(found)})" if len(found) > 1 else ""))


def no_drivetrain_hint(command: str, scene_path) -> str | None:
    """The hint for ``command`` on a scene without a motor-driven drivetrain (None when the
    scene cannot be read or does have one)."""
    from ..scene.loader import load_scene
    from ..studies.run import has_motor_drivetrain
    try:
        scene = load_scene(scene_path) if scene_path is not None else None
    except (SceneError, OSError):
        return None
    if scene is None or has_motor_drivetrain(scene):
        return None
    return f"`{command}` needs a motor-driven drivetrain; for this scene {what_to_run(scene, scene_path)}"


__all__ = ["no_drivetrain_hint", "what_to_run"]
