"""numba kernel of the IDM forward simulation (``pip install iamp[fast]``).

The same arithmetic as :func:`iamp.prediction.leader.car_following._simulate_idm` (checked against it
in ``tests/test_leader.py``), as scalar loops compiled by numba: the 20-neighbour prediction of
``iamp bench`` is dominated by numpy's per-call overhead on short arrays otherwise.  This
module imports numba at import time: import it only through
:func:`iamp.prediction.leader.car_following.simulate`, which falls back to numpy without numba.
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = ["simulate_idm_kernel"]


@numba.njit(cache=True, error_model="numpy", nogil=True)
def simulate_idm_kernel(a_: float, b_: float, v0_: float, T: float, s0: float, x: np.ndarray, v: np.ndarray,
                        xl: np.ndarray, vl: np.ndarray, off: np.ndarray, dt: float, a_max: float, b_max: float,
                        min_gap: float) -> None:  # pragma: no cover - compiled
    c = 1.0 / (2.0 * math.sqrt(a_ * b_))
    inv_v0 = 1.0 / v0_
    B, M1 = xl.shape
    for i in range(B):
        for k in range(M1 - 1):
            vk = v[i, k]
            xlo = xl[i, k] - off[i]
            s = max(xlo - x[i, k], 0.1)
            star = s0 + max(vk * (T + c * (vk - vl[i, k])), 0.0)
            r = vk * inv_v0
            r = r * r
            q = star / s
            acc = a_ * (1.0 - r * r - q * q)
            acc = min(max(acc, -b_max), a_max)
            vn = max(vk + acc * dt, 0.0)
            xn = x[i, k] + 0.5 * dt * (vk + vn)
            cap = xl[i, k + 1] - off[i] - min_gap
            if xn > cap:
                xn = max(cap, x[i, k])
                vn = min(vn, max(vl[i, k + 1], 0.0))
            x[i, k + 1] = xn
            v[i, k + 1] = vn
