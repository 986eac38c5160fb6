"""Strict JSON from numerical results: one converter for every writer in iamp."""

from __future__ import annotations

import math
from typing import Any

import numpy as np


def to_jsonable(obj: Any) -> Any:
    """Recursively turn ``obj`` into something :func:`json.dumps` accepts with ``allow_nan=False``.

    Dicts (keys become strings), lists and tuples recurse; numpy arrays become lists, numpy
    integers and booleans Python ones; floats stay floats when finite and become ``None``
    otherwise (strict JSON has no NaN or infinity).  Anything else is returned unchanged.
    """
    if isinstance(obj, dict):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist())
    if isinstance(obj, np.bool_):
        return bool(obj)
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        x = float(obj)
        return x if math.isfinite(x) else None
    return obj
