r"""Dimensionless form of a problem: time in units of the horizon, lengths in units of the
problem's own size.

With :math:`T = t_f` and a length :math:`L` (the largest position the problem mentions,
see :func:`length_unit`), the scaled variables are :math:`\sigma = t/T`,
:math:`\tilde s = s/L`, :math:`\tilde v = vT/L`, :math:`\tilde u = uT^2/L`,
:math:`\tilde\Phi = \Phi T^3/L`, :math:`\tilde J = J T^3/L^2` and
:math:`\tilde H = H T^4/L^2`.  The necessary conditions are invariant under this change of
units, so every solve happens on numbers of order one and every residual is compared,
dimensionless, with the tolerance table.

The vehicle polynomials become polynomials in :math:`\sigma`:
:math:`\tilde c_k = c_k T^k / L`.  Trailing coefficients whose contribution on
:math:`[0, t_f]` is below ``pmp_poly_negligible_rel`` times the polynomial's size are
dropped (a ``1e-300`` last coefficient solves exactly like the polynomial without it).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np
import numpy.typing as npt

from iamp.core.free import min_energy_cubic
from iamp.core.problem import Problem
from iamp.core.tolerances import TOLERANCES

FloatArray = npt.NDArray[np.float64]


def powers(T: float, n: int) -> FloatArray:
    """``[1, T, T², …, T^(n−1)]`` by repeated multiplication (the scalar and batched paths
    use the same products, so they give the same numbers)."""
    out: FloatArray = np.cumprod(np.r_[1.0, np.full(max(n - 1, 0), float(T))], dtype=np.float64)[:n]
    return out


def strip_negligible(coeffs: FloatArray, T: float) -> FloatArray:
    r"""``coeffs`` (ascending in ``t``) without trailing terms with
    :math:`|c_k| T^k \le \epsilon \max_j |c_j| T^j` (``ε = pmp_poly_negligible_rel``)."""
    c = np.asarray(coeffs, dtype=float)
    with np.errstate(over="ignore"):
        size = np.abs(c) * powers(T, c.size)
    big = float(np.max(size)) if c.size else 0.0
    keep = c.size
    eps = TOLERANCES["pmp_poly_negligible_rel"]
    while keep > 1 and size[keep - 1] <= eps * big:
        keep -= 1
    return c[:keep]


def hermite_sigma(s0: float, v0: float, sf: float, vf: float) -> FloatArray:
    """Ascending coefficients in ``σ`` of the unconstrained path on ``[0, 1]`` (scaled data;
    :func:`iamp.core.free.min_energy_cubic` with ``t_f = 1``)."""
    return np.array(min_energy_cubic(s0, v0, sf, vf))


def transfer_cost_sigma(s0: float, v0: float, sf: float, vf: float) -> float:
    r"""Scaled :math:`\tilde J` of one axis on ``[0, 1]``: :math:`6e^2 - 6eg + 2g^2`."""
    e = sf - s0 - v0
    g = vf - v0
    return 6 * e * e - 6 * e * g + 2 * g * g


def length_unit(problem: Problem) -> float:
    """``L``: the largest of the boundary positions, the distances the boundary speeds
    cover in ``t_f``, and the corners' coordinates (bounded by the sum of the absolute
    scaled coefficients); ``1`` if all vanish."""
    ego, T = problem.ego, problem.tf
    vals = [abs(ego.x0), abs(ego.xf), abs(ego.y0), abs(ego.yf),
            abs(ego.vx0) * T, abs(ego.vxf) * T, abs(ego.vy0) * T, abs(ego.vyf) * T]
    for v in problem.vehicles:
        c = _stripped(v.x_poly, float(T))
        vals.append(_sum_small([abs(ck * pk) for ck, pk in zip(c, _powers(float(T), len(c)))]) + abs(v.offset_x))
        vals.append(abs(v.corner_y))
    L = max(vals)
    return L if L > 0 and math.isfinite(L) else 1.0


def _powers(T: float, n: int) -> list[float]:
    """:func:`powers` as a list (the same products)."""
    out = [1.0]
    p = 1.0
    for _ in range(n - 1):
        p = p * T
        out.append(p)
    return out[:n]


def _stripped(coeffs: Sequence[float], T: float) -> list[float]:
    """:func:`strip_negligible` in scalar code (the same comparisons)."""
    c = [float(x) for x in coeffs]
    n = len(c)
    size = []
    for ck, pk in zip(c, _powers(T, n)):
        try:
            size.append(abs(ck) * pk)
        except OverflowError:  # pragma: no cover - float products give inf, never raise
            size.append(math.inf)
    if not n:
        return c
    big = size[0]
    for x in size:  # np.max: NaN wins
        if x > big or x != x:
            big = x
            if x != x:
                break
    keep = n
    eps = TOLERANCES["pmp_poly_negligible_rel"]
    while keep > 1 and size[keep - 1] <= eps * big:
        keep -= 1
    return c[:keep]


def _sum_small(a: list[float]) -> float:
    """``np.sum`` of a short vector in numpy's order (plain loop below 8 terms)."""
    if len(a) >= 8:
        return float(np.sum(np.array(a)))
    res = -0.0
    for x in a:
        res += x
    return res


@dataclass(frozen=True)
class Units:
    """Time unit ``T`` (s) and length unit ``L`` (m) with the derived units."""

    T: float
    L: float

    def __post_init__(self) -> None:
        # the derived units once, here: later reads are plain attributes (no call, scripts/walk.py)
        self.vel, self.acc, self.jerk, self.cost, self.ham  # noqa: B018

    @cached_property
    def vel(self) -> float:
        return self.L / self.T

    @cached_property
    def acc(self) -> float:
        return self.L / self.T**2

    @cached_property
    def jerk(self) -> float:
        """Unit of ``p1``, ``p3`` and of the jumps ``Φ``."""
        return self.L / self.T**3

    @cached_property
    def cost(self) -> float:
        return self.L**2 / self.T**3

    @cached_property
    def ham(self) -> float:
        """Unit of ``H`` and of the Hamiltonian-jump residual ``r = ∂J/∂t``."""
        return self.L**2 / self.T**4


@dataclass(frozen=True)
class Scaled:
    """A problem in scaled units.

    Attributes
    ----------
    units : Units
    ego : ndarray (8,)
        ``(x0, vx0, xf, vxf, y0, vy0, yf, vyf)`` scaled.
    EX, EY : ndarray (m, d), (m, 4)
        Ascending ``σ``-coefficients of ``e_x,i = (corner_x,i − s̄_x)/L`` and
        ``e_y,i = (corner_y,i − s̄_y)/L``.
    CX : ndarray (m, d)
        ``σ``-coefficients of ``corner_x,i / L`` (for the corner speed).
    CY : ndarray (m,)
        ``corner_y,i / L``.
    jbar : float
        Scaled cost of the unconstrained path.
    """

    units: Units
    ego: FloatArray
    EX: FloatArray
    EY: FloatArray
    CX: FloatArray
    CY: FloatArray
    jbar: float

    def __post_init__(self) -> None:
        self.m  # noqa: B018 - once, here: later reads are plain attributes

    @cached_property
    def m(self) -> int:
        return int(self.EX.shape[0])


def scale_problem(problem: Problem) -> Scaled:
    """The dimensionless data of ``problem`` (see the module docstring)."""
    T = float(problem.tf)
    L = length_unit(problem)
    ego = problem.ego
    e = [ego.x0 / L, ego.vx0 * T / L, ego.xf / L, ego.vxf * T / L,
         ego.y0 / L, ego.vy0 * T / L, ego.yf / L, ego.vyf * T / L]
    ea = np.array(e)
    e = ea.tolist()
    hx, hy = _hermites(e)
    polys = []
    for v in problem.vehicles:
        c = _stripped(v.x_poly, T)
        cs = [ck * pk / L for ck, pk in zip(c, _powers(T, len(c)))]
        cs[0] += v.offset_x / L
        polys.append(cs)
    d = max(4, max(len(p) for p in polys))
    CXl = [p + [0.0] * (d - len(p)) for p in polys]
    EXl = [[r[k] - hx[k] if k < 4 else r[k] for k in range(d)] for r in CXl]
    CYl = [v.corner_y / L for v in problem.vehicles]
    EYl = [[cy - hy[0], -hy[1], -hy[2], -hy[3]] for cy in CYl]
    jbar = transfer_cost_sigma(*e[:4]) + transfer_cost_sigma(*e[4:])
    m = len(polys)
    return Scaled(Units(T, L), ea, np.array(EXl).reshape(m, d), np.array(EYl).reshape(m, 4),
                  np.array(CXl).reshape(m, d), np.array(CYl), float(jbar))


def _hermites(e: list[float]) -> tuple[list[float], list[float]]:
    """:func:`hermite_sigma` of the x axis (``e[:4]``) and of the y axis (``e[4:]``) as lists, in
    one elementwise call (numpy's float64 arithmetic is the floats', bit for bit)."""
    a = np.array(e).reshape(2, 4)
    cubic = min_energy_cubic(a[:, 0], a[:, 1], a[:, 2], a[:, 3])
    return [float(c[0]) for c in cubic], [float(c[1]) for c in cubic]
