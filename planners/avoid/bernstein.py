r"""Bernstein rows: a half-plane imposed on a whole piece of a QP trajectory (SPEC §14).

On grid piece ``k`` (:math:`t \in [t_k, t_{k+1}]`, :math:`h = t_{k+1} - t_k`,
:math:`\sigma = (t - t_k)/h`) the position of either hold is the cubic Hermite interpolant
of its end states (FOH: a cubic; ZOH: a quadratic, which its Hermite interpolant reproduces):

.. math::  s(\sigma) = s_k H_{00}(\sigma) + h v_k H_{10}(\sigma) + s_{k+1} H_{01}(\sigma)
           + h v_{k+1} H_{11}(\sigma),

so on any sub-interval :math:`\sigma \in [\lambda_0, \lambda_1]` its Bernstein coefficients
(degree :math:`d \ge 3`, in :math:`\rho = (\sigma - \lambda_0)/(\lambda_1 - \lambda_0)`) are
linear in the node variables :math:`(s_k, v_k, s_{k+1}, v_{k+1})`:
:math:`b = M(\lambda_0, \lambda_1)\,(s_k, v_k, s_{k+1}, v_{k+1})^\top`
(:func:`piece_matrix`).  A vehicle's :math:`x_{s,i}(t)` is a polynomial of degree at most
``d`` and has Bernstein coefficients :math:`\beta` on the same sub-interval
(:func:`poly_bernstein`).  A polynomial lies between the smallest and largest of its
Bernstein coefficients, so the half-plane :math:`\sigma_a s - c(t) \le 0` (the table of
:mod:`iamp.planners.avoid.data`) holds on the whole sub-interval when every coefficient of
:math:`\sigma_a s - c` is :math:`\le 0`:

.. math::  \sigma_a\, M_r \cdot (s_k, v_k, s_{k+1}, v_{k+1}) \;\le\; \beta^{c}_r ,
           \qquad r = 0..d .

These rows are the certificate of the continuous-time avoidance QP
(:mod:`iamp.planners.avoid.continuous`).  The end coefficients are the states themselves
(:math:`b_0 = s(\lambda_0)`, :math:`b_d = s(\lambda_1)`), so the rows of a sub-interval
ending at the crossing time :math:`\tau` include the state at :math:`\tau`, which is linear
in the node variables.
"""

from __future__ import annotations

from functools import lru_cache
from math import comb

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

__all__ = ["HERMITE", "piece_matrix", "poly_bernstein", "power_to_bernstein", "reparametrise"]

#: Power coefficients (rows: σ⁰..σ³) of H00, H10, H01, H11 (columns).
HERMITE = np.array([[1.0, 0.0, 0.0, 0.0],
                    [0.0, 1.0, 0.0, 0.0],
                    [-3.0, -2.0, 3.0, -1.0],
                    [2.0, 1.0, -2.0, 1.0]])


def reparametrise(degree: int, lam0: float | FloatArray, width: float | FloatArray) -> FloatArray:
    r"""The matrix ``T`` with ``c' = T c``: power coefficients in :math:`\rho` of
    :math:`p(\lambda_0 + w\rho)` from those of :math:`p(\sigma)` (ascending, ``degree + 1``).

    :math:`c'_j = \sum_{i \ge j} \binom{i}{j} \lambda_0^{i-j} w^j c_i`.  Arrays ``lam0`` and
    ``width`` (broadcast together) give one matrix per entry, shape ``(..., degree + 1, degree + 1)``:
    each the same operations as for a scalar.
    """
    binom, lag = _binomials(degree)
    lam0, width = np.asarray(lam0, dtype=float), np.asarray(width, dtype=float)
    return np.asarray(binom * lam0[..., None, None] ** lag
                      * (width[..., None] ** np.arange(degree + 1))[..., :, None], dtype=float)


@lru_cache(maxsize=16)
def _binomials(degree: int) -> tuple[FloatArray, FloatArray]:
    """``C[j, i] = binom(i, j)`` (zero below the diagonal's other side) and ``max(i - j, 0)``."""
    n = degree + 1
    i = np.arange(n)
    binom = np.array([[comb(int(c), int(r)) if r <= c else 0 for c in i] for r in i], dtype=float)
    lag = np.maximum(i[None, :] - i[:, None], 0).astype(float)
    binom.flags.writeable = False
    lag.flags.writeable = False
    return binom, lag


def power_to_bernstein(degree: int) -> FloatArray:
    r"""``B`` with ``b = B c``: Bernstein coefficients on :math:`[0, 1]` of degree ``degree``
    from ascending power coefficients, :math:`b_r = \sum_{j \le r} \binom{r}{j}/\binom{d}{j}\, c_j`."""
    return _power_to_bernstein(degree).copy()


@lru_cache(maxsize=16)
def _power_to_bernstein(degree: int) -> FloatArray:
    """:func:`power_to_bernstein`, computed once per degree (read-only: callers get a copy or
    use it in products only)."""
    n = degree + 1
    B = np.zeros((n, n))
    for r in range(n):
        for j in range(r + 1):
            B[r, j] = comb(r, j) / comb(degree, j)
    B.flags.writeable = False
    return B


def piece_matrix(h: float, lam0: float, lam1: float, degree: int = 3) -> FloatArray:
    r"""``M`` (``(degree + 1) × 4``): Bernstein coefficients of the position on
    :math:`\sigma \in [\lambda_0, \lambda_1]` of a piece of length ``h`` from
    :math:`(s_k, v_k, s_{k+1}, v_{k+1})` (module docstring)."""
    if degree < 3:
        raise ValueError("the Bernstein degree must be at least 3 (the position is a cubic)")
    H = HERMITE * np.array([1.0, h, 1.0, h])  # columns act on (s_k, v_k, s_{k+1}, v_{k+1})
    Hd = np.zeros((degree + 1, 4))
    Hd[:4] = H
    return np.asarray(_power_to_bernstein(degree) @ reparametrise(degree, lam0, lam1 - lam0) @ Hd, dtype=float)


def poly_bernstein(coeffs: FloatArray, ta: float | FloatArray, tb: float | FloatArray, degree: int) -> FloatArray:
    r"""Bernstein coefficients (degree ``degree``) on :math:`t \in [t_a, t_b]` of
    :math:`p(t) = \sum_k c_k t^k` (``len(coeffs) <= degree + 1``); arrays ``ta``, ``tb`` give
    the coefficients on every interval, shape ``(..., degree + 1)``."""
    c = np.zeros(degree + 1)
    c[: len(coeffs)] = coeffs
    return np.asarray(_power_to_bernstein(degree) @ reparametrise(degree, ta, tb - ta) @ c, dtype=float)
