"""The drivetrain mode read off a measured plant response, and where the design's resonance
filter goes when the rig's mode is not the model's (``design --plant-frf``).

Finding the mode
----------------
The response from the motor current to the motor angle of a two-mass drivetrain is
``(s^2 + 2 z_a w_a s + w_a^2) / (J s^2 (s^2 + 2 z_r w_r s + w_r^2))`` up to a constant: times
``w^2`` (``w`` for the motor speed) it is flat below the mode, dips at the anti-resonance
``w_a`` (the load's mode with the motor held) and peaks at the resonance ``w_r`` above it. To
the output there is the peak only. Over the points of good coherence, the highest local
maximum of that rigid-body-free magnitude whose prominence (its height over the higher of
the lowest points on either side) reaches :data:`MIN_PROMINENCE_DB` is the resonance; for a
motor-side signal the lowest point below it is the anti-resonance. Each is refined by a
parabola through the point and its two neighbours in (log f, dB), within the two
neighbours. The model's response is read the same way at the same points, so the ratio of
the two readings carries neither the damping's shift of the dip nor the grid's resolution:
on a noise-free response of a plant whose stiffness is off the model's by ``r^2`` it is ``r``
within a fraction of the points' spacing.

The output's transmission
-------------------------
A loop closed on a measured motor-side response still needs the output, which the rig did not
log: the model's transmission ``theta / omega_m``, whose poles are the motor side's
anti-resonance. With the measured anti-resonance off the model's, the model's transmission
would put its peak where the measured response has none; :func:`signal_responses` moves it by
the measured ratio (for a two-mass drivetrain a stiffness scaled by ``r^2``, its damper by
``r``, gives exactly ``G(jw / r) / (N jw)`` with ``T = G / (N s)``), and the notes say so.

Where the notch goes
--------------------
The design's notch sits on the anti-resonance at the operating point (the mode a position
loop over a stiff speed loop sees). With the measured one more than :data:`MIN_SHIFT` off the
model's, the search ranks its candidates on the model with the drivetrain stiffness scaled by
``(measured / model)^2`` (the damping ratio kept), every design point alike: its mode, and so
the notch, at the measured frequency. From an output signal the anti-resonance is not seen;
the resonance's ratio stands for it (a stiffness error moves both alike; an inertia error
does not, and the note says so). The margins reported stay the scene model's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..lti.system import as_system, ss

#: a peak less prominent than this (dB) over the rigid-body line is not a resonance
MIN_PROMINENCE_DB = 6.0
#: a measured mode within this relative shift of the model's leaves the model's placement
MIN_SHIFT = 0.02
#: power of w that takes the rigid body out of the response to each signal
_RIGID_POWER = {"motor_angle_rad": 2, "motor_speed_rad_s": 1, "output_angle_rad": 2, "output_travel_m": 2}


@dataclass(frozen=True)
class MeasuredMode:
    """The drivetrain mode of a measured response.

    Attributes
    ----------
    signal : str
        The measured signal (the response is from the motor current to it).
    resonance_hz : float
        The peak (Hz).
    antiresonance_hz : float or None
        The dip below it (Hz), for a motor-side signal; None from an output signal.
    prominence_db : float
        The peak's height over the rigid-body line (dB).
    """

    signal: str
    resonance_hz: float
    antiresonance_hz: float | None
    prominence_db: float
    grid_hz: tuple = ()

    def ratio_to(self, model) -> float | None:
        """Measured over ``model`` (the model's response read alike): the anti-resonances'
        ratio when both show one, else the resonances' (None without a model reading)."""
        if model is None:
            return None
        if self.antiresonance_hz is not None and model.antiresonance_hz is not None:
            return self.antiresonance_hz / model.antiresonance_hz
        return self.resonance_hz / model.resonance_hz

    def model_reading(self, p):
        """The model's response at plant parameters ``p`` read alike at the same points
        (None: no mode there)."""
        w = 2 * np.pi * np.asarray(self.grid_hz, float)
        h = signal_responses(plant_system(p), w, self.signal)[0]
        return find_mode(self.grid_hz, h, np.ones(w.size), self.signal)

    def text(self, model, p) -> str:
        """The measured mode against the model's reading ``model`` (Hz)."""
        r = self.ratio_to(model)
        if self.antiresonance_hz is not None and model.antiresonance_hz is not None:
            return (f"measured anti-resonance {self.antiresonance_hz:.4g} Hz against the model's "
                    f"{model.antiresonance_hz:.4g} Hz at q0 ({100 * (r - 1):+.1f} %; resonance "
                    f"{self.resonance_hz:.4g} Hz against {model.resonance_hz:.4g} Hz; each read off the dip and "
                    "peak of the response at the measured points)")
        return (f"measured resonance {self.resonance_hz:.4g} Hz against the model's {model.resonance_hz:.4g} Hz "
                f"at q0 ({100 * (r - 1):+.1f} %); the anti-resonance, not seen from {self.signal}, taken as the "
                f"model's scaled alike (right for a stiffness error, not for an inertia error)")

    def placement(self, p, resonance_filter: str) -> tuple:
        """``(stiffness factor or None, note)``: the factor the design's search scales the
        drivetrain stiffness of plant parameters ``p`` by (None: the model's placement kept)
        and the note saying so."""
        if p.rigid:
            return None, (f"the measured response shows a resonance at {self.resonance_hz:.4g} Hz that the rigid "
                          "model lacks: no filter is placed on it (fit the scene's stiffness, servo-toolkit fit)")
        model = self.model_reading(p)
        if model is None:
            return None, (f"the measured response shows a resonance at {self.resonance_hz:.4g} Hz; the model's "
                          f"(anti-resonance {p.antiresonance_hz:.4g} Hz) shows none at the measured points: the "
                          "model's placement kept")
        text, r = self.text(model, p), self.ratio_to(model)
        if resonance_filter != "auto":
            return None, f"{text}: --filter {resonance_filter} keeps the model's placement"
        if abs(r - 1) <= MIN_SHIFT:
            return None, f"{text}: within {100 * MIN_SHIFT:g} %, the model's placement kept"
        return r * r, (f"{text}: the filter search ranks its candidates on the model with the drivetrain "
                       f"stiffness scaled by {r * r:.4g}, the notch on {r * p.antiresonance_hz:.4g} Hz instead of "
                       f"{p.antiresonance_hz:.4g} Hz (the model's undamped anti-resonance); the margins shown "
                       "are the scene model's")

    def to_dict(self) -> dict:
        """JSON-ready, units in the key names."""
        return {"signal": self.signal, "resonance_hz": self.resonance_hz, "antiresonance_hz": self.antiresonance_hz,
                "prominence_db": self.prominence_db}

    def __repr__(self) -> str:
        anti = "" if self.antiresonance_hz is None else f", anti-resonance {self.antiresonance_hz:.6g} Hz"
        return (f"<MeasuredMode {self.signal}: resonance {self.resonance_hz:.6g} Hz{anti}, "
                f"{len(self.grid_hz)} points {self.grid_hz[0] if self.grid_hz else 0:.6g}.."
                f"{self.grid_hz[-1] if self.grid_hz else 0:.6g} Hz>")


def plant_system(p):
    """The voltage-driven plant of parameters ``p`` (what the design's result holds)."""
    from ..plant.linear import plant_matrices
    from ..plant.signals import PLANT_OUTPUTS
    A, B, C, D, states = plant_matrices(p, True)
    return ss(A, B, C, D, inputs=["u", "tau_ext"], outputs=list(PLANT_OUTPUTS), states=states)


def system_responses(system, w) -> np.ndarray:
    """Frequency response of ``system`` (a python-control system or the toolkit's own) at ``w``
    (rad/s): (outputs, inputs, points)."""
    system = as_system(system)
    with np.errstate(all="ignore"):
        r = np.asarray(system(1j * np.asarray(w, float)))
    return r.reshape(system.noutputs, system.ninputs, len(w))


def model_mechanics(plant_ss, w, ratio: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """The model's response from the motor current to the motor angle (rad/A) and its
    transmission from the motor speed to the output position (``theta / omega_m``) at ``w``;
    ``ratio``: the transmission's mode moved by it (its part apart from the integration
    evaluated at ``w / ratio``, module notes).

    Both come from the voltage-driven plant: with the external load at rest the current and
    the motion answer the same voltage, so their ratio is the mechanics' response to the
    current (the back-EMF cancels out of it)."""
    r = system_responses(plant_ss, w)
    names = list(plant_ss.output_labels)
    theta, omega_m, i = (r[names.index(n), 0] for n in ("theta", "omega_m", "i"))
    transmission = theta / omega_m
    if ratio != 1.0:
        r = system_responses(plant_ss, np.asarray(w) / ratio)
        # theta / omega_m = G(s) / (N s): the mode part G moved, the integration kept
        transmission = r[names.index("theta"), 0] / r[names.index("omega_m"), 0] / ratio
    return omega_m / i / (1j * w), transmission


def signal_responses(plant_ss, w, signal: str, ratio: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """The model's response from the motor current to ``signal`` at ``w`` (what ``frf``
    estimates from the model's own run) and its transmission (:func:`model_mechanics`)."""
    mech, transmission = model_mechanics(plant_ss, w, ratio)
    if signal == "motor_angle_rad":
        return mech, transmission
    if signal == "motor_speed_rad_s":
        return 1j * w * mech, transmission
    return 1j * w * mech * transmission, transmission


def stiffened(params, factor: float):
    """Plant parameters with the drivetrain stiffness times ``factor``, the damping ratio kept
    (the damper scales with ``sqrt(K)``)."""
    return replace(params, K=params.K * factor, c=params.c * math.sqrt(factor))


def _refine(x, y, j) -> float:
    """The vertex of the parabola through points ``j - 1, j, j + 1``, kept between them."""
    if j <= 0 or j >= len(x) - 1:
        return float(x[j])
    x0, x1, x2 = x[j - 1], x[j], x[j + 1]
    y0, y1, y2 = y[j - 1], y[j], y[j + 1]
    den = (x0 - x1) * (x0 - x2) * (x1 - x2)
    a = (x2 * (y1 - y0) + x1 * (y0 - y2) + x0 * (y2 - y1)) / den
    b = (x2 * x2 * (y0 - y1) + x1 * x1 * (y2 - y0) + x0 * x0 * (y1 - y2)) / den
    if a == 0:
        return float(x1)
    return float(min(max(-b / (2 * a), x0), x2))


def find_mode(frequency_hz, response, coherence, signal: str, poor: float = 0.8) -> MeasuredMode | None:
    """The drivetrain mode of a measured response (module notes), or None when no peak over
    the points of coherence ``>= poor`` reaches :data:`MIN_PROMINENCE_DB`."""
    f = np.asarray(frequency_hz, float)
    good = np.asarray(coherence, float) >= poor
    f = f[good]
    if f.size < 3:
        return None
    with np.errstate(divide="ignore"):
        y = 20 * np.log10(np.abs(np.asarray(response, complex)[good]) * (2 * np.pi * f) ** _RIGID_POWER[signal])
    x = np.log10(f)
    best = None
    for j in range(1, f.size - 1):
        if not (y[j] > y[j - 1] and y[j] >= y[j + 1]):
            continue
        base = max(float(np.min(y[:j])), float(np.min(y[j + 1:])))
        prominence = float(y[j] - base)
        if prominence >= MIN_PROMINENCE_DB and (best is None or y[j] > y[best[0]]):
            best = (j, prominence)
    if best is None:
        return None
    j, prominence = best
    anti = None
    if signal.startswith("motor_"):
        k = int(np.argmin(y[:j]))
        if 0 < k and y[j] - y[k] >= MIN_PROMINENCE_DB:
            anti = float(10 ** _refine(x, y, k))
    return MeasuredMode(signal, float(10 ** _refine(x, y, j)), anti, prominence, tuple(float(v) for v in f))
