"""The ``scene`` argument of the toolkit's Python functions: a Scene, or a scene file's path."""

from __future__ import annotations

import os

from ..errors import SceneError


def as_scene(scene, name: str = "scene"):
    """``scene`` as a :class:`~servo_toolkit.scene.loader.Scene`: a Scene as it is, a path
    (str or path-like) read with :func:`~servo_toolkit.scene.loader.load_scene`, as the
    command line reads its scene argument.

    Raises
    ------
    SceneError
        Naming ``name``: neither a Scene nor a path (a DesignResult, a dict ...); the file's
        own errors as :func:`~servo_toolkit.scene.loader.load_scene` gives them.
    """
    from .loader import Scene, load_scene
    if isinstance(scene, Scene):
        return scene
    if isinstance(scene, (str, os.PathLike)):
        return load_scene(scene)
    raise SceneError(name, f"expected a Scene or a scene file's path (servo_toolkit.load_scene), "
                           f"got {type(scene).__name__}")


__all__ = ["as_scene"]
