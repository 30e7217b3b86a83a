"""servo_toolkit: servo control design for electromechanical actuators."""

from .errors import SceneError, SimulationError
from .export import export
from .loop import design
from .scene import Scene, load_scene
from .sim import simulate

__version__ = "0.1.0"

__all__ = ["Scene", "SceneError", "SimulationError", "design", "export", "load_scene", "simulate", "__version__"]
