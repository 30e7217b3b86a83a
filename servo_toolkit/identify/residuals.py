"""What a fit compares: the residual vector of a scene against the data, the features the
search starts from, and the noise floor of that vector.

Frequency responses
    Gain difference and wrapped phase difference, each over its own noise at that point
    (:mod:`.noise`: from the coherence and the number of averages, or from the scatter
    about a local fit), so that the floor is 1 and the intervals weigh gain and phase by
    their noise; with the noise unknown, dB and deg times :data:`PHASE_DB_PER_DEG` (one
    neper weighs as one radian), each weighted by sqrt(coherence). Features of a current
    -> speed response (:mod:`.features`).
Voltage-driven time traces
    Current, motor angle and output angle, each divided by its own noise (the scatter of
    its measurement, at least an encoder count's rounding noise), so the floor is 1 and the
    intervals weigh each channel by its noise; each angle's zero fitted (the mean difference
    from the model's), so no one sample's noise shifts a trace; features: the steady gain and time constant of the motor speed (:mod:`.trace_features`).
Closed-loop time traces
    Output position and motor current of the nonlinear closed loop (:mod:`.loop_model`),
    each divided by its own noise (the scatter of its measurement, at least an encoder
    count's rounding noise), so the floor is 1 and the intervals weigh each channel by its
    noise; the residual tested for whiteness and the intervals robust to its correlation in
    time (:mod:`.whiteness`); features: the inverse-dynamics regression of the current.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..errors import SceneError
from .data import FrequencyData, LoopData
from .features import feature_mismatch, response_features
from .loop_model import LoopRun
from .model import frequency_model, time_response
from .noise import FrequencyNoise, frequency_noise
from .trace_features import LoopScales, loop_features, step_features, step_mismatch
from .verdict import bands, scatter_sd
from .whiteness import block_test, clusters

#: dB of log-magnitude per degree of phase with the weight of the complex logarithm
PHASE_DB_PER_DEG = 20 / math.log(10) * math.pi / 180


def wrap_deg(x):
    """Angles wrapped to [-180, 180) deg."""
    return (np.asarray(x) + 180.0) % 360.0 - 180.0


@dataclass(frozen=True)
class Comparison:
    """A scene against one data set.

    Attributes
    ----------
    evaluate : callable
        ``scene -> (model, residual vector, feature mismatch or None)``; one model run.
    floor : float or None
        RMS of the residual vector that the data's own noise leaves (None: too few points).
    blocks : int
        Residual blocks (channels) along ``axis``.
    axis : numpy.ndarray
        Frequencies (Hz) or times from the start (s) of the points.
    unit : str
        ``"Hz"`` or ``"s"``.
    noise : str
        Where the noise floor comes from.
    verify : callable or None
        ``scene -> None``: the checks the evaluations of the search leave out, run once on the
        fitted scene (raises SimulationError).
    whiteness : callable or None
        ``residual vector -> TraceWhiteness``: whether the residual of time traces is their
        noise (:mod:`.whiteness`); None where the data have no time order to test.
    clusters : numpy.ndarray or None
        Each residual's stretch of time, for intervals robust to a residual correlated in
        time (:func:`.whiteness.robust_inflation`); None: the intervals of white noise.
    """

    evaluate: Callable
    floor: float | None
    blocks: int
    axis: np.ndarray
    unit: str
    noise: str = "scatter of the measurement (third differences)"
    verify: Callable | None = None
    whiteness: Callable | None = None
    clusters: np.ndarray | None = None


@dataclass(frozen=True)
class TraceWhiteness:
    """The test of the residual of time traces, channel by channel (:func:`.whiteness.block_test`).

    Attributes
    ----------
    white : bool
        Every channel passes as white noise.
    text : str
        The worst channel's finding (empty when every channel passes).
    windows : tuple of str
        Where the worst channel's block means miss most (times from the start).
    """

    white: bool
    text: str = ""
    windows: tuple = ()


def trace_whiteness(names, measured, noise, time_s):
    """``residual vector -> TraceWhiteness`` of channels ``names`` (their measurements and
    noise standard deviations), each block of the vector in noise units."""
    quanta = [quantum_sd(m) / s for m, s in zip(measured, noise)]
    t = np.asarray(time_s, float) - float(time_s[0])

    def test(residual):
        parts = np.split(np.asarray(residual, float), len(names))
        tests = [(name, block_test(r, m, q)) for name, r, m, q in zip(names, parts, measured, quanta)]
        failed = [(name, bt) for name, bt in tests if bt is not None and not bt.white]
        if not failed:
            return TraceWhiteness(True)
        name, bt = min(failed, key=lambda x: x[1].p_value)
        span = bt.width * float(t[1] - t[0]) if t.size > 1 else 0.0
        text = (f"the residual of {name} is not white noise: its means over {bt.width} samples "
                f"({1e3 * span:.3g} ms) are {bt.ratio:.3g} times what white noise leaves (p = {bt.p_value:.2g})")
        block_t = t[: bt.missed.size * bt.width: bt.width]
        return TraceWhiteness(False, text, tuple(bands(block_t, bt.missed.astype(float), "s")))
    return test


def frequency_residual(h, data: FrequencyData, noise: FrequencyNoise) -> np.ndarray:
    """Residual vector of a model response ``h`` (complex) against ``data``: the gain and the
    wrapped phase differences, each over its own noise (so each is in standard deviations
    and the vector's floor is 1); with the noise unknown, the gain difference in dB and the
    phase difference times :data:`PHASE_DB_PER_DEG`, each weighted by sqrt(coherence)."""
    gain = 20 * np.log10(np.abs(h)) - data.gain_db
    phase = wrap_deg(np.degrees(np.angle(h)) - data.phase_deg)
    if noise.known:
        return np.concatenate([gain / noise.gain_db, phase / noise.phase_deg])
    w = np.sqrt(data.coherence)
    return np.concatenate([w * gain, w * PHASE_DB_PER_DEG * phase])


def frequency(data: FrequencyData, kind: str, base, controller=None) -> Comparison:
    """A frequency response (``kind`` ``plant`` or ``closed_loop``)."""
    model = frequency_model(base, kind, controller)
    features = response_features(data.frequency_hz, data.complex) if kind == "plant" else None
    noise = frequency_noise(data)

    def evaluate(scene):
        h = model(scene, data.frequency_hz)
        m = None if features is None else feature_mismatch(response_features(data.frequency_hz, h), features)
        return h, frequency_residual(h, data, noise), m
    return Comparison(evaluate, 1.0 if noise.known else None, 2, data.frequency_hz, "Hz", noise.basis)


def voltage_traces(data) -> Comparison:
    """Time traces of the voltage-driven linear plant."""
    measured = (data.current_A, data.motor_angle_rad - data.motor_angle_rad[0],
                data.output_angle_rad - data.output_angle_rad[0])
    noise = []
    for name, m in zip(("current_A", "motor_angle_rad", "output_angle_rad"), measured):
        rms = float(np.sqrt(np.mean((m - m.mean()) ** 2)))
        if not rms > 0:
            raise SceneError(name, "is constant in the time traces; nothing to fit it to", data.source)
        sd = scatter_sd(m)
        noise.append(rms if sd is None else max(sd, quantum_sd(m), 1e-9 * rms))
    features = step_features(data.time_s, data.voltage_V, measured[1])

    def evaluate(scene):
        model = time_response(scene, data.time_s, data.voltage_V)
        r = np.concatenate([(y - m - (k > 0) * np.mean(y - m)) / s
                            for k, (y, m, s) in enumerate(zip(model, measured, noise))])
        return model, r, step_mismatch(step_features(data.time_s, data.voltage_V, model[1]), features)
    floor = None if scatter_sd(measured[0]) is None else 1.0
    return Comparison(evaluate, floor, 3, data.time_s - data.time_s[0], "s")


def quantum_sd(values) -> float:
    """The rounding noise of a quantized measurement, its smallest step between distinct
    values over sqrt(12) (an encoder's count; negligible for a continuous one): the floor of
    its noise where the signal rests on a count and its differences vanish."""
    steps = np.diff(np.unique(np.asarray(values, float)))
    return float(steps.min()) / math.sqrt(12.0) if steps.size else 0.0


def loop_traces(data: LoopData, base, controller) -> Comparison:
    """Closed-loop time traces of the nonlinear model (``controller`` held fixed)."""
    loop = LoopRun.for_log(base, controller, data)
    measured = (data.output, data.current_A)
    names = (f"output_{data.unit}", "current_A")
    noise = []
    for name, m in zip(names, measured):
        rms = float(np.sqrt(np.mean((m - m.mean()) ** 2)))
        if not rms > 0:
            raise SceneError(name, "is constant in the time traces; nothing to fit it to", data.source)
        sd = scatter_sd(m)
        noise.append(rms if sd is None else max(sd, quantum_sd(m), 1e-9 * rms))
    scales = LoopScales(data.time_s, data.output, data.current_A)
    features = loop_features(data.time_s, data.output, data.current_A)

    def evaluate(scene):
        model = loop.traces(scene, check=False)
        r = np.concatenate([(y - m) / s for y, m, s in zip(model, measured, noise)])
        return model, r, scales.mismatch(loop_features(data.time_s, *model), features)
    floor = None if scatter_sd(data.output) is None else 1.0
    return Comparison(evaluate, floor, 2, data.time_s - data.time_s[0], "s",
                      verify=lambda scene: loop.traces(scene, check=True),
                      whiteness=trace_whiteness(names, measured, noise, data.time_s),
                      clusters=clusters(data.points, 2))
