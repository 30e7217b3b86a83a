"""Study look-up shared by ``simulate``, ``kv`` and ``sweep``: seed-mechanism studies first.

A seed-mechanism scene (cam drive, crossed-arch platform, roller screw) runs its studies
through :func:`servo_toolkit.mechanisms.run_study`, whatever the command, as
:mod:`servo_toolkit.mechanisms` decides (``handles``). Roller-screw scenes have built-in
studies that are not in the scene file (``ROLLER_SCREW_STUDIES``); a "no such study" error
lists them with the scene's own.
"""

from __future__ import annotations

import importlib

from ..errors import SceneError


def mechanisms():
    """The mechanism-study module when it is installed, else None."""
    try:
        return importlib.import_module("servo_toolkit.mechanisms")
    except ImportError:
        return None


def builtin_studies(scene) -> tuple:
    """Names of the built-in (not in the scene file) mechanism studies of ``scene``."""
    mech = mechanisms()
    if mech is None or not getattr(scene, "roller_screw", ()):
        return ()
    return tuple(getattr(mech, "ROLLER_SCREW_STUDIES", ()))


def handled(scene, study) -> bool:
    """True when the mechanism module runs ``study`` (a name or a Study) of ``scene``."""
    mech = mechanisms()
    handles = getattr(mech, "handles", None)
    return bool(handles is not None and handles(scene, study))


def run_mechanism(scene, study, **options):
    """Run a seed-mechanism study (``options`` go to ``mechanisms.run_study``)."""
    return mechanisms().run_study(scene, study, **options)


def available(scene) -> list:
    """Every study name the commands accept for ``scene``: the file's and the built-in ones."""
    return sorted(scene.studies) + [s for s in builtin_studies(scene) if s not in scene.studies]


def require(scene, name: str) -> None:
    """Raise SceneError ``studies.NAME`` when ``name`` is neither a study of the scene nor a
    built-in mechanism study; the message lists both."""
    if name in scene.studies or name in builtin_studies(scene):
        return
    built = [s for s in builtin_studies(scene) if s not in scene.studies]
    extra = f" and the built-in mechanism studies {built}" if built else ""
    raise SceneError(f"studies.{name}", f"no such study; the scene has {sorted(scene.studies)}{extra}")
