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
    (``ex``, ``ey`` ascending in ``σ``)."""
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
