"""From a scene's named study (or the defaults) to a reference, a duration and options."""

from __future__ import annotations

import math

from ...core.output_units import DEFAULT_RUN_S, REQUIREMENT_SINE_DEG, REQUIREMENT_SINE_HZ, REQUIREMENT_SINE_MM
from ...errors import SceneError
from ...sim.reference import Reference
from ...sim.reference_checks import check_sine_frequency
from ..kv.kind import KV
from .kind import SIMULATE

#: default closed-loop run: the requirement sine of seed 000 (8 Hz, 2 deg) for 1 s
DEFAULT_SINE = (math.radians(REQUIREMENT_SINE_DEG), REQUIREMENT_SINE_HZ, DEFAULT_RUN_S)
#: its amplitude for an output travel (m): 1 mm
DEFAULT_LINEAR_AMPLITUDE = REQUIREMENT_SINE_MM * 1e-3


def run_spec(scene, study_name=None, *, amplitude=None, frequency=None, duration=None):
    """``(reference, duration, voltage, method, dt)`` for a study name or the default.

    Open-loop studies (a ``voltage`` parameter) give ``reference=None`` and the voltage.
    The default is :data:`DEFAULT_SINE`, with :data:`DEFAULT_LINEAR_AMPLITUDE` for an
    output travel. ``amplitude`` (SI: rad or m) and ``frequency`` (Hz) replace the sine's;
    ``duration`` (s), when given, is the run's length the frequency is checked against.

    Raises
    ------
    SceneError
        The sine's frequency is outside what the run resolves (:func:`check_sine_frequency`):
        key ``--frequency`` for ``frequency``, else ``studies.NAME.frequency``.
    """
    spec = _spec(scene, study_name)
    if amplitude is None and frequency is None:
        _check_spec(scene, spec, study_name, duration)
        return spec
    reference, duration_, voltage, method, dt = spec
    if reference is None:
        raise SceneError(f"studies.{study_name}", "is an open-loop voltage run: --amplitude and --frequency "
                         "apply to a sine command only")
    amp = reference.amplitude if amplitude is None else float(amplitude)
    freq = reference.frequency if frequency is None else float(frequency)
    if study_name is not None and frequency is not None:
        duration_ = max(duration_, 3.0 / freq)
    spec = Reference.sine(amp, freq), duration_, voltage, method, dt
    _check_spec(scene, spec, study_name, duration, "--frequency" if frequency is not None else None)
    return spec


def _check_spec(scene, spec, study_name, duration=None, key=None):
    reference, run_duration = spec[0], spec[1]
    if reference is None or reference.kind != "sine":
        return
    key = key or (f"studies.{study_name}.frequency" if study_name is not None else "frequency")
    check_sine_frequency(float(reference.frequency), float(scene.sensors.sample_time),
                         float(run_duration if duration is None else duration), key)


def _spec(scene, study_name):
    if study_name is None:
        amp, freq, dur = DEFAULT_SINE
        if scene.drivetrain.output_is_linear:
            amp = DEFAULT_LINEAR_AMPLITUDE
        return Reference.sine(amp, freq), dur, None, None, None
    study = scene.study(study_name)
    p = study.params
    method = p.get("method")
    dt = p.get("sample_time") if study.kind == SIMULATE.name else None
    if "voltage" in p:
        return None, float(p.get("duration", 1.0)), float(p["voltage"]), method, dt
    freq = p.get("frequency")
    if freq is None and "period" in p:
        freq = 1.0 / p["period"]
    amp = p.get("amplitude")
    if amp is None and p.get("amplitudes"):
        amp = p["amplitudes"][0]
    if study.kind == KV.name and amp is not None:  # a motor-gear amplitude moves the output by A / N
        from ..kv.study import output_amplitudes
        amp = output_amplitudes(scene, study, [amp])[0]
    if isinstance(p.get("frequencies"), dict):
        freq = freq or p["frequencies"].get("start")
    if amp is None or freq is None:
        raise SceneError(study.key("kind"), f"study kind {study.kind!r} has no amplitude/frequency "
                         "or voltage that a time simulation can use")
    duration = float(p.get("duration", max(1.0, 3.0 / freq)))
    return Reference.sine(float(amp), float(freq)), duration, None, method, dt
