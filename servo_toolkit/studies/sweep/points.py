"""Frequencies and amplitudes of a sweep study (``[studies.NAME]`` of kind ``frequency_sweep``)."""

from __future__ import annotations

import math

import numpy as np

from ...errors import SceneError
from ...core.output_units import REQUIREMENT_SINE_DEG, REQUIREMENT_SINE_HZ, output_unit
from .kind import SWEEP
from ...scene.study_kind import study_kind

#: the seed's key frequency, always in the default sweep
DEFAULT_FREQUENCY_HZ = REQUIREMENT_SINE_HZ
#: command amplitude when the scene has no sweep study (seed 000's 8 Hz case); an output
#: travel takes 1 mm (:attr:`servo_toolkit.core.output_units.OutputUnit.default_amplitude`)
DEFAULT_AMPLITUDE = math.radians(REQUIREMENT_SINE_DEG)


#: most frequencies a sweep study's ``{start, stop, points}`` table may give
MAX_POINTS = 100_000


def study_points(scene, study=None):
    """``(name, frequencies_hz, amplitudes_rad)`` of a sweep study.

    ``study=None`` takes the scene's first ``frequency_sweep`` study; without one, 8 Hz at
    2 deg (1 mm for an output travel). The seed's 8 Hz is always added to a study's frequencies (callers that give
    frequencies explicitly replace the whole list). A study gives ``amplitude`` or
    ``amplitudes``, and ``frequencies`` as a list or a table ``{start, stop, points,
    spacing = "log" | "linear"}`` (or ``frequency``).

    Raises
    ------
    SceneError
        The named study is not of kind ``frequency_sweep`` (key ``studies.NAME.kind``), or
        its amplitudes or frequencies are missing or not positive.
    """
    extra = (DEFAULT_FREQUENCY_HZ,)
    if study is None:
        found = scene.studies_of_kind(SWEEP.name)
        if not found:
            return None, (DEFAULT_FREQUENCY_HZ,), (output_unit(scene).default_amplitude,)
        study = found[0]
    elif isinstance(study, str):
        study = scene.study(study)
    if study.kind != SWEEP.name:
        raise SceneError(study.key("kind"), f"is {study.kind!r}; a sweep runs studies of kind {SWEEP.name!r} "
                         f"({study_kind(study.kind).commands} runs this one)")
    p = study.params
    if p.get("amplitudes"):
        amps = tuple(float(a) for a in p["amplitudes"])
    elif p.get("amplitude") is not None:
        amps = (float(p["amplitude"]),)
    else:
        raise SceneError(study.key("amplitude"), "a sweep needs an amplitude (or amplitudes)")
    spec = p.get("frequencies", p.get("frequency"))
    if isinstance(spec, dict):
        try:
            lo_, hi, n = float(spec["start"]), float(spec["stop"]), int(spec.get("points", 20))
        except KeyError as exc:
            raise SceneError(study.key("frequencies"), f"missing {exc.args[0]!r} (start, stop, points)") from None
        spacing = spec.get("spacing", "log")
        if n > MAX_POINTS:
            raise SceneError(study.key("frequencies"), f"at most {MAX_POINTS} points (got {n})")
        if spacing not in ("log", "linear") or not 0 < lo_ < hi or n < 1:
            raise SceneError(study.key("frequencies"), "needs 0 < start < stop, points >= 1, "
                             "spacing 'log' or 'linear'")
        freqs = np.geomspace(lo_, hi, n) if spacing == "log" else np.linspace(lo_, hi, n)
    elif spec is not None:
        freqs = np.atleast_1d(np.asarray(spec, dtype=float))
    else:
        raise SceneError(study.key("frequencies"), "a sweep needs frequencies (or frequency)")
    if np.any(~np.isfinite(freqs)) or np.any(freqs <= 0) or any(a <= 0 for a in amps):
        raise SceneError(study.key("frequencies"), "frequencies and amplitudes must be positive")
    freqs = np.concatenate([freqs, extra])
    freqs = np.unique(np.round(freqs, 12))
    return study.name, tuple(float(f) for f in freqs), amps


def check_sweep_frequencies(scene, frequencies, key: str, plan) -> None:
    """SceneError naming ``key`` unless every dwell frequency is one the sweep resolves.

    A frequency above a quarter of the controller's sample rate is refused as a time run's
    (:func:`servo_toolkit.sim.reference_checks.check_sine_frequency`); below, a dwell lasts its
    settling and estimation cycles (``plan``, a :class:`~.sine_dwell.DwellPlan`), and a
    frequency whose dwell needs more fixed steps at the sample time than one run may take
    (:data:`servo_toolkit.sim.fixed_run.MAX_STEPS`) cannot run at all.
    """
    from ...sim.fixed_run import MAX_STEPS
    from ...sim.reference_checks import check_sine_frequency
    ts = float(scene.sensors.sample_time)
    for f in frequencies:
        check_sine_frequency(float(f), ts, None, key)
        if ts > 0:
            cycles = sum(plan.cycles(float(f)))
            low = cycles / (ts * MAX_STEPS)
            if not f >= low:
                raise SceneError(key, f"must be at least {low:.3g} Hz: a dwell of {cycles} periods (settling and "
                                      f"estimation) at the {ts:g} s sample time takes more than the {MAX_STEPS:.0e} "
                                      f"steps one run may take (got {float(f):g} Hz)")
