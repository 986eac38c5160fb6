"""Array type aliases shared by the prediction modules (for mypy strict)."""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable
from typing import Any

import numpy as np
import numpy.typing as npt

__all__ = ["Array", "BoolArray", "FloatArray", "IntArray", "Lines", "PathLike", "Progress", "Seed", "StateSequences"]

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
#: The file line of every row of a loaded table (for messages), when the loader knows it.
Lines = IntArray | None
#: A file path.
PathLike = str | os.PathLike[str]
#: What :func:`numpy.random.default_rng` accepts: a generator, a seed, or ``None`` (fresh entropy).
Seed = np.random.Generator | int | None
#: Integer state sequences: one 1-D array, or an iterable of 1-D sequences (one per track).
StateSequences = npt.NDArray[np.integer[Any]] | Iterable[npt.ArrayLike]
