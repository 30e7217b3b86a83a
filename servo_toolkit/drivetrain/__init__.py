"""The drivetrain between the motor and the load: ratio N(q), reflected inertia J(q),
stiffness chain, lash and efficiency along the stroke.

Modules: :mod:`.reflected` (the :class:`Drivetrain` of a scene), :mod:`.chain` (the one
lumped chain: every inertia, compliance, lash and loss at its place), :mod:`.elements` (each
element's reflection, coordinate units, seed 001's neglect criterion) and
:mod:`.operating_point` (the design's point along the stroke).
"""

from .chain import Chain, TwoMassSplit
from .reflected import (DEFAULT_LINEAR_STROKE, RATIO_RANGE, Drivetrain, Kinematics, StiffnessChain,
                        ratio_keys, series)

__all__ = ["Chain", "DEFAULT_LINEAR_STROKE", "RATIO_RANGE", "Drivetrain", "Kinematics", "StiffnessChain",
           "TwoMassSplit", "ratio_keys", "series"]
