"""Scene files: TOML with units -> validated, frozen component descriptions."""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from types import MappingProxyType

from ..components.ball_screw import BallScrew
from ..components.cam.geometry import Cam
from ..components.compliance import Compliance, Load
from ..components.gear import GearTrain
from ..components.linkage import RockerLinkage
from ..components.motor import DCMotor
from ..components.platform.geometry import CrossedArchPlatform
from ..components.roller_screw.stages import RollerScrew, RollerScrewOperating, RollerScrewStage
from ..errors import SceneError
from ..core.fields import Fields, require
from ..core.ranges import VARIED
from ..drivetrain.elements import stage_units
from ..display.units import DisplayUnits, display_units_from_table
from .tracking import tracking_error as _tracking_error

#: speed signals the speed loop can use (``[sensors] speed_estimator``)
SPEED_ESTIMATORS = ("ideal", "difference", "kalman")
STAGE_KINDS = {"gear": GearTrain, "ball_screw": BallScrew, "rocker_linkage": RockerLinkage,
               "compliance": Compliance, "cam": Cam, "roller_screw": RollerScrew}
STUDY_KINDS = ("kv", "frequency_sweep", "simulate", "inverse_dynamics", "mechanism_sweep")
MECHANISM_KINDS = {"crossed_arch_platform": CrossedArchPlatform}
_TOP_KEYS = {"name", "description", "motor", "drivetrain", "load", "sensors", "requirements",
             "studies", "mechanism", "stages", "operating", "robustness", "duty_cycle", "display", "tolerances"}
#: ``[robustness] method`` values
ROBUSTNESS_METHODS = ("monte_carlo", "grid")


@dataclass(frozen=True)
class Sensors:
    """Position sensing and sampling.

    Parameters
    ----------
    output_encoder_bits : int
        Output encoder resolution, counts per revolution = 2**bits (0 = ideal).
    motor_encoder_counts : int
        Motor encoder counts per revolution (0 = ideal).
    sample_time : float
        Controller sample time (s); 0 = continuous.
    speed_estimator : str
        Motor speed fed to the speed loop: ``"ideal"`` (the true speed, a tachometer-grade
        signal), ``"difference"`` (backward difference of the motor encoder counts over one
        sample) or ``"kalman"`` (a Kalman filter on the motor encoder counts, see
        :mod:`servo_toolkit.loop.encoder_estimators`). The last two need a motor encoder and a sample time.
    """

    output_encoder_bits: int = 0
    motor_encoder_counts: int = 0
    sample_time: float = 0.0
    speed_estimator: str = "ideal"

    @classmethod
    def from_table(cls, f: Fields) -> "Sensors":
        """Build from a ``[sensors]`` table."""
        s = cls(output_encoder_bits=f.integer("output_encoder_bits", 0, minimum=0),
                motor_encoder_counts=f.integer("motor_encoder_counts", 0, minimum=0),
                sample_time=f.quantity("sample_time", "s", 0.0, rule="nonnegative"),
                speed_estimator=f.text("speed_estimator", "ideal", choices=SPEED_ESTIMATORS))
        f.check_unknown()
        require(s.output_encoder_bits <= 64, f.key("output_encoder_bits"),
                f"must be at most 64 (got {s.output_encoder_bits}): counts per turn are 2**bits")
        require(s.motor_encoder_counts <= 2**40, f.key("motor_encoder_counts"),
                f"must be at most 2**40 (got {s.motor_encoder_counts})")
        require(s.sample_time <= 1.0, f.key("sample_time"), f"must be at most 1 s (got {s.sample_time:g} s)")
        if s.speed_estimator != "ideal" and (s.motor_encoder_counts == 0 or s.sample_time == 0):
            raise SceneError(f.key("speed_estimator"), f"{s.speed_estimator!r} estimates the speed "
                             "from motor encoder counts: it needs motor_encoder_counts > 0 and "
                             "sample_time > 0")
        return s


@dataclass(frozen=True)
class Requirements:
    """Loop requirements; ``None`` where the scene sets none.

    Bandwidth in Hz, angles in rad, levels in dB.
    """

    bandwidth: float | None = None
    max_phase_lag_at_bandwidth: float | None = None
    min_gain_margin: float | None = None
    min_phase_margin: float | None = None
    max_sensitivity_peak: float | None = None

    @classmethod
    def from_table(cls, f: Fields) -> "Requirements":
        """Build from a ``[requirements]`` table."""
        def opt(name, unit, rule="positive"):
            return f.quantity(name, unit, rule=rule) if f.has(name) else None
        r = cls(bandwidth=opt("bandwidth", "Hz"),
                max_phase_lag_at_bandwidth=opt("max_phase_lag_at_bandwidth", "rad"),
                min_gain_margin=opt("min_gain_margin", "dB", "nonnegative"),
                min_phase_margin=opt("min_phase_margin", "rad"),
                max_sensitivity_peak=opt("max_sensitivity_peak", "dB"))
        f.check_unknown()
        require(r.min_phase_margin is None or r.min_phase_margin < 3.141592653589793,
                f.key("min_phase_margin"), "must be below 180 deg: a phase margin lies in [-180, 180) deg")
        return r


@dataclass(frozen=True)
class Robustness:
    """Parameter variations the loop must tolerate, and what it must achieve over them.

    Variations are at the design operating point: ``load_inertia`` replaces the load's
    inertia (kg*m^2 at the output), ``stiffness`` multiplies the drivetrain's series
    stiffness. A margin left ``None`` defaults to the nominal ``[requirements]`` one (see
    :func:`servo_toolkit.loop.requirements.robust_requirements`).

    Parameters
    ----------
    load_inertia : tuple of float or None
        (lo, hi) in kg*m^2, 0 <= lo <= hi.
    stiffness : tuple of float or None
        (lo, hi) factors, 0 < lo <= hi.
    samples : int
        Variants in total (Monte Carlo draws, or grid points spread over the axes).
    method : str
        ``"monte_carlo"`` (uniform, seeded) or ``"grid"`` (corners included).
    seed : int
    min_stable_fraction : float
        Fraction of the variants whose closed loop must be stable, 0..1.
    min_gain_margin, max_sensitivity_peak : float or None
        Worst case over the stable variants (dB).
    min_phase_margin : float or None
        Worst case (rad).
    min_bandwidth : float or None
        Worst-case closed-loop bandwidth (Hz); not checked when ``None``.
    max_tracking_error : float or None
        Worst |output - command| over the nonlinear time runs of the variants
        (``servo-toolkit montecarlo``; rad, or m for an output travel); not checked when
        ``None``.
    tracking_error_dimension : str or None
        ``"angle"`` or ``"length"`` as the scene gave it (None for a bare SI number).
    max_peak_current : float or None
        Worst peak motor current over those runs (A); not checked when ``None``.
    min_yield : float or None
        Fraction of the built actuators (the ranges drawn as tolerances,
        :mod:`servo_toolkit.scene.tolerances`) that must meet every requirement; ``check``
        gates on the lower end of its confidence interval. Not checked when ``None``.
    """

    load_inertia: tuple | None = (0.0, 4.0)
    stiffness: tuple | None = (0.7, 1.3)
    samples: int = 1000
    method: str = "monte_carlo"
    seed: int = 0
    min_stable_fraction: float = 1.0
    min_gain_margin: float | None = None
    min_phase_margin: float | None = None
    max_sensitivity_peak: float | None = None
    min_bandwidth: float | None = None
    max_tracking_error: float | None = None
    tracking_error_dimension: str | None = None
    max_peak_current: float | None = None
    min_yield: float | None = None

    @property
    def ranges(self) -> dict:
        """name -> (lo, hi) of the parameters that vary."""
        return {k: v for k, v in (("load_inertia", self.load_inertia), ("stiffness", self.stiffness))
                if v is not None}

    @classmethod
    def from_table(cls, f: Fields) -> "Robustness":
        """Build from a ``[robustness]`` table."""
        known = {"load_inertia", "stiffness", "samples", "method", "seed", "min_stable_fraction",
                 "min_gain_margin", "min_phase_margin", "max_sensitivity_peak", "min_bandwidth",
                 "max_tracking_error", "max_peak_current", "min_yield"}
        unknown = sorted(set(f.table) - known)
        require(not unknown, f.key(unknown[0]) if unknown else "", f"unknown key; known keys are {sorted(known)}")

        def span(name, unit, positive):
            if not f.has(name):
                return None
            lo_hi = f.quantity_list(name, unit, rule="positive" if positive else "nonnegative", bounds=VARIED[name])
            require(len(lo_hi) == 2, f.key(name), f"expected [lo, hi], got {len(lo_hi)} values")
            require(lo_hi[0] <= lo_hi[1], f.key(name), f"lo must not exceed hi (got {lo_hi[0]:g} > {lo_hi[1]:g})")
            return lo_hi

        def opt(name, unit, rule="positive"):
            return f.quantity(name, unit, rule=rule) if f.has(name) else None

        load, stiff = span("load_inertia", "kg*m^2", False), span("stiffness", "dimensionless", True)
        require(load is not None or stiff is not None, f.key("load_inertia"),
                "missing key: give load_inertia and/or stiffness, the ranges to vary")
        samples = f.integer("samples", 1000, minimum=1)
        require(samples <= 1_000_000, f.key("samples"), f"at most 1000000 variants (got {samples})")
        r = cls(load_inertia=load, stiffness=stiff, samples=samples,
                method=f.text("method", "monte_carlo", choices=ROBUSTNESS_METHODS),
                seed=f.integer("seed", 0, minimum=0),
                min_stable_fraction=f.number("min_stable_fraction", 1.0, rule="nonnegative"),
                min_gain_margin=opt("min_gain_margin", "dB", "nonnegative"),
                min_phase_margin=opt("min_phase_margin", "rad"),
                max_sensitivity_peak=opt("max_sensitivity_peak", "dB"),
                min_bandwidth=opt("min_bandwidth", "Hz"), max_peak_current=opt("max_peak_current", "A"),
                min_yield=f.number("min_yield", rule="positive", bounds=(1e-6, 1.0)) if f.has("min_yield") else None,
                **_tracking_error(f))
        require(r.min_stable_fraction <= 1.0, f.key("min_stable_fraction"),
                f"a fraction of the variants, 0..1 (got {r.min_stable_fraction:g})")
        require(r.min_phase_margin is None or r.min_phase_margin < 3.141592653589793,
                f.key("min_phase_margin"), "must be below 180 deg")
        return r


@dataclass(frozen=True)
class Study:
    """A named study of the scene: its kind and parameters in SI (angles rad, Hz for frequency)."""

    name: str
    kind: str
    params: MappingProxyType

    def get(self, key: str, default=None):
        """A parameter or ``default``."""
        return self.params.get(key, default)

    def key(self, name: str) -> str:
        """Key path of a parameter, for error messages."""
        return f"studies.{self.name}.{name}"


@dataclass(frozen=True, repr=False)
class Scene:
    """A validated actuator description. Everything is SI.

    Attributes
    ----------
    name, description : str
    motor : DCMotor or None
    stages : tuple
        Drivetrain stages from the motor to the load.
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
    """

    name: str
    description: str = ""
    motor: DCMotor | None = None
    stages: tuple = ()
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

    def study(self, name: str) -> Study:
        """The study called ``name``; a SceneError lists the available ones."""
        if name not in self.studies:
            raise SceneError(f"studies.{name}", f"no such study; the scene has {sorted(self.studies)}")
        return self.studies[name]

    def studies_of_kind(self, kind: str) -> list[Study]:
        """All studies of one kind, in file order."""
        return [s for s in self.studies.values() if s.kind == kind]

    @property
    def drivetrain(self):
        """The reflected drivetrain (motor, stages, load); see :mod:`servo_toolkit.drivetrain.reflected`."""
        from ..drivetrain.reflected import Drivetrain
        return Drivetrain.from_scene(self)

    def __repr__(self) -> str:
        from .card import scene_line
        return f"<Scene {scene_line(self)}>"

    def _repr_html_(self) -> str:
        from .card import scene_card
        return scene_card(self)


#: stage kind -> (input, output): ``rotary`` (a shaft angle) or ``travel`` (a linear
#: position); a compliance passes on what it receives. The motor delivers a rotary input.
STAGE_IO = {"gear": ("rotary", "rotary"), "ball_screw": ("rotary", "travel"), "roller_screw": ("rotary", "travel"),
            "rocker_linkage": ("travel", "rotary"), "cam": ("rotary", "travel"), "compliance": (None, None)}


def _built(path: str, build):
    """``build()``; a Python error from a value the table's checks let through becomes a
    SceneError naming the table (any such error is a missing rule)."""
    try:
        return build()
    except SceneError:
        raise
    except (TypeError, ValueError, ArithmeticError, IndexError, KeyError, AttributeError) as exc:
        raise SceneError(path, f"invalid value ({type(exc).__name__}: {exc})") from None


def _stage(table, i: int):
    f = Fields(table, f"drivetrain[{i}]")
    kind = f.text("kind")
    cls = STAGE_KINDS.get(kind)
    require(cls is not None, f.key("kind"), f"unknown stage kind {kind!r}; known: {sorted(STAGE_KINDS)}")
    return _built(f.path, lambda: cls.from_table(f))


def _output_is_travel(raw_stages) -> bool:
    """True when the chain's output coordinate is a travel (it ends in a screw); a chain
    ending in a cam keeps the cam angle as its coordinate."""
    if raw_stages and raw_stages[-1].get("kind") == "cam":
        return False
    have = "rotary"
    for table in raw_stages:
        give = STAGE_IO.get(table.get("kind"), (None, None))[1]
        have = give or have
    return have == "travel"


def check_stage_order(raw_stages) -> None:
    """Each stage's input must be what the previous stage delivers (the motor: a rotary
    shaft): a screw turns a shaft into travel, a linkage travel into an angle."""
    have, prev = "rotary", "the motor"
    for i, table in enumerate(raw_stages):
        kind = table.get("kind")
        need, give = STAGE_IO.get(kind, (None, None))
        require(need is None or need == have, f"drivetrain[{i}].kind",
                f"a {kind} stage takes a {need} input, but {prev} delivers {have} "
                f"({'a screw or cam turns a shaft into travel, a linkage travel into an angle'})")
        if give is not None:
            have, prev = give, f"drivetrain[{i}] ({kind})"


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
        unknown = sorted(set(data) - _TOP_KEYS)
        require(not unknown, unknown[0] if unknown else "", f"unknown top-level key; known: {sorted(_TOP_KEYS)}")
        name = data.get("name")
        require("name" in data, "name", "missing key (required): a non-empty string")
        require(isinstance(name, str) and name.strip(), "name", f"expected a non-empty string, got {name!r}")
        motor = DCMotor.from_table(Fields(data["motor"], "motor")) if "motor" in data else None
        raw_stages = data.get("drivetrain", [])
        require(isinstance(raw_stages, list), "drivetrain", "must be an array of tables [[drivetrain]]")
        stages = tuple(_stage(t, i) for i, t in enumerate(raw_stages))
        check_stage_order(raw_stages)
        forward = [i for i, s in enumerate(stages) if s.direction == "forward"]
        require(not forward or forward[-1] == len(stages) - 1 and len(forward) == 1,
                f"drivetrain[{forward[0] if forward else 0}].kind", "a cam must be the last stage")
        if stages:
            require(motor is not None, "motor", "missing key (required): a drivetrain needs a motor")
        linear = bool(stages) and not forward and stage_units(stages)[0][-1] == "m"
        load = Load.from_table(Fields(data["load"], "load"), linear) if "load" in data else Load()
        sensors = Sensors.from_table(Fields(data["sensors"], "sensors")) if "sensors" in data else Sensors()
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
        scene = Scene(name=name, description=str(data.get("description", "")), motor=motor,
                      stages=stages, load=load, sensors=sensors, requirements=req,
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
            dt = scene.drivetrain
            check_positions(scene.duty_cycle, dt.stroke, dt.mid_stroke, unit)
        if "tolerances" in data or robust is not None:
            from .tolerances import tolerances_of
            scene = replace_params(scene, tolerances=tolerances_of(data, source, robust, scene, scene_from_dict))
        return scene
    except SceneError as exc:
        raise exc.with_source(source) if source else exc from None


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
    return scene_from_dict(data, str(path))


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
