"""Scene files: TOML with units -> validated, frozen descriptions of an actuator.

Modules: :mod:`.loader` (reading and validating a scene, :class:`Scene`),
:mod:`.study_kind` (the registry of study kinds: what each ``[studies.NAME]`` kind takes
and runs), :mod:`.study_schema` (how a study table is read with its kind's keys) and
:mod:`.card` (its Jupyter display).
"""

from .loader import (Requirements, Robustness, Scene, Sensors, Study, default_scene_path, load_scene,
                     read_scene_text, replace_params, scene_from_dict)

__all__ = ["Requirements", "Robustness", "Scene", "Sensors", "Study", "default_scene_path", "load_scene",
           "read_scene_text", "replace_params", "scene_from_dict"]
