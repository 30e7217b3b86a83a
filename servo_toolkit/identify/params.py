"""Scene key paths as fit parameters: resolve ``load.inertia``, ``drivetrain[3].stiffness``,
``motor.resistance`` ... to their SI unit and value, and build the scene with new values.

The key paths themselves are :mod:`servo_toolkit.scene.key_paths` (shared with the
scene's ``[tolerances]``); a fit parameter is a positive scalar quantity of the actuator
(or a nonzero signed one, a constant force or moment), fitted as a logarithm (or a value).
"""

from __future__ import annotations

import tomllib
from dataclasses import replace
from pathlib import Path

from ..errors import SceneError
from ..scene.key_paths import KeyPath, SceneKeys
from ..scene.loader import read_scene_text, scene_from_dict


#: A scene key to fit: its :attr:`~servo_toolkit.scene.key_paths.KeyPath.value` in the scene
#: is the fit's initial value, :attr:`~servo_toolkit.scene.key_paths.KeyPath.signed` says
#: whether the fit varies the value or its logarithm, ``bounds`` the magnitudes it may take.
Parameter = KeyPath


class SceneTemplate:
    """A scene's tables with some keys free: :meth:`scene` builds it with given values.

    Parameters
    ----------
    scene : Scene
        A scene loaded from a file (its ``source``).
    keys : sequence of str
        Key paths to free; each must be a positive scalar quantity the loader reads, or a
        nonzero one that it accepts with either sign (``load.hinge_moment``).

    Raises
    ------
    SceneError
        A key the scene does not read (naming the keys it does), or one that is not a
        positive scalar quantity.
    """

    def __init__(self, scene, keys):
        if not scene.source:
            raise SceneError("scene", "fitting needs a scene read from a file (load_scene)")
        self.source = scene.source
        self.text = read_scene_text(Path(scene.source))
        self.data = tomllib.loads(self.text)
        self.keys = SceneKeys(self.data, self.source, scene_from_dict)
        self.base = self.keys.base if "robustness" not in self.data and "tolerances" not in self.data else \
            _full_scene(self.data, self.source)
        if not keys:
            raise SceneError("--param", "give at least one scene key to fit, e.g. load.inertia")
        if len(set(keys)) != len(keys):
            dup = next(k for k in keys if list(keys).count(k) > 1)
            raise SceneError(dup, "given twice as a fit parameter")
        params = []
        for key in keys:
            if key.startswith("sensors."):
                raise SceneError(key, "not a physical parameter of the plant; fit motor, drivetrain or load keys")
            kp = self.keys.resolve(key, integers=False, what="a quantity of this scene that fit can estimate")
            value, signed = kp.value, kp.signed
            if signed and not (value != 0 and abs(value) < float("inf")):
                raise SceneError(key, f"must be a nonzero finite scalar to be fitted: its magnitude sets the "
                                 f"search's scale (is {value:g} {kp.unit})")
            if not signed and not (value > 0 and value < float("inf")):
                raise SceneError(key, f"must be a positive finite scalar to be fitted (is {value:g} {kp.unit})")
            params.append(replace(kp, bounds=None if kp.bounds is None else tuple(float(b) for b in kp.bounds)))
        self.parameters = tuple(params)

    @property
    def initial(self) -> list:
        """Initial values (SI), in parameter order."""
        return [p.value for p in self.parameters]

    def scene(self, values):
        """The scene with the parameters set to ``values`` (SI, in parameter order)."""
        data = self.keys.data_with({p.key: v for p, v in zip(self.parameters, values)})
        for name in ("robustness", "tolerances"):
            if name in self.data:
                data[name] = self.data[name]
        return scene_from_dict(data, self.source)


def _full_scene(data, source):
    return scene_from_dict(dict(data), source)
