"""The seed mechanisms: cam drive (seed 002), deflection platform (003), roller screw (004).

Two functions dispatch a scene's study to its mechanism model; :func:`servo_toolkit.studies.run.run_study` calls
them for the studies below (so do the ``simulate``, ``kv`` and ``sweep`` commands).

=====================  ===============================  ====================================
scene                  study (kind)                     result
=====================  ===============================  ====================================
cam drive (a single    ``constant_speed``               :class:`~servo_toolkit.studies.cam.constant_speed.CamSweepResult`
``cam`` stage)         (mechanism_sweep)
                       ``constant_voltage`` (simulate)  :class:`~servo_toolkit.studies.cam.voltage_result.CamVoltageResult`
crossed-arch platform  ``ramp`` (inverse_dynamics)      :class:`~.platform.PlatformRampResult`
roller-screw           ``efficiency`` (default, built   :class:`~.roller_screw.EfficiencyResult`
``[[stages]]``         in: figures 9-10 of the seed)
                       ``carrier_step`` (built in:      :class:`~.roller_screw.CarrierStepResult`
                       the single-stage check)
=====================  ===============================  ====================================

The platform is also a plant: :func:`platform_plant` gives its linear MIMO model (motor
torques in, tilts and motor angles out) at an operating point.

Studies are matched by kind and scene content, so any ``mechanism_sweep`` / ``simulate``
study of a cam scene, or ``inverse_dynamics`` study of a platform scene, is handled.
"""

from __future__ import annotations

from ...components.cam.geometry import Cam
from ...components.platform.geometry import CrossedArchPlatform
from ...errors import SceneError
from ...plant.platform import platform_plant
from ..time.kind import SIMULATE
from .kind import INVERSE_DYNAMICS, MECHANISM_SWEEP

#: Built-in studies of roller-screw scenes (which have no ``[studies]`` table).
ROLLER_SCREW_STUDIES = ("efficiency", "carrier_step")


def _is_cam(scene) -> bool:
    return len(scene.stages) == 1 and isinstance(scene.stages[0], Cam) and scene.motor is not None


def _kind(scene, study):
    """(name, kind, Study or None) of ``study`` in ``scene``."""
    if isinstance(study, str):
        if study in scene.studies:
            s = scene.studies[study]
            return s.name, s.kind, s
        if scene.roller_screw and study in ROLLER_SCREW_STUDIES:
            return study, study, None
        return study, None, None
    return study.name, study.kind, study


def handles(scene, study) -> bool:
    """True when ``study`` (a Study or its name) of ``scene`` is a seed-mechanism study."""
    _, kind, _ = _kind(scene, study)
    if _is_cam(scene):
        return kind in (MECHANISM_SWEEP.name, SIMULATE.name)
    if isinstance(scene.mechanism, CrossedArchPlatform):
        return kind == INVERSE_DYNAMICS.name
    if scene.roller_screw:
        return kind in ROLLER_SCREW_STUDIES
    return False


def run_mechanism(scene, study, method=None, dt=None, executor=None):
    """Run a seed-mechanism study.

    Parameters
    ----------
    scene : Scene
    study : Study or str
        The study or its name (``"efficiency"`` or ``"carrier_step"`` for roller-screw scenes).
    method : str, optional
        Recorded by the cam's constant-voltage study (both its methods always run).
    dt : float, optional
        Step (s) overriding the study's ``sample_time``.
    executor : concurrent.futures.Executor, optional
        For the roller-screw cases.

    Returns
    -------
    result
        A result dataclass with ``to_dict()``, ``table()`` and ``plot()``.

    Raises
    ------
    SceneError
        When the study is not a seed-mechanism study of this scene.
    """
    name, kind, st = _kind(scene, study)
    if not handles(scene, study):
        raise SceneError(f"studies.{name}", "not a seed-mechanism study of this scene "
                         f"(cam, platform or roller-screw studies; roller screws: {list(ROLLER_SCREW_STUDIES)})")
    get = st.get if st is not None else (lambda key, default=None: default)
    if _is_cam(scene):
        from ...components.cam.drive import CamDrive
        from ..cam.constant_speed import constant_speed
        drive = CamDrive.from_scene(scene)
        if kind == MECHANISM_SWEEP.name:
            return constant_speed(drive, get("speed", 1.0), dt or get("sample_time", 0.01),
                                  get("gravity_tilts", [drive.cam.gravity_tilt]), get("gravity_headings"))
        from ..cam.estimation import estimation_options
        from ..cam.voltage import constant_voltage
        return constant_voltage(drive, _required(st, "voltage"), get("duration", 3.0),
                                dt or get("sample_time", 1e-3), method=method or get("method"),
                                **estimation_options(scene, st))
    if kind == INVERSE_DYNAMICS.name:
        from ...components.platform.model import PlatformModel
        from .platform import ramp
        return ramp(PlatformModel.from_scene(scene), _required(st, "rate_alpha"), _required(st, "rate_beta"),
                    _required(st, "duration"), get("external_moments", [[0.0, 0.0]]))
    from . import roller_screw
    if kind == "carrier_step":
        return roller_screw.carrier_step(scene)
    return roller_screw.efficiency_study(scene, executor=executor)


def _required(study, key):
    value = study.get(key)
    if value is None:
        raise SceneError(study.key(key), "missing key (required)")
    return value


__all__ = ["handles", "run_mechanism", "platform_plant", "ROLLER_SCREW_STUDIES"]
