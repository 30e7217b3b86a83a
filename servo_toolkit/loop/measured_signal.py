"""Which signal a measured plant response is to, read off the response against the model's.

A response file that does not say what it measured (no ``# signal:`` line, see
:func:`servo_toolkit.identify.frf.response_signal`) may hold another signal than the one
``--plant-frf-signal`` names: most often the motor speed (``frf --derivative``) read as the
motor angle, whose loop then looks unstable by 90 deg of phase and a gain slope of a decade
per decade. The model's response to each signal the loop can take (the motor angle, the
motor speed, the output) is compared with the measured one at the points of good coherence:
when the named signal's phase is far off the measured one while another signal's phase and
gain match it, the file holds that other signal. A model that is merely wrong (a moved mode,
a gain error) leaves the named signal the closest of the three, and passes.
"""

from __future__ import annotations

import numpy as np

from ..errors import SceneError
from .measured_mode import signal_responses

#: the named signal is off when the median phase difference at the good points exceeds this
#: (deg): a quarter turn is the step between an angle and its speed
OFF_DEG = 60.0
#: ... or when the median gain difference exceeds this (dB): a tenth in amplitude
OFF_DB = 20.0
#: another signal matches when its median phase difference is within this (deg) ...
MATCH_DEG = 20.0
#: ... and its median gain difference within this (dB)
MATCH_DB = 6.0


def distance(measured, model) -> tuple[float, float]:
    """``(median |phase difference| in deg, median |gain difference| in dB)`` of ``measured``
    against ``model`` over the points given."""
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.asarray(measured) / np.asarray(model)
    return float(np.median(np.abs(np.degrees(np.angle(ratio))))), float(np.median(np.abs(20 * np.log10(np.abs(ratio)))))


def check_signal(plant, w, response, good, signal: str, candidates, option: str = "--plant-frf-signal") -> None:
    """SceneError naming ``option`` when the measured ``response`` (at ``w`` rad/s, points of
    good coherence ``good``) reads as the response to another of ``candidates`` than
    ``signal``: ``signal``'s model is off (:data:`OFF_DEG` or :data:`OFF_DB`) and the other's
    matches (:data:`MATCH_DEG` and :data:`MATCH_DB`). ``plant``: the model's plant block."""
    good = np.asarray(good, bool)
    if good.sum() < 3:
        return
    h = np.asarray(response)[good]
    named = distance(h, signal_responses(plant, w, signal)[0][good])
    if named[0] <= OFF_DEG and named[1] <= OFF_DB:
        return
    for other in candidates:
        if other == signal:
            continue
        deg, db = distance(h, signal_responses(plant, w, other)[0][good])
        if deg <= MATCH_DEG and db <= MATCH_DB:
            raise SceneError(option, f"the measured response reads as the response to {other}, not to {signal}: "
                             f"the model's response to {other} lies within {deg:.3g} deg and {db:.3g} dB of it (median "
                             f"over {int(good.sum())} points of good coherence), to {signal} {named[0]:.3g} deg and "
                             f"{named[1]:.3g} dB off; give {option} {other}, or a '# signal: {other}' line before the "
                             "file's header (frf -o writes it)")
