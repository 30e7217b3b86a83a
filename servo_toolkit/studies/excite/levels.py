"""How large an excitation may be, and how large it should be.

Upper bounds, from the linear loop's periodic response to one period of the signal
(:func:`.drive.periodic_response`, per unit of its peak) about the operating point (the
current ``i0`` that holds the load there, its voltage ``R i0``): the current and the voltage
within :data:`HEADROOM` of the motor's limits (the voltage with the current loop's
proportional answer ``kp`` to each held sample's step of the current reference added: the
linear loop's delay smooths those steps, a binary sequence's are its largest), and the output within it of the distance to
the nearer stroke end. The headroom leaves room for what the linear response leaves out (the
loss that switches with the power flow, friction, the start's transient); the model's own
run then checks the limits (:mod:`.run`).

Lower levels, which the response should clear to be the linear plant's rather than a
nonlinearity's:

- breakaway: the current's swing about ``i0`` at least :data:`BREAKAWAY_FACTOR` times the
  current of the band of motor torques that hold the drive at rest
  (:func:`servo_toolkit.studies.hunting.holding_band` over Kt): a sine of that peak stays
  inside the band a third of its period at most;
- backlash: the motor side's motion (at the output) of an amplitude A at which the play's
  describing function keeps :data:`BACKLASH_GAIN` of the gain,
  ``|N(A)| >= 0.9`` (:func:`servo_toolkit.loop.backlash_df.backlash_df`; A about 13 half-plays).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: a limit is used up to this fraction when the amplitude is chosen
HEADROOM = 0.8
#: the current's swing over the breakaway current the excitation should reach
BREAKAWAY_FACTOR = 2.0
#: the gain the play's describing function should keep at the motor side's motion amplitude
BACKLASH_GAIN = 0.9


@dataclass(frozen=True)
class Bound:
    """The largest amplitude one limit allows, with the limit's figures.

    Attributes
    ----------
    name : {"current", "voltage", "stroke"}
    amplitude : float
        Largest excitation peak (A or rad/s) keeping the quantity within ``fraction`` of its limit.
    per_unit : float
        The quantity's largest excursion from its operating value per unit of the excitation's peak.
    operating : float
        Its operating value (A, V; the output's distance to the nearer stroke end for the stroke).
    limit : float
    """

    name: str
    amplitude: float
    per_unit: float
    operating: float
    limit: float


def _largest(trace, operating: float, limit: float) -> float:
    """Largest a with |operating + a trace| <= limit everywhere (inf for a zero trace; 0
    when the operating value is already beyond the limit)."""
    trace = np.asarray(trace, float)
    room_up, room_down = limit - operating, limit + operating
    if room_up <= 0 or room_down <= 0:
        return 0.0
    up, down = trace[trace > 0], -trace[trace < 0]
    return min(room_up / up.max() if up.size else math.inf, room_down / down.max() if down.size else math.inf)


def bounds(shapes: dict, i0: float, resistance: float, limits: dict, fraction: float = HEADROOM) -> tuple:
    """The :class:`Bound` of the current, the voltage and (when ``limits`` has a
    ``stroke_room``) the stroke, for responses ``shapes`` (``current``, ``voltage``,
    ``excursion``: per unit of the excitation's peak over one period)."""
    out = [Bound("current", _largest(shapes["current"], i0, fraction * limits["current"]),
                 float(np.max(np.abs(shapes["current"]))), i0, limits["current"]),
           Bound("voltage", _largest(shapes["voltage"], resistance * i0, fraction * limits["voltage"]),
                 float(np.max(np.abs(shapes["voltage"]))), resistance * i0, limits["voltage"])]
    room = limits.get("stroke_room")
    if room is not None:
        per = float(np.max(np.abs(shapes["excursion"])))
        out.append(Bound("stroke", fraction * room / per if per > 0 else math.inf, per, room, room))
    return tuple(out)


def backlash_amplitude(half_play: float) -> float:
    """The motion amplitude (same unit as ``half_play``) at which the play's describing
    function keeps :data:`BACKLASH_GAIN` of the gain."""
    from scipy.optimize import brentq

    from ...loop.backlash_df import backlash_df
    if not half_play > 0:
        return 0.0
    ratio = brentq(lambda x: abs(complex(backlash_df(x, 1.0))) - BACKLASH_GAIN, 1.0 + 1e-9, 1e6)
    return ratio * half_play


def breakaway_current(scene, q0: float) -> float:
    """The current of the holding band's half width (A): the motor torques that hold the
    drive at rest at q0, over Kt."""
    from ..hunting import holding_band
    return holding_band(scene, q0) / scene.motor.torque_constant


__all__ = ["BACKLASH_GAIN", "BREAKAWAY_FACTOR", "HEADROOM", "Bound", "backlash_amplitude", "bounds",
           "breakaway_current"]
