"""The IDM forward simulation, written once (issue 32: one implementation per algorithm).

:func:`idm_forward` is plain Python over flat sequences of floats (scalar loops, nothing numba
lacks).  :func:`iamp.prediction.leader.car_following.simulate` runs it compiled by numba
(``numba.njit`` of this very function, no fastmath, kept in numba's on-disk cache) when numba is
importable, and as Python otherwise: the same IEEE operations in the same order, so both give
the same numbers bit for bit (``tests/test_leader_kernel.py``), and no prediction depends on
whether numba is installed.  The operation order is that of the numba kernel it replaces (the
closed loop's episodes are unchanged, bit for bit).  Nothing here imports numba until
:func:`compiled` is called.
"""

from __future__ import annotations

import importlib.util
import math
from collections.abc import Callable, MutableSequence, Sequence
from typing import Any

__all__ = ["compiled", "idm_forward"]


def idm_forward(a_: float, b_: float, v0_: float, T: float, s0: float, x: MutableSequence[float],
                v: MutableSequence[float], xl: Sequence[float], vl: Sequence[float], off: Sequence[float], B: int,
                M1: int, dt: float, a_max: float, b_max: float, min_gap: float) -> None:
    """Integrate IDM along ``B`` leader trajectories of ``M1`` nodes, in place.

    Row ``i`` occupies the flat indices ``i M1 .. i M1 + M1 - 1`` of ``x``, ``v``, ``xl``, ``vl``
    (C order of a ``(B, M1)`` array).  Per step (module docstring of
    :mod:`~iamp.prediction.leader.car_following`): gap ``s = max(xl - off - x, 0.1)``, IDM's
    acceleration clipped to ``[-b_max, a_max]``, speed clamped at 0, trapezoidal position, and
    the position held at most at the leader's rear minus ``min_gap`` (speed then at most the
    leader's).

    Parameters
    ----------
    a_, b_, v0_, T, s0 : float
        IDM's parameters.
    x, v : mutable sequence of float, length ``B M1``
        Follower positions and speeds; the first node of each row is the initial state, the
        others are written.
    xl, vl : sequence of float, length ``B M1``
        Leader centre positions and speeds.
    off : sequence of float, length ``B``
        Half the sum of the two lengths per row.
    B, M1 : int
        Rows and nodes per row.
    dt : float
        Step [s].
    a_max, b_max, min_gap : float
        Acceleration clip [m/s²] and smallest gap [m].
    """
    c = 1.0 / (2.0 * math.sqrt(a_ * b_))
    inv_v0 = 1.0 / v0_
    for i in range(B):
        o = off[i]
        for j in range(i * M1, i * M1 + M1 - 1):
            vk = v[j]
            xlo = xl[j] - o
            s = max(xlo - x[j], 0.1)
            star = s0 + max(vk * (T + c * (vk - vl[j])), 0.0)
            r = vk * inv_v0
            r = r * r
            q = star / s
            acc = a_ * (1.0 - r * r - q * q)
            acc = min(max(acc, -b_max), a_max)
            vn = max(vk + acc * dt, 0.0)
            xn = x[j] + 0.5 * dt * (vk + vn)
            cap = xl[j + 1] - o - min_gap
            if xn > cap:
                xn = max(cap, x[j])
                vn = min(vn, max(vl[j + 1], 0.0))
            x[j + 1] = xn
            v[j + 1] = vn


_COMPILED: list[Callable[..., Any] | None] = []


def compiled() -> Callable[..., Any] | None:
    """:func:`idm_forward` compiled by numba (``cache=True``), or ``None`` when numba is not
    importable or fails to compile (cached per process).

    Returns
    -------
    callable or None
        The compiled function, called with flat ``numpy`` arrays in place of the sequences.
    """
    if not _COMPILED:
        fn: Callable[..., Any] | None = None
        if importlib.util.find_spec("numba") is not None:
            try:
                import numba
                import numpy as np

                jitted: Callable[..., Any] = numba.njit(cache=True, nogil=True)(idm_forward)
                one = np.zeros(2)
                jitted(1.0, 1.0, 30.0, 1.0, 2.0, one.copy(), one.copy(), np.array([10.0, 10.0]), one, np.zeros(1), 1, 2,
                       0.1, 3.0, 8.0, 0.5)  # compiles now (or loads numba's cache)
                fn = jitted
            except Exception:  # a broken numba install: the Python path (the same numbers) stays
                fn = None
        _COMPILED.append(fn)
    return _COMPILED[0]
