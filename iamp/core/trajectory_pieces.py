r"""A plan's trajectory as exact polynomial pieces (for the safety report, SPEC §9).

Every planner's trajectory is piecewise polynomial: the PMP's position is a cubic between
contact times, a QP's is a cubic (FOH) or quadratic (ZOH) between grid nodes.  The pieces'
ends come from the trajectory (:func:`breakpoints`: ``breakpoints()``, else ``t_nodes``, else
the contact times).  On each piece :math:`[a, b]`, :math:`h = b - a`, the ego's position is
rebuilt from the trajectory's own evaluation as the Taylor polynomial

.. math::  s(a + h\sigma) = s_a + v_a h\sigma + \tfrac12 u_a h^2\sigma^2 + \tfrac16 j h^3\sigma^3,
           \qquad j = \frac{u(a + h/2) - u_a}{h/2},\quad \sigma \in [0, 1]

(:func:`taylor_pieces`), and checked against the trajectory's position and speed at
:math:`b`.  A vehicle's :math:`x_{s,i}(t)` on the same pieces is :func:`shifted_poly`.
A trajectory of unknown structure, or one that fails the end check, is cut into pieces of
:data:`FALLBACK_PIECE_S` (1 ms; SPEC §9 allows a grid of at most 1 ms) instead.
"""

from __future__ import annotations

from collections.abc import Sequence
from math import comb
from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["FALLBACK_PIECE_S", "MERGE_S", "PiecewiseTrajectory", "breakpoints", "cut_times", "merged_times",
           "shifted_poly", "taylor_pieces"]

FloatArray = NDArray[np.float64]

#: Cut points closer than this [s] are merged.
MERGE_S = 1e-9
#: Fallback piece length [s] for trajectories of unknown structure.
FALLBACK_PIECE_S = 1e-3


class PiecewiseTrajectory(Protocol):
    """What the safety report evaluates: states ``(s_x, v_x, s_y, v_y)`` and inputs ``(u_x, u_y)``."""

    def states(self, t: ArrayLike) -> FloatArray: ...

    def inputs(self, t: ArrayLike) -> FloatArray: ...


def breakpoints(traj: object, tf: float) -> FloatArray | None:
    """The piece ends ``0 = b_0 < … < b_P = t_f`` of ``traj`` (merged within :data:`MERGE_S`),
    or None when the trajectory does not say where its pieces are."""
    bp: Any = getattr(traj, "breakpoints", None)
    if callable(bp):
        bp = bp()
    if bp is None and getattr(traj, "t_nodes", None) is not None:
        bp = traj.t_nodes  # type: ignore[attr-defined]
    if bp is None and getattr(traj, "contact_times", None) is not None:
        ct: FloatArray = np.asarray(getattr(traj, "contact_times"), dtype=np.float64).ravel()  # noqa: B009
        bp = ct[(ct > 0) & (ct < tf)]
    if bp is None:
        return None
    # numpy.unique's sort of the same array, the times outside [0, tf] (and NaN) dropped, then
    # the merge: an exact duplicate differs by 0 from the first of its run, which numpy.unique
    # keeps and the merge keeps too (the merge of merged_times; the same numbers)
    t = np.concatenate(([0.0], np.asarray(bp, dtype=float).ravel(), [float(tf)]))
    t.sort()
    b = t[(t >= 0) & (t <= tf)]
    keep = np.empty(b.size, dtype=np.bool_)
    keep[0] = True
    np.greater(b[1:] - b[:-1], MERGE_S, out=keep[1:])
    b = b[keep]
    b[-1] = tf
    return b


def taylor_pieces(traj: PiecewiseTrajectory, breaks: FloatArray) -> tuple[FloatArray, float]:
    """Per piece and axis, the position's coefficients in ``σ ∈ [0, 1]`` (ascending, 4 each):
    shape ``(P, 2, 4)``, plus the largest end-of-piece mismatch (position and speed)."""
    a, b = breaks[:-1], breaks[1:]
    h = b - a
    P = a.size
    # the states at both ends, the inputs at the start and the middle, each in one call (a
    # trajectory is evaluated point by point: the numbers of one call per set of times)
    Xab = traj.states(np.concatenate((a, b)))
    Xa, Xb = Xab[:P], Xab[P:]
    Uam = traj.inputs(np.concatenate((a, 0.5 * (a + b))))
    Ua, Um = Uam[:P], Uam[P:]
    jerk = (Um - Ua) / (0.5 * h)[:, None]
    C = np.empty((a.size, 2, 4))
    hh = h[:, None]
    # the position's and the speed's columns as slices (the numbers of indexing with lists)
    C[:, :, 0] = Xa[:, 0:3:2]
    C[:, :, 1] = Xa[:, 1:4:2] * hh
    C[:, :, 2] = Ua * hh**2 / 2
    C[:, :, 3] = jerk * hh**3 / 6
    s_end = C.sum(axis=2)
    v_end = (C[:, :, 1] + 2 * C[:, :, 2] + 3 * C[:, :, 3]) / hh
    scale = max(1.0, float(np.abs(Xb).max()))
    mismatch = max(float(np.abs(s_end - Xb[:, 0:3:2]).max()), float(np.abs(v_end - Xb[:, 1:4:2]).max()))
    return C, mismatch / scale


def shifted_poly(coeffs: Sequence[float], a: FloatArray, h: FloatArray, degree: int) -> FloatArray:
    """Coefficients of ``p(a + h σ)`` in ``σ`` (ascending), shape ``(len(a), degree + 1)``:
    :math:`\\sum_{k} \\sigma^k h^k \\sum_{j \\ge k} c_j \\binom{j}{k} a^{j-k}`."""
    c = np.zeros(degree + 1)
    c[:len(coeffs)] = coeffs
    out = np.zeros((a.size, degree + 1))
    powers: dict[int, FloatArray] = {}  # a ** e, each computed once (the same numbers)
    for k in range(degree + 1):
        acc = np.zeros(a.size)
        for j in range(k, degree + 1):
            if c[j] != 0.0:
                ae = powers.get(j - k)
                if ae is None:
                    ae = powers[j - k] = a ** (j - k)
                acc += c[j] * comb(j, k) * ae
        out[:, k] = acc * h**k
    return out


def cut_times(breaks: FloatArray, p: NDArray[np.intp], sigma: FloatArray) -> FloatArray:
    """The piece ends plus the roots ``σ`` of piece ``p``, as sorted times (merged within 1 ns):
    :func:`merged_times` of the times :math:`a_p + h_p σ`."""
    a, h = breaks[:-1], np.diff(breaks)
    return merged_times(breaks, a[p] + h[p] * sigma)


def merged_times(breaks: FloatArray, times: FloatArray) -> FloatArray:
    r"""The piece ends plus ``times``, as sorted times merged within 1 ns (:data:`MERGE_S`).

    The times :math:`t_0 \le t_1 \le \dots` sorted (as ``numpy.unique`` sorts: the same sort of
    the same array), then :math:`t_j` kept where :math:`t_j - t_{j-1} > 10^{-9}` (and :math:`t_0`):
    the numbers of ``numpy.unique`` followed by that merge, without its overhead.  An exact
    duplicate has difference 0 and is dropped, as ``numpy.unique`` drops it; the first of a run
    of equal values is the one kept by both (a ``+0``/``-0`` pair too), and the next distinct
    value's difference is to that same value; a NaN's difference is NaN, never kept after the
    first place, where ``numpy.unique`` keeps one NaN that the merge then drops.  The last time
    is set to the last piece end.
    """
    t = np.concatenate((breaks, times))
    t.sort()
    keep = np.empty(t.size, dtype=np.bool_)
    keep[0] = True
    np.greater(t[1:] - t[:-1], MERGE_S, out=keep[1:])
    out: FloatArray = t[keep]
    out[-1] = breaks[-1]
    return out
