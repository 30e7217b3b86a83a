"""Scene files: TOML with units -> validated, frozen component descriptions (the
``[[drivetrain]]`` stages' tables are read by :mod:`.drivetrain_tables`)."""

from __future__ import annotations

import os
import tomllib
import warnings
from dataclasses import dataclass, field
from functools import cached_property
from importlib import resources
from pathlib import Path
from types import MappingProxyType

from ..components.compliance import Load
from ..components.motor import DCMotor
from ..components.platform.geometry import CrossedArchPlatform
from ..components.roller_screw.stages import RollerScrewOperating, RollerScrewStage
from ..components.stages import STAGE_KINDS  # noqa: F401 - the scene's stage kinds
from ..errors import SceneError, SceneWarning
from ..core.fields import Fields, collecting_notes, require
from ..drivetrain.elements import stage_units
from ..display.units import DisplayUnits, display_units_from_table
from .drivetrain_tables import (_built, _check_load_not_mass, _output_is_travel, _stage,
                                _stage_outputs_travel, check_stage_order, check_stroke_stage)
from .tables import ROBUSTNESS_METHODS, SPEED_ESTIMATORS, Requirements, Robustness, Sensors, Study  # noqa: F401

MECHANISM_KINDS = {"crossed_arch_platform": CrossedArchPlatform}
_TOP_KEYS = {"name", "description", "motor", "drivetrain", "load", "sensors", "requirements",
             "studies", "mechanism", "stages", "operating", "robustness", "duty_cycle", "display", "tolerances"}
#: where a scene keeps its derived quantities (:meth:`Scene.derived`) in its ``__dict__``
_DERIVED = "_derived"
#: the entries of a scene's ``__dict__`` that are derived from its fields, not fields
_CACHED = ("drivetrain", _DERIVED)


@dataclass(frozen=True, repr=False)
class Scene:
    """A validated actuator description. Everything is SI.

    Attributes
    ----------
    name, description : str
    motor : DCMotor or None
    stages : tuple
        Drivetrain stages from the motor to the load.
    stage_friction : tuple of StageFriction or None
        Friction at each stage's output (:class:`~servo_toolkit.components.stage_friction.StageFriction`,
        one per stage, None where a stage gives none); empty when no stage gives any.
    load : Load
    sensors : Sensors
    requirements : Requirements
    studies : mapping of str to Study
    mechanism : object or None
        A multi-DOF mechanism (``[mechanism]``), e.g. :class:`CrossedArchPlatform`.
    roller_screw : tuple of RollerScrewStage
        ``[[stages]]`` of a roller-screw scene.
    operating : RollerScrewOperating or None
    robustness : Robustness or None
        ``[robustness]``: variations the loop must tolerate (None: the scene states none).
    duty_cycle : DutyCycle or None
        ``[duty_cycle]``: the motion the actuator repeats in service, for the sizing
        (:mod:`servo_toolkit.scene.duty_cycle`).
    display : DisplayUnits
        ``[display]``: the units a reader is shown for a stiffness and an inertia at the
        output (default SI); only tables, figures and text change, never the values.
    tolerances : Tolerances or None
        ``[tolerances]`` and the ``[robustness]`` ranges as distributions of scene keys
        (:mod:`servo_toolkit.scene.tolerances`); None when the scene has neither.
    source : str or None
        File the scene was read from.
    notes : tuple of str
        What the loader read that the user may not have meant: a bare number far outside its
        key's typical values, read in the key's SI unit (``sensors.sample_time = 0.2`` is
        0.2 s). :func:`load_scene` also issues each as a :class:`~servo_toolkit.errors.SceneWarning`.
    """

    name: str
    description: str = ""
    motor: DCMotor | None = None
    stages: tuple = ()
    stage_friction: tuple = ()
    load: Load = field(default_factory=Load)
    sensors: Sensors = field(default_factory=Sensors)
    requirements: Requirements = field(default_factory=Requirements)
    studies: MappingProxyType = field(default_factory=lambda: MappingProxyType({}))
    mechanism: object = None
    roller_screw: tuple = ()
    operating: RollerScrewOperating | None = None
    robustness: Robustness | None = None
    duty_cycle: object = None
    display: DisplayUnits = field(default_factory=DisplayUnits)
    source: str | None = None
    tolerances: object = None
    notes: tuple = ()

    def study(self, name: str) -> Study:
        """The study called ``name``; a SceneError lists the available ones."""
        if name not in self.studies:
            raise SceneError(f"studies.{name}", f"no such study; the scene has {sorted(self.studies)}")
        return self.studies[name]

    def studies_of_kind(self, kind: str) -> list[Study]:
        """All studies of one kind, in file order."""
        return [s for s in self.studies.values() if s.kind == kind]

    @property
    def input_files(self) -> tuple:
        """The files the scene was read from: its TOML file (when it has one) and the points
        files of its ``[duty_cycle]`` (as read). A command's outputs never replace one of them."""
        points = tuple(s.path for s in getattr(self.duty_cycle, "segments", ()) if getattr(s, "path", None))
        return ((self.source,) if self.source else ()) + points

    @cached_property
    def drivetrain(self):
        """The reflected drivetrain (motor, stages, load); see :mod:`servo_toolkit.drivetrain.reflected`.
        Built once per scene object (a changed scene is a new object: :func:`replace_params`)."""
        from ..drivetrain.reflected import Drivetrain
        return Drivetrain.from_scene(self)

    def derived(self, key, compute):
        """The scene's derived quantity ``key``: ``compute()`` the first time it is asked
        for, the same object afterwards (e.g. the linear plant's parameters at an operating
        point). The values live with this scene object, never in its equality, repr or
        pickle; a value must be immutable. Two threads asking at once may both compute it,
        and both get the value stored first.

        Parameters
        ----------
        key : hashable
            Names the quantity and every argument it depends on besides the scene.
        compute : callable
            Takes no argument; returns the value.
        """
        cache = self.__dict__.get(_DERIVED)
        if cache is None:
            cache = self.__dict__.setdefault(_DERIVED, {})
        try:
            return cache[key]
        except KeyError:
            return cache.setdefault(key, compute())

    def __getstate__(self):
        """The fields only: a pickled scene (a process pool's, a cluster's) carries none of
        its derived quantities; its copy computes them again."""
        return {k: v for k, v in self.__dict__.items() if k not in _CACHED}

    def __repr__(self) -> str:
        from .card import scene_line
        return f"<Scene {scene_line(self)}>"

    def _repr_html_(self) -> str:
        from .card import scene_card
        return scene_card(self)


def _study(name: str, table, output_unit: str = "rad") -> Study:
    from .study_schema import study_params
    kind, params = study_params(name, table, output_unit)
    return Study(name=name, kind=kind, params=MappingProxyType(params))


def scene_from_dict(data: dict, source: str | None = None) -> Scene:
    """Build a :class:`Scene` from parsed TOML.

    Raises
    ------
    SceneError
        With the key path and the rule broken.
    """
    try:
        with collecting_notes() as notes:
            scene = _scene_of(data, source)
        return replace_params(scene, notes=tuple(notes)) if notes else scene
    except SceneError as exc:
        raise exc.with_source(source) if source else exc from None


def _scene_of(data: dict, source: str | None) -> Scene:
    """The scene of :func:`scene_from_dict` (errors without their file)."""
    unknown = sorted(set(data) - _TOP_KEYS)
    require(not unknown, unknown[0] if unknown else "", f"unknown top-level key; known: {sorted(_TOP_KEYS)}")
    name = data.get("name")
    require("name" in data, "name", "missing key (required): a non-empty string")
    require(isinstance(name, str) and name.strip(), "name", f"expected a non-empty string, got {name!r}")
    motor = DCMotor.from_table(Fields(data["motor"], "motor")) if "motor" in data else None
    raw_stages = data.get("drivetrain", [])
    require(isinstance(raw_stages, list), "drivetrain", "must be an array of tables [[drivetrain]]")
    built = [_stage(t, i, travel) for i, (t, travel) in enumerate(zip(raw_stages, _stage_outputs_travel(raw_stages)))]
    stages = tuple(b[0] for b in built)
    stage_friction = tuple(b[1] for b in built) if any(b[1] is not None for b in built) else ()
    check_stage_order(raw_stages)
    check_stroke_stage(raw_stages)
    forward = [i for i, s in enumerate(stages) if s.direction == "forward"]
    require(not forward or forward[-1] == len(stages) - 1 and len(forward) == 1,
            f"drivetrain[{forward[0] if forward else 0}].kind", "a cam must be the last stage")
    if stages:
        require(motor is not None, "motor", "missing key (required): a drivetrain needs a motor")
    linear = bool(stages) and not forward and stage_units(stages)[0][-1] == "m"
    if not linear:
        _check_load_not_mass(data.get("load"), raw_stages)
    load = Load.from_table(Fields(data["load"], "load"), linear) if "load" in data else Load()
    sensors = Sensors.from_table(Fields(data["sensors"], "sensors"), linear) if "sensors" in data else Sensors()
    req = (Requirements.from_table(Fields(data["requirements"], "requirements"))
           if "requirements" in data else Requirements())
    studies = data.get("studies", {})
    require(isinstance(studies, dict), "studies", "must be a table of [studies.NAME] tables")
    mechanism = None
    if "mechanism" in data:
        f = Fields(data["mechanism"], "mechanism")
        kind = f.text("kind")
        require(kind in MECHANISM_KINDS, f.key("kind"),
                f"unknown mechanism kind {kind!r}; known: {sorted(MECHANISM_KINDS)}")
        mechanism = MECHANISM_KINDS[kind].from_table(f)
    raw_rs = data.get("stages", [])
    require(isinstance(raw_rs, list), "stages", "must be an array of tables [[stages]]")
    roller = tuple(RollerScrewStage.from_table(Fields(t, f"stages[{i}]"), i == 0)
                   for i, t in enumerate(raw_rs))
    operating = (RollerScrewOperating.from_table(Fields(data["operating"], "operating"))
                 if "operating" in data else None)
    robust = (Robustness.from_table(Fields(data["robustness"], "robustness"))
              if "robustness" in data else None)
    require(bool(stages or mechanism or roller), "drivetrain",
            "the scene describes nothing to drive: give [[drivetrain]], [mechanism] or [[stages]]")
    unit = ("m" if motor is not None and stages and _output_is_travel(raw_stages) else "rad")
    req.time.check_output(unit == "m")  # a position in the output's dimension, before any work
    scene = Scene(name=name, description=str(data.get("description", "")), motor=motor,
                  stages=stages, stage_friction=stage_friction, load=load, sensors=sensors, requirements=req,
                  studies=MappingProxyType({k: _study(k, v, unit) for k, v in studies.items()}),
                  mechanism=mechanism, roller_screw=roller, operating=operating, robustness=robust,
                  duty_cycle=_duty_cycle(data, stages, unit, source),
                  display=display_units_from_table(Fields(data.get("display", {}), "display"), unit == "m"),
                  source=source)
    if stages:
        _built("drivetrain", scene.drivetrain.check)
        from .study_stroke import check_study_amplitudes
        check_study_amplitudes(scene)
    if scene.duty_cycle is not None:
        from .duty_cycle import check_positions
        drive = scene.drivetrain
        check_positions(scene.duty_cycle, drive.stroke, drive.mid_stroke, unit)
    if "tolerances" in data or robust is not None:
        from .tolerances import tolerances_of
        scene = replace_params(scene, tolerances=tolerances_of(data, source, robust, scene, scene_from_dict))
    return scene


def _duty_cycle(data: dict, stages: tuple, unit: str, source):
    """The scene's ``[duty_cycle]`` (None when absent); it needs a motor-driven drivetrain."""
    if "duty_cycle" not in data:
        return None
    from .duty_cycle import duty_cycle_from_table
    require(bool(stages), "duty_cycle", "a duty cycle needs a motor-driven drivetrain ([motor] and [[drivetrain]])")
    return duty_cycle_from_table(data["duty_cycle"], unit, source)


def default_scene_path() -> Path:
    """Path of the built-in reference EMA scene (package data)."""
    return Path(str(resources.files("servo_toolkit") / "data" / "ema_reference.toml"))


def load_scene(path=None) -> Scene:
    """Read and validate a scene file.

    Parameters
    ----------
    path : str or path-like, optional
        TOML scene file; ``None`` loads the built-in reference EMA.

    Returns
    -------
    Scene

    Raises
    ------
    SceneError
        The file is missing or malformed, or a value breaks a rule; the message names the
        key path and the rule.

    Examples
    --------
    >>> scene = load_scene()
    >>> scene.motor.torque_constant
    0.2
    """
    if path is not None and not isinstance(path, (str, os.PathLike)):
        hint = " (a scene's text: scene_from_dict(tomllib.loads(text)))" if isinstance(path, bytes) else ""
        raise SceneError("path", f"expected a file path (str or path-like) or None for the built-in reference "
                                 f"EMA, got {type(path).__name__}{hint}")
    path = default_scene_path() if path is None else Path(path)
    text = read_scene_text(path)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError("(file)", f"not valid TOML: {exc}", str(path)) from None
    except RecursionError:
        raise SceneError("(file)", "not a scene: tables or arrays nested too deeply", str(path)) from None
    except ValueError as exc:  # e.g. an integer of thousands of digits
        raise SceneError("(file)", f"not valid TOML: {exc}", str(path)) from None
    depth = _depth(data)
    if depth > MAX_DEPTH:
        raise SceneError("(file)", f"not a scene: nested {depth} levels deep (a scene needs at most {MAX_DEPTH})",
                         str(path))
    scene = scene_from_dict(data, str(path))
    for note in scene.notes:
        warnings.warn(f"{path}: {note}", SceneWarning, stacklevel=2)
    return scene


#: largest scene file read (bytes): a scene is a few kilobytes of text
MAX_SCENE_BYTES = 4 * 1024 * 1024
#: deepest nesting of tables and arrays in a scene
MAX_DEPTH = 12


def read_scene_text(path: Path) -> str:
    """The scene file's text: a regular file of UTF-8 text, at most :data:`MAX_SCENE_BYTES`.

    Raises
    ------
    SceneError
        Key ``(file)``, naming the file: missing, not a regular file, too large, not UTF-8.
    """
    from ..core.inputs import read_input_text
    return read_input_text(path, "(file)", MAX_SCENE_BYTES, source=str(path), what="scene")


def _depth(obj, level: int = 0) -> int:
    """Nesting depth of tables and arrays (iterative: no recursion limit)."""
    deepest, stack = level, [(obj, level)]
    while stack:
        item, d = stack.pop()
        deepest = max(deepest, d)
        if d > MAX_DEPTH:
            break
        if isinstance(item, dict):
            stack.extend((v, d + 1) for v in item.values())
        elif isinstance(item, list):
            stack.extend((v, d + 1) for v in item)
    return deepest


def scene_keys(scene):
    """The numeric keys of a scene read from a file (:class:`~.key_paths.SceneKeys`): its
    tolerances' when it has them, else its file's."""
    from .key_paths import SceneKeys
    if scene.tolerances is not None:
        return scene.tolerances.scene_keys()
    if not scene.source:
        raise SceneError("scene", "naming scene keys needs a scene read from a file (load_scene)")
    return SceneKeys(tomllib.loads(read_scene_text(Path(scene.source))), scene.source, scene_from_dict)


def replace_params(scene: Scene, **changes) -> Scene:
    """A copy of ``scene`` with top-level fields replaced (studies never edit scenes)."""
    from dataclasses import replace
    return replace(scene, **changes)


__all__ = ["Robustness", "Scene", "Sensors", "Requirements", "Study", "load_scene", "read_scene_text",
           "scene_from_dict", "scene_keys", "default_scene_path", "replace_params"]
