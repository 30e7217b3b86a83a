"""servo_toolkit: servo control design for electromechanical actuators.

The top-level names are imported on first use, so ``import servo_toolkit`` (and the command
line's ``--help``) stays quick: python-control, scipy and the compiled kernels load only when a name that
needs them is used.
"""

from importlib import import_module

from .core.version import __version__
from .errors import SceneError, SimulationError

#: public name -> module that defines it (imported on first access)
_LAZY = {"Scene": ".scene", "load_scene": ".scene", "design": ".loop", "export": ".export",
         "simulate": ".sim", "tune": ".tuner", "tuned_design": ".loop.tuning", "LoopTuning": ".loop.tuning",
         "fit": ".identify", "run_study": ".studies.run",
         "size": ".studies.sizing"}

__all__ = ["SceneError", "SimulationError", "__version__", *sorted(_LAZY)]


def __getattr__(name: str):
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'servo_toolkit' has no attribute {name!r}")
    value = getattr(import_module(module, __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_LAZY))
