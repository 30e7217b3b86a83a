"""The seed mechanisms' studies (cam drive, deflection platform, roller screw) and the
inverse dynamics of a drivetrain along a prescribed motion.

:mod:`.kind` describes the study kinds ``inverse_dynamics`` and ``mechanism_sweep`` (their
scene keys, runner and result); :mod:`.dispatch` sends a scene's study to its mechanism
model (:mod:`.platform`, :mod:`.roller_screw`, the cam's in :mod:`servo_toolkit.studies.cam`);
:mod:`.inverse_dynamics` computes the loads along a motion (the Kv study and the sizing use
it). The names below are imported on first use, so that reading the kinds' descriptions
imports no computation.
"""

from __future__ import annotations

__all__ = ["ROLLER_SCREW_STUDIES", "handles", "platform_plant", "run_mechanism"]


def __getattr__(name: str):
    if name in __all__:
        from . import dispatch
        return getattr(dispatch, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
