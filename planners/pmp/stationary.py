r"""The stationary points of the one-vehicle value function in scaled time.

For one vehicle the scaled value function is :math:`\tilde J(\sigma) = \bar J + \tfrac12 N(\sigma)/\tilde K(\sigma)`
with :math:`N = e_x^2 + e_y^2` and :math:`\tilde K \propto \sigma^3(1-\sigma)^3`, so
:math:`d\tilde J/d\sigma = 0` in :math:`(0, 1)` exactly where the polynomial
:math:`P = N'\sigma(1-\sigma) - 3N(1-2\sigma)` vanishes.  Used by the search
(:mod:`.search`) and by the value function's one-vehicle stationary points (:mod:`.fixed`).
"""

from __future__ import annotations

from collections.abc import Sequence

from .jit import compilable
from .roots import unit_roots


@compilable
def stationarity_poly(ex: Sequence[float], ey: Sequence[float]) -> list[float]:
    """Ascending coefficients of ``P = N'σ(1−σ) − 3N(1−2σ)`` with ``N = ex² + ey²``
    (``ex``, ``ey`` ascending in ``σ``).  The common case (cubic ``x_poly``: four
    coefficients per axis) is written out term by term with the loops' order of floating
    operations (bit-identical, tested)."""
    if len(ex) == 4 and len(ey) == 4:
        x0, x1, x2, x3 = float(ex[0]), float(ex[1]), float(ex[2]), float(ex[3])
        y0, y1, y2, y3 = float(ey[0]), float(ey[1]), float(ey[2]), float(ey[3])
        n0 = 0.0 + (x0 * x0 + y0 * y0)
        n1 = (0.0 + (x0 * x1 + y0 * y1)) + (x1 * x0 + y1 * y0)
        n2 = ((0.0 + (x0 * x2 + y0 * y2)) + (x1 * x1 + y1 * y1)) + (x2 * x0 + y2 * y0)
        n3 = (((0.0 + (x0 * x3 + y0 * y3)) + (x1 * x2 + y1 * y2)) + (x2 * x1 + y2 * y1)) + (x3 * x0 + y3 * y0)
        n4 = ((0.0 + (x1 * x3 + y1 * y3)) + (x2 * x2 + y2 * y2)) + (x3 * x1 + y3 * y1)
        n5 = (0.0 + (x2 * x3 + y2 * y3)) + (x3 * x2 + y3 * y2)
        n6 = 0.0 + (x3 * x3 + y3 * y3)
        d1 = 1 * n1
        d2 = 2 * n2
        d3 = 3 * n3
        d4 = 4 * n4
        d5 = 5 * n5
        d6 = 6 * n6
        return [0.0 - 3 * n0,
                ((0.0 + d1) + 6 * n0) - 3 * n1,
                ((0.0 - d1) + d2) + 6 * n1 - 3 * n2,
                ((0.0 - d2) + d3) + 6 * n2 - 3 * n3,
                ((0.0 - d3) + d4) + 6 * n3 - 3 * n4,
                ((0.0 - d4) + d5) + 6 * n4 - 3 * n5,
                ((0.0 - d5) + d6) + 6 * n5 - 3 * n6,
                (0.0 - d6) + 6 * n6]
    return stationarity_poly_loops(ex, ey)


@compilable
def stationarity_poly_loops(ex: Sequence[float], ey: Sequence[float]) -> list[float]:
    """:func:`stationarity_poly` for any number of coefficients (the general loops)."""
    d = max(len(ex), len(ey))
    x = [0.0] * d
    y = [0.0] * d
    for k in range(len(ex)):
        x[k] = float(ex[k])
    for k in range(len(ey)):
        y[k] = float(ey[k])
    N = [0.0] * (2 * d - 1)
    for i in range(d):
        xi = x[i]
        yi = y[i]
        for j in range(d):
            N[i + j] += xi * x[j] + yi * y[j]
    Pc = [0.0] * (len(N) + 1)
    for k in range(1, len(N)):
        dk = k * N[k]
        Pc[k] += dk
        Pc[k + 1] -= dk
    for k in range(len(N)):
        Pc[k] -= 3 * N[k]
        Pc[k + 1] += 6 * N[k]
    return Pc


@compilable
def stationary_sigmas(ex: Sequence[float], ey: Sequence[float]) -> list[float]:
    """Every zero of ``dJ̃/dσ`` in ``(0, 1)`` for one vehicle (sorted)."""
    return unit_roots(stationarity_poly(ex, ey))
