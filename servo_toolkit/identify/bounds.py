"""The physical range of a fit parameter: where the search looks, and the bound of the fit.

A rig differs from its scene, but not without limit: a value is searched within a factor
:data:`RANGE_FACTOR` either side of the scene's (in log space, where an inertia twice too
large and one half too large are equally far), and within the range the loader accepts for
its key (:mod:`servo_toolkit.core.ranges`: the range the models are conditioned for, or the
component's own, e.g. an efficiency in [0.01, 1]). The scene's loader refuses anything else
it knows to be unphysical; the fit steps back from such values.

A parameter the scene accepts with either sign (a constant force such as a hinge moment)
has no logarithm: it is searched as ``value = initial + |initial| z`` within
:data:`SIGNED_SPAN` times its magnitude either side (and within the magnitude its key
accepts). :class:`Coordinates` maps the search's
coordinates z to values and back, and a half-width in z to an interval.
"""

from __future__ import annotations

import math

import numpy as np

#: the search spans this factor either side of the scene's value
RANGE_FACTOR = 100.0
#: upper limits by key name (SI), where physics sets one
UPPER = {"efficiency": 1.0}
#: a signed parameter is searched within this many times its magnitude either side
SIGNED_SPAN = 10.0


def physical_range(parameters) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper bounds (SI) of each parameter.

    Parameters
    ----------
    parameters : sequence of Parameter
        From :class:`~servo_toolkit.identify.params.SceneTemplate`.

    Returns
    -------
    lower, upper : numpy.ndarray
    """
    c = Coordinates(parameters)
    return c.values(c.lower), c.values(c.upper)


class Coordinates:
    """The search's coordinates of the parameters: z = ln(value / initial), or (value -
    initial) / |initial| for a signed parameter; z = 0 at the initial values.

    Parameters
    ----------
    parameters : sequence of Parameter

    Attributes
    ----------
    lower, upper : numpy.ndarray
        The physical range in z.
    """

    def __init__(self, parameters):
        self.initial = np.array([p.value for p in parameters], float)
        self.signed = np.array([p.signed for p in parameters], bool)
        self.scale = np.abs(self.initial)
        accepted = [getattr(p, "bounds", None) or (0.0, math.inf) for p in parameters]
        low = np.array([b[0] for b in accepted], float)
        high = np.minimum([b[1] for b in accepted], [UPPER.get(p.name, math.inf) for p in parameters])
        with np.errstate(divide="ignore", invalid="ignore"):
            # positive: ln(value / initial) within +-ln(RANGE_FACTOR) and the accepted magnitudes
            log_lo = np.maximum(-math.log(RANGE_FACTOR), np.log(low / self.scale))
            log_hi = np.minimum(math.log(RANGE_FACTOR), np.log(high / self.scale))
            # signed: (value - initial) / |initial| within +-SIGNED_SPAN and |value| <= high
            lin_lo = np.maximum(-SIGNED_SPAN, (-high - self.initial) / self.scale)
            lin_hi = np.minimum(SIGNED_SPAN, (high - self.initial) / self.scale)
        self.lower = np.minimum(np.where(self.signed, lin_lo, log_lo), 0.0)
        self.upper = np.maximum(np.where(self.signed, lin_hi, log_hi), 0.0)

    def values(self, z) -> np.ndarray:
        """Values (SI) at coordinates z."""
        z = np.asarray(z, float)
        with np.errstate(over="ignore"):
            return np.where(self.signed, self.initial + self.scale * z, self.initial * np.exp(z))

    def intervals(self, values, half) -> np.ndarray:
        """(n, 2) intervals of values whose coordinates have these half-widths: ``value *
        exp(-+half)`` (not symmetric), or ``value -+ |initial| half`` for a signed one."""
        values, half = np.asarray(values, float), np.asarray(half, float)
        with np.errstate(over="ignore", invalid="ignore"):
            lo = np.where(self.signed, values - self.scale * half, values * np.exp(-half))
            hi = np.where(self.signed, values + self.scale * half, values * np.exp(half))
        return np.column_stack([lo, hi])

    def relative_half(self, values, half) -> np.ndarray:
        """Half-width of each interval relative to its value (asinh-free for a log one)."""
        values = np.asarray(values, float)
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            return np.where(self.signed, self.scale * half / np.abs(values), np.sinh(np.minimum(half, 700.0)))
