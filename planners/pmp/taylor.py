r"""Taylor shifts of polynomials: the coefficients of :math:`p(c + h)` in :math:`h`.

Shared by the branch-and-bound certificate (:mod:`.bound`) and the basin bounds (:mod:`.basin`).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]


def taylor_shift(C: FloatArray, c: FloatArray) -> FloatArray:
    """Coefficients in ``h`` of ``p(c + h)`` for every row ``p`` of ``C`` (ascending) and the
    matching centre ``c`` (shape ``C.shape[:-1]``; repeated synthetic division)."""
    A = np.array(C, dtype=float, copy=True)
    d = A.shape[-1]
    for i in range(d - 1):
        for j in range(d - 2, i - 1, -1):
            A[..., j] += c * A[..., j + 1]
    return A
