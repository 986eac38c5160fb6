"""Array type aliases shared by the prediction modules (for mypy strict)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import numpy.typing as npt

__all__ = ["Array", "BoolArray", "FloatArray", "IntArray", "Progress"]

#: A float64 array.
FloatArray = npt.NDArray[np.float64]
#: An int64 array.
IntArray = npt.NDArray[np.int64]
#: A boolean array.
BoolArray = npt.NDArray[np.bool_]
#: Any numpy array (strings, mixed).
Array = npt.NDArray[Any]
#: Progress callback ``(done, total)`` (see ``iamp.cli.progress``).
Progress = Callable[[int, int], None]
