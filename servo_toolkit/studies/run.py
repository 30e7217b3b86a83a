"""Run study NAME of a scene: the one place that maps a ``[studies.NAME]`` table (or a
built-in study of a seed-mechanism scene) to the function that runs it.

A study runs through its kind's descriptor (:class:`~servo_toolkit.scene.study_kind.StudyKind`,
registered in :func:`~servo_toolkit.scene.study_kind.study_kinds`): its ``run`` function,
``run(scene, study, **options)``, gives its ``result``. The built-in kinds:

- ``kv``: :func:`.kv.study.kv_study`, giving a :class:`.kv.result.KvResult`;
- ``frequency_sweep``: :func:`.sweep.compute.sweep`, giving a :class:`.sweep.result.SweepResult`;
- ``simulate``: :func:`.time.run.simulate_study`, giving a
  :class:`~servo_toolkit.sim.result.SimulationResult`;
- a seed-mechanism study (cam, platform, roller screw; see :mod:`.mechanisms.dispatch`):
  :func:`.mechanisms.dispatch.run_mechanism`, giving the mechanism's own result.

``run_study(scene, name, as_kind="simulate")`` runs a sine study of another kind (a ``kv``
study's sine) as a time simulation, as ``servo-toolkit simulate --study NAME`` does: a kind
whose descriptor has ``runs_other_kinds`` runs the studies of other kinds. The command line
and the report call these functions; a notebook can too::

    import servo_toolkit as st
    scene = st.load_scene("scenes/ema_reference.toml")
    result = st.run_study(scene, "kv_8hz")
"""

from __future__ import annotations

from ..errors import SceneError
from ..scene.study_kind import study_kind, study_kinds
from .mechanisms.dispatch import ROLLER_SCREW_STUDIES, handles, run_mechanism


def runnable_kinds() -> list:
    """Names of the registered kinds that run on their own (not only as a seed-mechanism
    study of a matching scene), in registry order."""
    return [name for name, kind in study_kinds().items() if not kind.mechanism_only]


def has_motor_drivetrain(scene) -> bool:
    """True when the scene has a motor-driven drivetrain (a loop to design)."""
    try:
        scene.drivetrain  # noqa: B018 - raises for a mechanism-only scene
    except SceneError:
        return False
    return True


def builtin_studies(scene) -> tuple:
    """Names of the built-in studies of ``scene`` (not in its file): the roller screw's."""
    return ROLLER_SCREW_STUDIES if getattr(scene, "roller_screw", ()) else ()


def study_names(scene) -> list:
    """Every study name of ``scene``: its file's, then the built-in ones."""
    return sorted(scene.studies) + [s for s in builtin_studies(scene) if s not in scene.studies]


def mechanism_studies(scene) -> list:
    """Names of the scene's seed-mechanism studies (file order, then built-in)."""
    names = [name for name, study in scene.studies.items() if handles(scene, study)]
    return names + [s for s in builtin_studies(scene) if s not in names]


def default_study(scene):
    """The study a study-running command runs when none is named on a scene without a
    motor-driven drivetrain (its first seed-mechanism study), else None."""
    if has_motor_drivetrain(scene):
        return None
    found = mechanism_studies(scene)
    return found[0] if found else None


def study_of(scene, name: str):
    """The :class:`~servo_toolkit.scene.Study` named ``name``, or the name of a built-in
    study.

    Raises
    ------
    SceneError
        ``studies.NAME``: no such study; the message lists the scene's studies.
    """
    if name in scene.studies:
        return scene.studies[name]
    if name in builtin_studies(scene):
        return name
    built = [s for s in builtin_studies(scene) if s not in scene.studies]
    extra = f" and the built-in mechanism studies {built}" if built else ""
    raise SceneError(f"studies.{name}", f"no such study; the scene has {sorted(scene.studies)}{extra}")


def is_mechanism_study(scene, name: str) -> bool:
    """True when study ``name`` of ``scene`` is run by a seed-mechanism model."""
    return handles(scene, study_of(scene, name))


def run_study(scene, name: str, *, as_kind: str | None = None, **options):
    """Run study ``name`` of ``scene``.

    Parameters
    ----------
    scene : Scene
    name : str
        A ``[studies.NAME]`` of the scene, or a built-in study of a roller-screw scene
        (``"efficiency"``, ``"carrier_step"``).
    as_kind : str, optional
        Run the study's motion as this kind instead of its own (e.g. ``"simulate"``: a time
        simulation of a ``kv`` study's sine); a kind whose descriptor has
        ``runs_other_kinds`` (``frequency_sweep``, ``simulate``). Seed-mechanism studies
        always run their own model.
    **options
        Passed to the kind's runner (see the list in this module's documentation): e.g.
        ``method``, ``dt``, ``full``, ``amplitude``, ``frequency`` for ``simulate``;
        ``frequencies``, ``amplitudes``, ``full``, ``executor``, ``progress`` for
        ``frequency_sweep``; ``losses``, ``progress`` for ``kv``; ``method``, ``dt``,
        ``executor`` for a seed-mechanism study.

    Returns
    -------
    result
        The runner's result dataclass (``to_dict()``, ``table()``, ``plot()``).

    Raises
    ------
    SceneError
        ``studies.NAME``: no such study, or a kind that cannot run as asked.
    """
    study = study_of(scene, name)
    if handles(scene, study):
        return run_mechanism(scene, study, **options)
    kind = study_kind(as_kind or study.kind, study.key("kind"))
    if kind.mechanism_only:
        raise SceneError(study.key("kind"), f"is {study.kind!r}, which runs only as a seed-mechanism study of a "
                         f"matching scene; runnable kinds: {', '.join(runnable_kinds())}")
    if kind.name != study.kind and not kind.runs_other_kinds:
        raise SceneError(study.key("kind"), f"is {study.kind!r}; only studies of kind {kind.name!r} run as {kind.name} "
                         f"studies ({study_kind(study.kind).commands} runs it)")
    return kind.resolve("run")(scene, study, **options)


__all__ = ["builtin_studies", "default_study", "has_motor_drivetrain", "is_mechanism_study",
           "mechanism_studies", "run_study", "runnable_kinds", "study_names", "study_of"]
