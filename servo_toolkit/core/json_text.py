"""JSON text of results: numpy scalars and arrays as plain numbers and lists, infinities as
the strings "inf" and "-inf", NaN as null (JSON has no such numbers)."""

from __future__ import annotations

import json
import math


def _default(obj):
    import numpy as np  # only for what json cannot write itself (the command line's parser loads no numpy)
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    raise TypeError(f"not JSON serializable: {type(obj).__name__}")


def to_json(data) -> str:
    """JSON text; infinities become null-safe strings via ``allow_nan`` off -> None."""
    return json.dumps(_finite(data), default=_default, indent=2)


def _finite(obj):
    if isinstance(obj, float) and not math.isfinite(obj):
        return None if math.isnan(obj) else ("inf" if obj > 0 else "-inf")
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v) for v in obj]
    return obj


def nulls(obj):
    """``obj`` (dicts, lists and tuples, nested) with every non-finite float as None: the form
    of a figure that does not exist or is unbounded in a result's ``to_dict()`` (strict JSON,
    ``json.dumps(..., allow_nan=False)``); tuples become lists."""
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, dict):
        return {k: nulls(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [nulls(v) for v in obj]
    return obj
