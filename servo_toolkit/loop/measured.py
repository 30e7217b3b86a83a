"""The designed loop closed on a measured plant response (``check --plant-frf``).

What is measured, and what stays the model's
--------------------------------------------
``frf`` estimates the response from the motor current (``current_A``) to one signal of the
rig: the motor angle (``motor_angle_rad``, its default), the motor speed
(``motor_speed_rad_s``) or the output (``output_angle_rad``, ``output_travel_m``). From the
current, it is the mechanics alone, the torque constant in it: ``P(jw)``, motor rad per A.
The scene's loop needs the plant from the current command of the analog current loop to
the two signals the motion controller reads, the output position ``theta`` and the motor
speed ``omega_m``. At every measured frequency:

- ``omega_m = jw P(jw) i`` (kinematics, no model), or the measured speed itself;
- ``theta`` is the measured output, or the motor's measured motion times the model's
  transmission ``theta / omega_m`` (``1 / (N jw)`` for a rigid chain; the two-mass or
  chain model's transmissibility otherwise); a measured output angle gives the motor speed
  through the model's inverse of it;
- the current loop is the scene's, closed on the measured mechanics:
  ``i / i_cmd = Cc / (L jw + R + Cc + Ke jw P)`` with ``Cc = kp + ki / (jw)`` (1 for a
  motor without inductance, whose ideal current loop holds ``i = i_cmd``);
- the motion controller and the sampling delay (1.5 samples, the model's Pade) are the
  design's, evaluated at the measured frequencies.

The open loop broken at the position error, ``L = -K_theta D G_theta / (1 - K_omega D
G_omega)``, and the closed loop ``T = K_ref D G_theta / (1 - D (K_theta G_theta + K_omega
G_omega))`` follow; the model's are evaluated the same way at the same frequencies, so the
model's response is beside the measured one.

Crossings on sampled data
-------------------------
python-control's margins on frequency-response data are not used: a crossing is found
between two measured points, magnitude interpolated linearly in log |L| against log f,
phase unwrapped and interpolated linearly in log f, and reported with the two points that
bracket it (the grid's resolution). A crossing bracketed by a point whose coherence is
below :data:`POOR_COHERENCE` is marked and never decides a requirement.

Nyquist count
-------------
Sampled data cannot show what lies between and outside its points: the open loop's
right-half-plane poles (P) and the encirclements outside the measured band are the
model's. Inside the band the measured curve replaces the model's: the change of
``arg(1 + L)`` along the measured points (joined to the model's at the band's ends) against
the model's own change there gives the difference in encirclements, so
``Z = Z_model - (change_measured - change_model) / pi``. A step between neighbouring points
turning ``1 + L`` by more than 90 deg makes the count ambiguous (stated, no verdict).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ..errors import SceneError
from ..plant.current_loop import sample_delay_block
from .closed_loop import DELAY_SAMPLES
from .crossings import response_of
from .measured_interval import combined, crossing_sd, point_sd, sensitivity
from .measured_mode import find_mode, model_mechanics, signal_responses, system_responses
from .measured_result import Crossing, MeasuredLoop, mismatch_bands, reversed_points, sign_reversed
from .measured_signal import check_signal

#: a point with a coherence below this is poor: it is shown and marked, never decides a row
POOR_COHERENCE = 0.8
#: the measured signals ``--plant-frf-signal`` may name (the output's by its unit)
SIGNALS = ("motor_angle_rad", "motor_speed_rad_s", "output_angle_rad", "output_travel_m")
#: relative step of the response's magnitude, and of the transmission's ratio, for the
#: margins' derivatives
STEP = 1e-6
#: the points either side of a mode's reading whose error moves it (its parabola's three and
#: one more, in case the reading's nearest point is not its middle one)
MODE_POINTS = 2
#: a step between neighbouring points turning ``1 + L`` more than this (rad) leaves the
#: encirclement count ambiguous
MAX_STEP_TURN = math.pi / 2


def output_signal(output_unit: str) -> str:
    """The column of the output position for an output in ``output_unit`` (``rad`` or ``m``)."""
    return "output_travel_m" if output_unit == "m" else "output_angle_rad"


def _motion_at(result):
    """The motion controller at the design's operating point (a schedule frozen there)."""
    c = result.controller
    if getattr(c, "schedule", None) is not None:
        c = c.schedule.scaled(c, result.q0)
    return c


def loop_on(result, motor, w, response, signal: str, ratio: float = 1.0):
    """``(L, T)`` of the design closed on ``response``, the current's response to ``signal``
    (a column of :data:`SIGNALS`), at ``w`` (rad/s); see the module notes. ``ratio``: the
    model's transmission with its mode moved by it (:func:`.measured_mode.model_mechanics`)."""
    c = _motion_at(result)
    p = result.parameters
    s = 1j * w
    _, transmission = model_mechanics(result.block("plant"), w, ratio)
    if signal == "motor_speed_rad_s":
        mech_omega = response
    elif signal == "motor_angle_rad":
        mech_omega = s * response
    else:
        mech_omega = response / transmission
    g_theta_per_i = mech_omega * transmission if signal not in ("output_angle_rad", "output_travel_m") else response
    if motor.inductance == 0:
        i_per_cmd = np.ones_like(s)
    else:
        cc = c.current_kp + c.current_ki / s
        i_per_cmd = cc / (p.L * s + p.R + cc + p.Ke * mech_omega)
    g_theta, g_omega = g_theta_per_i * i_per_cmd, mech_omega * i_per_cmd
    k = system_responses(c.motion_block, w)[0]
    d = system_responses(sample_delay_block(c.sample_time, DELAY_SAMPLES), w)[0, 0]
    k_ref, k_theta, k_omega = k[0], k[1], k[2]
    den = 1.0 - k_omega * d * g_omega
    loop = -k_theta * d * g_theta / den
    closed = k_ref * d * g_theta / (den - k_theta * d * g_theta)
    return loop, closed


def model_response(result, w, signal: str) -> np.ndarray:
    """The model's response from the motor current to ``signal`` at ``w`` (what ``frf``
    estimates from the model's own run)."""
    return signal_responses(result.block("plant"), w, signal)[0]


def transmission_ratio(f, measured, model, coherence, signal: str) -> tuple:
    """``(ratio, measured mode, model's mode)``: the measured mode frequency over the model's,
    each read off its response at the measured points (:mod:`.measured_mode`); ratio 1 when
    either shows no mode."""
    mode = find_mode(f, measured, coherence, signal, POOR_COHERENCE)
    model_mode = find_mode(f, model, np.ones(len(f)), signal, POOR_COHERENCE) if mode is not None else None
    ratio = mode.ratio_to(model_mode) if model_mode is not None else None
    if ratio is None or abs(ratio - 1.0) < 1e-6:  # the file's rounding: the model's own mode
        ratio = 1.0
    return ratio, mode, model_mode


def ratio_gradient(f, h, coherence, signal: str, mode, model_mode) -> dict:
    """``d ratio / d ln |H|`` at the points about the measured mode's readings (the ratio of
    :func:`transmission_ratio`; empty without a mode on both sides)."""
    if mode is None or model_mode is None:
        return {}
    base = mode.ratio_to(model_mode)
    x = np.log(f)
    points = set()
    for hz in (mode.resonance_hz, mode.antiresonance_hz):
        if hz is not None:
            j = int(np.argmin(np.abs(x - math.log(hz))))
            points |= set(range(max(j - MODE_POINTS, 0), min(j + MODE_POINTS + 1, f.size)))
    out = {}
    for q in sorted(points):
        moved = h.copy()
        moved[q] *= math.exp(STEP)
        again = find_mode(f, moved, coherence, signal, POOR_COHERENCE)
        if again is not None and again.ratio_to(model_mode) is not None:
            out[q] = (again.ratio_to(model_mode) - base) / STEP
    return out


def with_spread(crossings, result, motor, f, h, coherence, signal: str, ratio: float, sens, sd, gradient,
                averages: int, sd_resolution=None) -> tuple:
    """``crossings`` with their margins' standard deviations and quantiles
    (:mod:`.measured_interval`): the two bracketing points' errors through the loop, and the
    mode's reading's through the model's transmission it moves; ``sd`` the coherence's part
    of each point's error, ``sd_resolution`` the logged signals' rounding's (None: none)."""
    out = []
    loop = loop_on(result, motor, 2 * np.pi * f, h, signal, ratio)[0]
    for c in crossings:
        k = int(np.searchsorted(f, c.low_hz))
        t = math.log(c.frequency_hz / f[k]) / math.log(f[k + 1] / f[k])
        per_ratio = 0.0
        if gradient:
            moved = loop_on(result, motor, 2 * np.pi * f[k:k + 2], h[k:k + 2], signal, ratio * (1 + STEP))[0]
            found = sampled_crossings(f[k:k + 2], moved, np.ones(2))[0 if c.kind == "gain" else 1]
            if found:
                near = min(found, key=lambda x: abs(x.margin - c.margin))
                per_ratio = (near.margin - c.margin) / (ratio * STEP)
        spread = crossing_sd(c.kind, t, k, loop, sens, sd, gradient, per_ratio)
        rounding = 0.0 if sd_resolution is None else crossing_sd(c.kind, t, k, loop, sens, sd_resolution, gradient,
                                                                 per_ratio)
        spread, q = combined(spread, rounding, averages)
        out.append(replace(c, sd=spread, quantile=q))
    return tuple(out)


def _interp(x, x0, x1, y0, y1):
    return y0 + (y1 - y0) * (x - x0) / (x1 - x0)


def sampled_crossings(f, loop, coherence, poor: float = POOR_COHERENCE) -> tuple[tuple, tuple]:
    """Gain and phase crossings of sampled ``loop`` at frequencies ``f`` (Hz).

    Between neighbouring points ``log |L|`` is linear in ``log f`` and the phase (unwrapped
    from the first point) linear in ``log f``. A gain crossing is where ``log |L|`` changes
    sign; its phase margin ``arg L + 180 deg`` in [-180, 180) (``arg L`` taken in [0, 360)). A phase crossing is where the
    phase passes -180 deg (mod 360); its gain margin ``-20 log10 |L|`` (dB). Each carries the
    two points bracketing it and the lower of their coherences.
    """
    x = np.log10(f)
    g = np.log10(np.abs(loop))
    ph = np.degrees(np.unwrap(np.angle(loop)))
    gains, phases = [], []
    for k in range(len(f) - 1):
        x0, x1 = x[k], x[k + 1]
        coh = float(min(coherence[k], coherence[k + 1]))
        if g[k] == 0 or np.sign(g[k]) * np.sign(g[k + 1]) < 0:
            xc = x0 if g[k] == 0 else _interp(0.0, g[k], g[k + 1], x0, x1)
            pc = _interp(xc, x0, x1, ph[k], ph[k + 1]) if x1 != x0 else ph[k]
            pm = float(np.remainder(pc, 360.0) - 180.0)  # in [-180, 180), python-control's convention
            gains.append(Crossing("gain", float(10 ** xc), float(f[k]), float(f[k + 1]), pm, coh, coh < poor))
        lo, hi = sorted((ph[k], ph[k + 1]))
        first = math.ceil((lo + 180.0) / 360.0)
        for n in range(first, math.floor((hi + 180.0) / 360.0) + 1):
            target = -180.0 + 360.0 * n
            if target == ph[k + 1] and k + 1 < len(f) - 1:
                continue  # counted at the next interval's start
            xc = x0 if ph[k + 1] == ph[k] else _interp(target, ph[k], ph[k + 1], x0, x1)
            gm = float(-20.0 * _interp(xc, x0, x1, g[k], g[k + 1]))
            phases.append(Crossing("phase", float(10 ** xc), float(f[k]), float(f[k + 1]), gm, coh, coh < poor))
    return tuple(gains), tuple(phases)


def _turns(values) -> np.ndarray:
    return np.angle(values[1:] / values[:-1])


def _model_turn(response, f1, f2, points) -> float:
    """Change of ``arg(1 + L)`` of the model from ``f1`` to ``f2`` Hz, on a grid refined until
    no step turns it by more than 45 deg."""
    w = 2 * np.pi * np.unique(np.concatenate([np.geomspace(f1, f2, 4000), points]))
    for _ in range(12):
        v = 1.0 + response(1j * w)
        bad = np.nonzero(~(np.abs(_turns(v)) < np.pi / 4))[0]
        if not bad.size:
            break
        w = np.sort(np.concatenate([w, np.sqrt(w[bad] * w[bad + 1])]))
    v = 1.0 + response(1j * w)
    return float(np.sum(_turns(v)))


def nyquist_on_data(result, f, loop, coherence, poor: float = POOR_COHERENCE):
    """Closed-loop right-half-plane poles with the measured curve in place of the model's
    over the band (module notes): ``(count or None, note)``; None when the data leave the
    count ambiguous or contradict it."""
    m = result.margins
    z_model = int(m.unstable_closed_loop_poles)
    response = response_of(result.block("loop"))
    model_ends = 1.0 + response(2j * np.pi * np.array([f[0], f[-1]]))
    meas = 1.0 + loop
    steps = _turns(meas)
    hybrid = (float(np.angle(meas[0] / model_ends[0])) + float(np.sum(steps))
              + float(np.angle(model_ends[1] / meas[-1])))
    turn = (hybrid - _model_turn(response, f[0], f[-1], f)) / (2 * np.pi)
    k = int(round(turn))
    z = z_model - 2 * k
    basis = (f"P = {m.open_loop_rhp_poles} open-loop right-half-plane pole(s) and {m.integrators} integrator(s) "
             f"from the model, the encirclements of -1 below {f[0]:.4g} Hz and above {f[-1]:.4g} Hz the model's, "
             f"those between from the {len(f)} measured points")
    coarse = np.flatnonzero(np.abs(steps) > MAX_STEP_TURN)
    if coarse.size:
        j = coarse[0]
        return None, (f"{basis}; not counted: 1 + L turns {math.degrees(abs(steps[j])):.0f} deg between "
                      f"{f[j]:.4g} and {f[j + 1]:.4g} Hz (more than {math.degrees(MAX_STEP_TURN):.0f} deg: "
                      f"the points are too sparse to tell on which side of -1 the curve passes)")
    near = np.flatnonzero((coherence < poor) & (np.abs(meas) <= np.abs(loop)))
    if near.size:
        j = near[0]
        return None, (f"{basis}; not decided: a point of poor coherence ({coherence[j]:.2f} < {poor:g}) lies "
                      f"closer to -1 than |L| there at {f[j]:.4g} Hz, where an error of its size can move the "
                      "curve across -1")
    if z < 0 or abs(turn - k) > 0.25:
        return None, f"{basis}; not counted: the measured curve's winding ({turn:+.2f} turns) is not a whole count"
    return z, f"{basis}: {z} closed-loop right-half-plane pole(s) (the model's own {z_model})"


def _check_cover(result, f, signal_option: str) -> None:
    """SceneError naming the option unless the band spans the model's gain crossovers."""
    wgc = [x for x in result.margins.gain_crossover_hz if x > 0 and math.isfinite(x)]
    if wgc and (min(wgc) <= f[0] or max(wgc) >= f[-1]):
        raise SceneError(signal_option, f"the measured response spans {f[0]:.4g}..{f[-1]:.4g} Hz; it must cover "
                         f"the loop's gain crossover ({', '.join(f'{x:.4g}' for x in wgc)} Hz, the model's) with a "
                         f"point on either side")


def measured_loop(result, motor, frequency_hz, response, coherence, *, signal: str = "motor_angle_rad",
                  source: str | None = None, required_bandwidth_hz: float | None = None,
                  option: str = "--plant-frf", averages: int | None = None,
                  resolution_sd=None) -> MeasuredLoop:
    """The design ``result`` closed on a measured plant response.

    Parameters
    ----------
    result : DesignResult
        The scene's design (its controller, model plant and margins).
    motor : Motor
        The scene's motor (an ideal current loop without inductance).
    frequency_hz : array_like
        Measured frequencies (Hz), increasing.
    response : array_like of complex
        The response from the motor current to ``signal`` at each.
    coherence : array_like
        Its coherence at each, in [0, 1].
    signal : str
        One of :data:`SIGNALS`.
    source : str, optional
        The file it came from.
    required_bandwidth_hz : float, optional
        Where the closed-loop phase lag is read (the bandwidth requirement).
    option : str
        The option that named the file (for errors).
    averages : int, optional
        The spectra averaged behind the coherence (what ``frf`` records): the margins' 95 %
        intervals rest on it (:mod:`.measured_interval`); None: unknown, no interval.
    resolution_sd : array_like, optional
        Standard deviation of ``ln H`` at each point (nepers, and rad of phase) that the
        logged signals' rounding leaves (what ``frf`` records as ``resolution_db``): added to
        the coherence's in the intervals; None: none.

    Raises
    ------
    SceneError
        ``signal`` not one of :data:`SIGNALS` (or an output in the other unit), fewer than
        two points, or a band that does not cover the loop's gain crossover, or no gain
        crossing of the measured loop within it; a response that reads as another signal's
        than ``signal`` (:func:`.measured_signal.check_signal`).
    """
    if signal not in SIGNALS or (signal.startswith("output_") and signal != output_signal(result.output_unit)):
        allowed = ("motor_angle_rad", "motor_speed_rad_s", output_signal(result.output_unit))
        raise SceneError("--plant-frf-signal", f"must be one of {', '.join(allowed)} (got {signal!r})")
    f = np.asarray(frequency_hz, float)
    h = np.asarray(response, complex)
    coh = np.asarray(coherence, float)
    if f.size < 2:
        raise SceneError(option, f"{f.size} point(s); a loop on measured data needs at least two")
    _check_cover(result, f, option)
    w = 2 * np.pi * f
    check_signal(result.block("plant"), w, h, coh >= POOR_COHERENCE, signal,
                 ("motor_angle_rad", "motor_speed_rad_s", output_signal(result.output_unit)))
    model = model_response(result, w, signal)
    ratio, mode, model_mode = transmission_ratio(f, h, model, coh, signal)
    loop, closed = loop_on(result, motor, w, h, signal, ratio)
    model_loop, model_closed = loop_on(result, motor, w, model, signal)
    gains, phases = sampled_crossings(f, loop, coh)
    sd, spread, rounding = point_sd(coh, averages), None, None
    sd_res = None if resolution_sd is None else np.asarray(resolution_sd, float)
    if sd is not None:
        sens = sensitivity(lambda x: loop_on(result, motor, w, x, signal, ratio)[0], h)
        gradient = ratio_gradient(f, h, coh, signal, mode, model_mode)
        gains, phases = (with_spread(x, result, motor, f, h, coh, signal, ratio, sens, sd, gradient, averages, sd_res)
                         for x in (gains, phases))
        spread = np.abs(sens) * sd
        rounding = None if sd_res is None else np.abs(sens) * sd_res
    if not gains:
        raise SceneError(option, f"|L| of the loop on the measured response does not cross 1 between {f[0]:.4g} and "
                         f"{f[-1]:.4g} Hz: the response must cover the loop's gain crossover")
    model_phases = tuple(Crossing("phase", x, x, x, g, 1.0, False, "model")
                         for g, x in zip(result.margins.gain_margins_db, result.margins.phase_crossover_hz)
                         if not f[0] <= x <= f[-1])
    z, nyquist_note = nyquist_on_data(result, f, loop, coh)
    if sign_reversed(*reversed_points(h, model, coh >= POOR_COHERENCE)):
        z, nyquist_note = None, ("not decided: the measured response's sign is the reverse of the model's, so the "
                                 "loops inside the position loop are not the model's and neither are the open "
                                 f"loop's right-half-plane poles the count starts from (the count on them: "
                                 f"{nyquist_note})")
    dc = abs(complex(result.block("closed_loop").dcgain())) if result.margins.closed_loop_stable else 1.0
    return MeasuredLoop(frequency_hz=f, response=h, model_response=model, coherence=coh, loop=loop,
                        model_loop=model_loop, closed=closed, model_closed=model_closed, signal=signal,
                        source=source, gain_crossings=gains, phase_crossings=phases + model_phases,
                        closed_loop_rhp_poles=z, nyquist_note=nyquist_note, poor_coherence=POOR_COHERENCE,
                        reference_gain=dc if math.isfinite(dc) and dc > 0 else 1.0,
                        required_bandwidth_hz=required_bandwidth_hz, model_margins=result.margins,
                        bands=mismatch_bands(f, h, model, coh, POOR_COHERENCE), mode=mode, model_mode=model_mode,
                        transmission_ratio=ratio, averages=averages, loop_sd=spread, loop_sd_resolution=rounding)
