"""The ``kv`` study: the dynamic-load factor Kv along prescribed motions (seed 000).

:mod:`.kind` describes the study kind (its scene keys, runner, result, command and report
section); :mod:`.study` runs it (:func:`~.study.kv_study`), :mod:`.result` holds
:class:`~.result.KvResult`. The names below are imported on first use, so that reading the
kind's description imports no computation.
"""

from __future__ import annotations

__all__ = ["KvCase", "KvResult", "default_kv_study", "kv_grid", "kv_studies", "kv_study", "output_amplitudes",
           "rigid_model_effect", "with_load_inertia"]


def __getattr__(name: str):
    if name in ("KvCase", "KvResult"):
        from . import result as module
    elif name in __all__:
        from . import study as module
    else:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(module, name)
