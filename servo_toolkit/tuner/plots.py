"""The tuner's figure: loop Bode with margins, Nichols chart, step and 8 Hz sine responses
(the sine with and without the controller's feedforward, when it has one)."""

from __future__ import annotations

import math

import numpy as np

#: the frequency of the tracking plot's sine (its amplitude is the output's default command,
#: 2 deg or 1 mm)
SINE_HZ = 8.0


def draw(result, axes, scene=None) -> None:
    """Draw the four panels of ``result`` (a DesignResult) on a 2x2 array of axes; with the
    ``scene`` and a controller with a feedforward, the sine panel also shows the output with
    it (:func:`servo_toolkit.loop.tracking.sine_tracking`)."""
    import control as ct
    (bode, nichols), (step, sine) = axes
    m = result.margins
    w = 2 * np.pi * np.logspace(-1, 3, 600)
    L = np.asarray(ct.frequency_response(result.loop, w).complex).reshape(-1)
    f = w / (2 * np.pi)
    gain_db = 20 * np.log10(np.abs(L))
    phase = np.degrees(np.unwrap(np.angle(L)))
    bode.semilogx(f, gain_db, label="|L|")
    bode.axhline(0.0, color="0.6", lw=0.8)
    if not m.closed_loop_stable:
        bode.set_title(f"loop: closed loop UNSTABLE ({m.unstable_closed_loop_poles} right-half-plane poles)", fontsize=9)
    elif math.isfinite(m.gain_margin_db):
        bode.set_title(f"loop: GM {m.gain_margin_db:.3g} dB, PM {m.phase_margin_deg:.3g} deg", fontsize=9)
    else:
        bode.set_title(f"loop: PM {m.phase_margin_deg:.3g} deg", fontsize=9)
    bode.set(xlabel="frequency [Hz]", ylabel="gain [dB]")
    bode.grid(True, which="both", alpha=0.3)
    nichols.plot(phase, gain_db)
    nichols.plot([-180], [0], "r+", ms=12)
    nichols.set(xlabel="phase [deg]", ylabel="gain [dB]", title="Nichols", ylim=(-40, 40))
    nichols.grid(True, alpha=0.3)
    t = np.linspace(0.0, 0.25, 600)
    y = np.asarray(ct.step_response(result.closed_loop, t).outputs).reshape(-1)
    step.plot(t * 1e3, y)
    step.axhline(1.0, color="0.6", lw=0.8)
    step.set(xlabel="time [ms]", ylabel="output / command", title="step")
    step.grid(True, alpha=0.3)
    ts = np.linspace(0.0, 4 / SINE_HZ, 800)
    u = result.unit
    amp = u.show(u.default_amplitude)
    ref = amp * np.sin(2 * np.pi * SINE_HZ * ts)
    out = np.asarray(ct.forced_response(result.closed_loop, ts, ref).outputs).reshape(-1)
    sine.plot(ts * 1e3, ref, color="0.6", lw=0.8, label="command")
    sine.plot(ts * 1e3, out, label="output")
    title = ""
    if scene is not None and result.controller.feedforward is not None:
        from ..loop.tracking import sine_tracking
        tr = sine_tracking(scene, result.controller, u.default_amplitude, SINE_HZ, result.q0, cycles=4, points=800)
        sine.plot(tr["t"] * 1e3, u.show(tr["output"]), label=f"output, {result.controller.feedforward.kind} feedforward")
        title = f", error {u.show(tr['steady_error']):.2g} {u.shown} with feedforward"
    sine.set(xlabel="time [ms]", ylabel=f"{'travel' if u.linear else 'angle'} [{u.shown}]",
             title=f"{amp:g} {u.shown} sine at {SINE_HZ:g} Hz{title}")
    sine.grid(True, alpha=0.3)
    sine.legend(fontsize="x-small")
