"""``simulate(scene, ...)``: the one-call entry point, and the controller to use."""

from __future__ import annotations

from dataclasses import replace

from ..core.units import argument_value
from ..errors import SceneError
from ..loop.controller import FEEDFORWARD_KINDS, CascadeController, Feedforward
from ..loop.result import DesignResult
from ..scene.argument import as_scene
from .engine import run
from .model import ModelOptions, build_model
from .reference import Reference
from .reference_checks import check_reference_output, check_sine_frequency


#: the source of a designed controller whose linear closed loop is unstable
UNSTABLE_SOURCE = "loop.design: closed loop UNSTABLE"


def controller_for(scene):
    """The designed controller (:func:`servo_toolkit.loop.design`).

    Returns
    -------
    controller : CascadeController
    source : str
        ``"loop.design"``, ``"loop.design: closed loop UNSTABLE"`` (the design found no
        stable controller: the run shows what that controller does, and says so).
    """
    from ..loop.design import design  # the loop is designed upstream of every simulation
    result = design(scene)
    if not result.margins.closed_loop_stable:
        return result.controller, UNSTABLE_SOURCE
    return result.controller, "loop.design"


def with_feedforward(controller, feedforward, scene=None, *, shaper=None, schedule=None):
    """The controller with its feedforward (and, given, its command shaper and gain schedule)
    replaced: a :class:`Feedforward`, ``"off"`` (none), ``"gains"`` (the designed velocity and
    acceleration gains of ``scene``, :func:`servo_toolkit.loop.feedforward.feedforward_gains`),
    ``"model"`` (model-based torque feedforward) or None (the controller's own); ``shaper``
    and ``schedule`` as :func:`servo_toolkit.loop.feedforward.with_command`.

    Raises
    ------
    SceneError
        ``feedforward`` names no known kind (key ``feedforward``), ``"gains"`` without a
        scene; a bad shaper or schedule (their keys).
    """
    from ..loop.feedforward import with_command
    if isinstance(feedforward, str) and feedforward not in FEEDFORWARD_KINDS:
        raise SceneError("feedforward", f"must be one of {', '.join(FEEDFORWARD_KINDS)} (got {feedforward!r})")
    if feedforward is not None and not isinstance(feedforward, (str, Feedforward)):
        raise SceneError("feedforward", f"must be a Feedforward or one of {', '.join(FEEDFORWARD_KINDS)} "
                                        f"(got {feedforward!r})")
    if scene is None:
        if feedforward == "gains" or shaper is not None or schedule is not None:
            raise SceneError("feedforward", "designed gains, a shaper or a schedule need the scene")
        return controller if feedforward is None else replace(controller, feedforward=Feedforward.from_kind(feedforward)
                                                              if isinstance(feedforward, str) else feedforward)
    return with_command(controller, scene, feedforward=feedforward, shaper=shaper, schedule=schedule)


def _controller_argument(controller, scene):
    """``simulate``'s controller: None, a CascadeController, or a DesignResult's (made for
    ``scene``: :meth:`~servo_toolkit.loop.result.DesignResult.require_scene`)."""
    if controller is None or isinstance(controller, CascadeController):
        return controller
    if isinstance(controller, DesignResult):
        controller.require_scene(scene, "controller")
        return controller.controller
    raise SceneError("controller", f"expected a CascadeController (a design's .controller) or a DesignResult, "
                                   f"got {type(controller).__name__}")


def simulate(scene, controller=None, *, reference: Reference | None = None, duration: float = 1.0,
             method: str = "rk4", dt: float | None = None, voltage: float | None = None,
             options: ModelOptions | None = None, feedforward=None, shaper=None, schedule=None,
             **run_options):
    """Simulate a scene in closed loop (or open loop at a constant voltage).

    Numbers are in SI (s, V); a pint Quantity is converted.

    Parameters
    ----------
    scene : Scene or path-like
        A path is read with :func:`~servo_toolkit.scene.load_scene`.
    controller : CascadeController or DesignResult, optional
        None with ``voltage`` given: open loop. None otherwise: :func:`controller_for`. A
        DesignResult runs its ``.controller``.
    reference : Reference, optional
        Position command; default: hold the mid-stroke angle. A sine must be one the run
        resolves (:func:`~.reference_checks.check_sine_frequency`): at most a quarter of the
        controller's sample rate, and at least one whole period in ``duration``.
    duration : float or pint.Quantity
        Seconds.
    method : {"rk4", "paper", "reference", "auto"}
    dt : float or pint.Quantity, optional
        Fixed step (s).
    voltage : float or pint.Quantity, optional
        Open-loop armature voltage (V).
    options : ModelOptions, optional
    feedforward : Feedforward or {"off", "gains", "model"}, optional
        Replaces the controller's feedforward (:func:`with_feedforward`); None keeps it.
        Outside the loop: the margins are the same with and without.
    shaper : InputShaper or {"off", "zv", "zvd"}, optional
        Command shaper on the reference (None keeps the controller's).
    schedule : bool or GainSchedule, optional
        Gains scheduled along the stroke (None keeps the controller's).
    **run_options
        Passed to :func:`servo_toolkit.sim.run` (``output_dt``, ``solver``, ``rtol``, ...).

    Returns
    -------
    SimulationResult

    Raises
    ------
    SceneError
        Before any work, naming the argument: a scene or controller of another type, a
        duration or step that is not a positive number, a sine command the run cannot
        resolve (``reference`` above a quarter of the sample rate, ``duration`` shorter
        than its period).
    """
    scene = as_scene(scene)
    controller = _controller_argument(controller, scene)
    duration = argument_value(duration, "s", "duration")
    if not duration > 0:
        raise SceneError("duration", f"must be positive (got {duration:g} s)")
    dt = None if dt is None else argument_value(dt, "s", "dt")
    if dt is not None and not dt > 0:
        raise SceneError("dt", f"must be positive (got {dt:g} s)")
    if reference is not None and not isinstance(reference, Reference):
        raise SceneError("reference", f"expected a Reference (servo_toolkit.sim.Reference.sine ...), "
                                      f"got {type(reference).__name__}")
    if reference is not None:
        check_reference_output(reference.position_unit, scene)
    if reference is not None and reference.kind == "sine":
        sample_time = scene.sensors.sample_time if controller is None else controller.sample_time
        check_sine_frequency(reference.frequency, sample_time, duration, "reference", duration_key="duration")
    source = "given"
    if voltage is not None:
        if controller is not None:
            raise ValueError("give either a controller or an open-loop voltage, not both")
        if feedforward not in (None, "off") or shaper not in (None, "off") or schedule not in (None, False):
            raise SceneError("feedforward", "a feedforward, shaper or schedule needs a closed loop, not an open-loop "
                                            "voltage")
        reference = Reference.voltage(argument_value(voltage, "V", "voltage"))
    elif controller is None:
        controller, source = controller_for(scene)
    if controller is not None:
        controller = with_feedforward(controller, feedforward, scene, shaper=shaper, schedule=schedule)
    model = build_model(scene, controller, options)
    result = run(model, reference or Reference(), duration, method, dt, **run_options)
    if source != "given":
        result = replace(result, controller=f"{result.controller} [{source}]")
    return result
