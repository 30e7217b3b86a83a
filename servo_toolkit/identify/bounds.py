"""The physical range of a fit parameter: where the search looks, and the bound of the fit.

A rig differs from its scene, but not without limit: a value is searched within a factor
:data:`RANGE_FACTOR` either side of the scene's (in log space, where an inertia twice too
large and one half too large are equally far), and within the limits of its kind (an
efficiency never exceeds 1). The scene's loader refuses anything else it knows to be
unphysical; the fit steps back from such values.
"""

from __future__ import annotations

import math

import numpy as np

#: the search spans this factor either side of the scene's value
RANGE_FACTOR = 100.0
#: upper limits by key name (SI), where physics sets one
UPPER = {"efficiency": 1.0}


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
    lower = np.array([p.initial / RANGE_FACTOR for p in parameters])
    upper = np.array([min(p.initial * RANGE_FACTOR, UPPER.get(p.name, math.inf)) for p in parameters])
    upper = np.maximum(upper, np.array([p.initial for p in parameters]))
    return lower, upper
