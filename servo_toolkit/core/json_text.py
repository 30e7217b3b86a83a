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
    return _each_float(obj, lambda x: None if math.isnan(x) else ("inf" if x > 0 else "-inf"))


def nulls(obj):
    """``obj`` (dicts, lists and tuples, nested) with every non-finite float as None: the form
    of a figure that does not exist or is unbounded in a result's ``to_dict()`` (strict JSON,
    ``json.dumps(..., allow_nan=False)``); tuples become lists."""
    return _each_float(obj, lambda x: None)


def _each_float(obj, replace):
    """``obj`` (dicts, lists and tuples, nested; tuples become lists) with each non-finite
    float ``x`` as ``replace(x)``."""
    if isinstance(obj, float) and not math.isfinite(obj):
        return replace(obj)
    if isinstance(obj, dict):
        return {k: _each_float(v, replace) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_each_float(v, replace) for v in obj]
    return obj
