r"""Lower bounds of the continuous-time avoidance QP over crossing-time boxes by weak duality.

For a crossing time :math:`\tau` the QP (:class:`~iamp.planners.avoid.continuous.ContinuousAvoidQP`)
is :math:`J(\tau) = \min \tfrac12 z^\top P z` s.t. :math:`Ez = e`, :math:`G(\tau) z \le h(\tau)`.
For **any** :math:`y \ge 0` on rows that every :math:`J(\tau)`, :math:`\tau` in a box, imposes (or
implies), weak duality gives

.. math::  J(\tau) \;\ge\; g(y; \tau) = \min_{Ez = e}\; \tfrac12 z^\top P z + y^\top (G(\tau) z - h(\tau)),

a bound that holds whatever solver produced :math:`y` and however accurate it is.  The inner
minimum is one solve with the fixed KKT matrix :math:`\begin{pmatrix}P & E^\top\\ E & 0\end{pmatrix}`
(factored once per grid, :class:`DualBounds`; with the node solver, from the columns of
:math:`K^{-1}` it keeps and its equality optimum, the same system).

Where a vehicle's box lies within one grid piece ``k`` (:math:`\tau_i = t_k + \lambda_i h`), the
rows that depend on :math:`\tau_i` are the Bernstein rows of the two sub-pieces
:math:`[0, \lambda_i]` (first half-plane) and :math:`[\lambda_i, 1]` (second) of piece ``k``;
their values and bounds are polynomials of degree at most ``d`` in :math:`\lambda_i`
(:func:`~iamp.planners.avoid.bernstein.piece_matrix`, :func:`~iamp.planners.avoid.bernstein.poly_bernstein`),
so the minimiser is polynomial in :math:`\lambda` and :math:`g(y; \tau)` is a polynomial of
degree at most ``2d`` in each :math:`\lambda_i` (:class:`DualPolynomial`).  Its minimum over a
box is bounded below by the smallest of its tensor Bernstein coefficients on the box
(:meth:`DualPolynomial.lower_bound`), a bound that is exact to second order in the box's width.

The multipliers :math:`y` are those of a solved candidate :math:`J(\tau_c)`, :math:`\tau_c` in the
box, kept on the rows that stay valid over the whole box:

* a vehicle whose box lies in one piece ``k`` (*polynomial*): the first half-plane's rows on the
  pieces before ``k``, the second's after ``k`` (unchanged), and both sub-pieces of ``k`` with
  the candidate's multipliers per Bernstein index (their rows then move with :math:`\lambda_i`);
* a vehicle whose box spans several pieces (*fixed*): the first half-plane's rows on pieces
  that end before the box, the second's on pieces that start after it;
* the physical-limit rows (never depend on :math:`\tau`).

Every other row's multiplier is set to zero, which keeps :math:`y` dual feasible.  At
:math:`\tau = \tau_c` (all vehicles polynomial) the bound equals the candidate's dual value, which
is :math:`J(\tau_c)` at the solver's optimum: the bound is tight there and falls off
quadratically, where the relaxation of :mod:`iamp.planners.avoid.continuous` (rows dropped
inside the box) falls off linearly in the box's width.  A round-off margin
(:data:`ROUND_OFF_REL`) is subtracted.

With **one** polynomial vehicle the multipliers need not stay fixed: weak duality holds for every
:math:`y \ge 0`, so they may move with :math:`\lambda` along their tangent,
:math:`y(\lambda) = y_c + (\lambda - \lambda_c)\,\dot y`, the derivative of the optimal
multipliers with the binding rows held (:meth:`DualBounds.tangent`, one small solve with the
Schur complement of those rows).  The dual function is concave in :math:`y` and maximal at the
optimal multipliers, so an error of second order in :math:`y` costs fourth order in the bound:
:math:`g(y(\lambda); \lambda)` agrees with :math:`J` to second order at the candidate and falls
below it as :math:`(\lambda - \lambda_c)^4` (``tests/test_avoid_dual.py``), a polynomial of degree
``2d + 2`` (:math:`z` and :math:`y^\top h` gain one degree).  Where a multiplier on its tangent would
turn negative within the box its slope is cut to keep it nonnegative (still a bound, no longer
second order); the store keeps, beside the piece's polynomial, the one on the interval where no
slope is cut (:meth:`DualBounds.tangent_interval`, :meth:`DualStore.near`).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from functools import lru_cache
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from numpy.typing import NDArray

from . import dual_kernel, search_kernel
from .bernstein import _binomials, _power_to_bernstein
from .schur import _run, full_hessian, kkt_matrix

if TYPE_CHECKING:
    from .continuous import ContinuousAvoidQP, Solved

FloatArray = NDArray[np.float64]

__all__ = ["ROUND_OFF_REL", "ROUND_OFF_TERMS", "DualBounds", "DualPolynomial", "DualStore", "Packing",
           "fit_polynomial", "fit_polynomials", "grid_minimum", "lower_bounds", "max_lower_bound", "piece_of"]

#: Subtracted from every bound, relative to ``max(1, |bound|)``: the bound is computed in floating
#: point (one sparse LU solve, or a sum of columns of ``K⁻¹``, and a Bernstein transform); far
#: below the search's gap (1e-4).
ROUND_OFF_REL = 1e-9
#: Times the size of the terms that cancel in ``g`` (:attr:`DualPolynomial.roundoff`): the
#: coefficients are sums of products of those terms, each exact to a few units of round-off
#: times its size (``tests/test_avoid_dual.py``: a nearly infeasible candidate's terms of 1e15
#: left 0.57 in a value of 2).
ROUND_OFF_TERMS = 1e-12


def piece_of(lo: float, hi: float, h: float, N: int) -> int | None:
    """The grid piece ``k`` with ``[lo, hi] ⊂ [k h, (k + 1) h]`` (to round-off), or ``None``."""
    k = min(max(math.floor(lo / h + 1e-9), 0), N - 1)  # numpy.floor's integer, without its scalar overhead
    return k if hi <= (k + 1) * h * (1 + 1e-12) + 1e-12 else None


def fit_polynomial(values: FloatArray, degree: int) -> FloatArray:
    """Power coefficients (axis 0) of the polynomials of ``degree`` sampled at ``λ_j = j/degree``
    (:func:`fit_polynomials` of a stack of one)."""
    out: FloatArray = fit_polynomials(values[np.newaxis], degree)[0]
    return out


def fit_polynomials(values: FloatArray, degree: int) -> FloatArray:
    """:func:`fit_polynomial` of every ``values[m]`` (samples on axis 1), in one stacked solve:
    numpy's solve runs LAPACK's ``gesv`` on each ``(degree + 1) × (degree + 1)`` system of the stack
    on its own, so each result is bit for bit the one of ``fit_polynomial(values[m], degree)``."""
    shape = values.shape
    return np.asarray(np.linalg.solve(_vander(degree), values.reshape(shape[0], degree + 1, -1)).reshape(shape),
                      dtype=float)


def _vander(degree: int) -> FloatArray:
    """The Vandermonde matrix of :func:`fit_polynomial`'s samples ``λ_j = j/degree`` (built once)."""
    V = _VANDER.get(degree)
    if V is None:
        V = _VANDER[degree] = np.vander(np.linspace(0.0, 1.0, degree + 1), degree + 1, increasing=True)
        V.flags.writeable = False
    return V


#: per degree, the Vandermonde matrix of :func:`fit_polynomial`'s samples (built once)
_VANDER: dict[int, FloatArray] = {}


#: per ``(q, D)``: :meth:`DualBounds._exponents` and :meth:`DualBounds._flat` (shared by every grid)
_EXPONENTS: dict[tuple[int, int], tuple[tuple[NDArray[np.int64], ...], tuple[NDArray[np.int64], ...]]] = {}
_FLATS: dict[tuple[int, int], NDArray[np.int64]] = {}

#: :meth:`_Binding.split_rows` of a piece without a binding row (empty; writeable like the arrays it
#: stands for, as the kernels take them)
_NO_ROWS = np.zeros(0, dtype=np.intp)


@dataclass(frozen=True)
class _Binding:
    """The rows of a solved candidate with a positive multiplier (:meth:`DualBounds._binding`):
    the candidate's imposed rows and bounds, the positions ``nz`` of the binding rows among them,
    their multipliers, and per row whether it is a Bernstein row, its vehicle, half-plane, piece
    and Bernstein index (from its layout number)."""

    A_in: sp.csr_matrix
    u_in: FloatArray
    nz: NDArray[np.int64]
    y: FloatArray
    bern: NDArray[np.bool_]
    veh: NDArray[np.int64]
    plane: NDArray[np.int64]
    piece: NDArray[np.int64]
    j: NDArray[np.int64]
    #: ``A_in``'s CSR arrays (int64 indices, as the node solver's kernels take them)
    indptr: NDArray[np.int64]
    indices: NDArray[np.int64]
    data: FloatArray
    #: the columns of the binding rows' entries (the rows of ``K⁻¹`` their tangent reads)
    cols: NDArray[np.int64]
    #: per vehicle, the sum of the multipliers on its Bernstein rows (:meth:`DualBounds.mass`;
    #: read-only, shared by every polynomial of the solution)
    mass: FloatArray
    #: per vehicle, the axes of its first and second half-planes (its spec's ``f``, ``s``)
    first: NDArray[np.int64]
    second: NDArray[np.int64]
    #: per vehicle, whether it binds (``mass > 0`` as Python booleans)
    binds: tuple[bool, ...]
    #: :meth:`DualBounds._split_blocks` per ``(vehicle, piece)``, each block with its terms of
    #: :meth:`DualBounds.polynomial` (``σ (y_j M)ᵀ``, ``rhs · y_j``), computed once per solution
    blocks: dict[tuple[int, int], list[tuple[FloatArray, FloatArray, FloatArray, float, NDArray[np.int64],
                                             FloatArray, FloatArray]]] = field(default_factory=dict)
    #: :meth:`DualBounds.tangent` per ``(vehicle, piece)``, computed once per solution
    tangents: dict[tuple[int, int], FloatArray] = field(default_factory=dict)
    #: :meth:`DualBounds._halves` per ``(vehicle, piece)``, computed once per solution
    halves: dict[tuple[int, int], tuple[tuple[NDArray[np.int64], FloatArray, FloatArray, float,
                                              NDArray[np.int64]], ...]] = field(default_factory=dict)
    #: per ``(vehicle, piece)``, the columns of ``K⁻¹`` the tangent and the polynomial read (the
    #: binding rows' entries and the split piece's node columns), and whether the node solver has
    #: them solved already
    entries: dict[tuple[int, int], NDArray[np.int64]] = field(default_factory=dict)
    solved: set[tuple[int, int]] = field(default_factory=set)
    #: :meth:`split_rows` per ``(vehicle, half-plane axis, piece)`` (filled on first use)
    _split: dict[tuple[int, int, int], NDArray[np.int64]] = field(default_factory=dict)

    def split_rows(self, i: int, pl: int, k: int) -> NDArray[np.int64]:
        """The positions (ascending) of the binding Bernstein rows of vehicle ``i``'s half-plane
        axis ``pl`` on piece ``k``: ``numpy.flatnonzero`` of those rows
        (:func:`~iamp.planners.avoid.dual_kernel.select_rows`, once per solution and key)."""
        key = (i, pl, k)
        out = self._split.get(key)
        if out is None:
            out = _run("select_rows", dual_kernel)(self.bern, self.veh, self.plane, self.piece, i, pl, k)
            if not out.size:
                out = _NO_ROWS
            self._split[key] = out
        return out


@dataclass(frozen=True)
class DualPolynomial:
    r"""``g(y; τ)`` of one dual vector over a box: a tensor polynomial in the ``λ_i`` of its
    polynomial vehicles (:mod:`module docstring <iamp.planners.avoid.dual>`).

    Attributes
    ----------
    vehicles : tuple of int
        The polynomial vehicles (one tensor axis each, in this order).
    pieces : tuple of int
        Their grid pieces ``k``: ``τ_i = t_k + λ_i h``.
    coef : ndarray
        Power coefficients, shape ``(2d + 1,) * len(vehicles)``, or ``(2d + 3,)`` for one
        polynomial vehicle (the multipliers on their tangent, :attr:`second_order`).
    h : float
        The grid step.
    mass : ndarray, shape (m,)
        Per vehicle, the sum of the candidate's multipliers on that vehicle's rows (zero: the
        vehicle does not bind at the candidate).
    """

    vehicles: tuple[int, ...]
    pieces: tuple[int, ...]
    coef: FloatArray
    h: float
    mass: FloatArray
    #: The multipliers follow their tangent in the crossing time (:meth:`DualBounds.tangent`, one
    #: polynomial vehicle): ``g`` then agrees with ``J`` to second order at the candidate, so its
    #: curvature there is ``J``'s (where the binding set does not change).
    second_order: bool = False
    #: A bound on the round-off of the polynomial's values (:data:`ROUND_OFF_TERMS` times the size
    #: of the terms that cancel in ``g``), subtracted by :meth:`lower_bound` besides
    #: :data:`ROUND_OFF_REL`.
    roundoff: float = 0.0

    @functools.cached_property
    def binds(self) -> tuple[bool, ...]:
        """Per vehicle of :attr:`mass`, whether its multipliers' sum is positive (``mass > 0`` as
        Python booleans; computed once)."""
        return tuple(x > 0 for x in np.asarray(self.mass, dtype=float).ravel().tolist())

    @functools.cached_property
    def meta(self) -> NDArray[np.int64]:
        """Its row for the search kernels (:func:`_pack`): ``q`` (its axes), ``n`` (coefficients per
        axis), its size, then its vehicles and their pieces, each padded with zeros to
        ``W = max(m, q, 1)`` (``m`` the vehicles of :attr:`mass`); computed once, read-only."""
        q = self.coef.ndim
        W = max(int(np.size(self.mass)), q, 1)
        pad = (0,) * (W - q)
        row = np.array((q, int(self.coef.shape[0]) if q else 1, self.coef.size) + tuple(self.vehicles) + pad
                       + tuple(self.pieces) + pad, dtype=np.int64)
        row.flags.writeable = False
        return row

    def lower_bound(self, lo: FloatArray, hi: FloatArray) -> float:
        """A lower bound of ``g`` (hence of every ``J(τ)``) over the box ``lo <= τ <= hi`` (a
        sub-box of the box the polynomial was built for): its smallest tensor Bernstein coefficient
        on the box, less the round-off margin (:func:`lower_bounds`)."""
        return lower_bounds([self], lo, hi)[0]

    def evaluate(self, taus: FloatArray) -> FloatArray:
        """``g`` at the crossing times ``taus`` (shape ``(n, m)``; every polynomial vehicle's
        time in its piece)."""
        return self._values(self.coef, taus)

    def slope(self, tau: FloatArray, vehicle: int) -> float:
        """``∂g/∂τ_vehicle`` at ``tau`` (zero for a vehicle that is not polynomial).  Where
        ``J`` is differentiable at the candidate's ``τ_c`` this is ``∂J/∂τ`` there: ``g <= J``
        touches ``J`` at ``τ_c``."""
        if vehicle not in self.vehicles:
            return 0.0
        return self._derivative_at(tau, self.vehicles.index(vehicle), 1)

    def curvature(self, tau: FloatArray, vehicle: int) -> float:
        """``∂²g/∂τ_vehicle²`` at ``tau`` (zero for a vehicle that is not polynomial); with
        :attr:`second_order`, ``J``'s curvature at the candidate."""
        if vehicle not in self.vehicles:
            return 0.0
        return self._derivative_at(tau, self.vehicles.index(vehicle), 2)

    def _derivative_at(self, tau: FloatArray, axis: int, order: int) -> float:
        """The ``order``-th derivative of ``g`` in ``τ`` along tensor axis ``axis`` at ``tau``: the
        coefficients of ``numpy.polynomial.polynomial.polyder`` (``der[j - 1] = j c[j]``, once per
        order: the same products in the same order), divided by ``h^order``, padded with zeros to
        the coefficients' shape and evaluated by :func:`polys_values`."""
        c = np.moveaxis(self.coef, axis, 0) if self.coef.ndim > 1 else self.coef
        n = c.shape[0]
        for _ in range(order):
            n -= 1
            c = np.arange(1, n + 1, dtype=float).reshape((n,) + (1,) * (c.ndim - 1)) * c[1:]
        der = np.zeros_like(self.coef)
        lead = np.moveaxis(der, axis, 0) if der.ndim > 1 else der
        lead[:n] = c / self.h ** order
        return float(self._values(der, np.asarray(tau, dtype=float)[None, :])[0])

    def _values(self, coef: FloatArray, taus: FloatArray) -> FloatArray:
        return polys_values([self], np.atleast_2d(np.asarray(taus, dtype=float)), [coef])


def _pack(polys: Sequence[DualPolynomial], coefs: Sequence[FloatArray] | None = None,
          packing: Packing | None = None) -> tuple[FloatArray, NDArray[np.int64], int, int]:
    """``polys`` as the search kernels take them (:func:`~iamp.planners.avoid.search_kernel.polys_max`):
    their coefficients (``coefs`` in place of theirs, of the same shapes) one after the other, a row
    per polynomial (:attr:`DualPolynomial.meta`, padded to the widest), the rows' width ``W`` and the
    largest size.  With ``packing`` (one search's :class:`Packing`), the packing of their own
    coefficients is kept there for the next calls with the same polynomials (a box's children, its
    probe and its bound often ask for the same list); ``meta`` is returned as a new array each time
    (the kernels overwrite its sizes with starts)."""
    if coefs is None and packing is not None:
        flat, meta, W, largest = packing.get(polys)
        return flat, meta.copy(), W, largest
    return _packed(polys, coefs)


class Packing:
    """One search's last packings of :func:`_pack` (of the polynomials' own coefficients), keyed by
    the polynomials' identities, each kept with the polynomials themselves (so that an identity is
    not reused while its entry lives); at most :attr:`SIZE`, the oldest dropped.  A pure function's
    memo: the packed arrays are those :func:`_packed` computes (read-only here; ``meta`` is copied
    by :func:`_pack`), so a search gives the same numbers with or without it."""

    SIZE = 32

    def __init__(self) -> None:
        self._kept: dict[tuple[int, ...], _Packed] = {}

    def get(self, polys: Sequence[DualPolynomial]) -> tuple[FloatArray, NDArray[np.int64], int, int]:
        """The packing of ``polys`` (:func:`_packed`), computed on the first call with them."""
        return self._entry(polys).packed

    def bound(self, polys: Sequence[DualPolynomial]
              ) -> tuple[FloatArray, NDArray[np.int64], int, int, int, FloatArray]:
        """The packing of ``polys`` (:meth:`get`) and what the bound kernels take besides, kept with
        it: the largest coefficient count per axis (``meta[:, 1].max()``) and the polynomials'
        round-off margins (:attr:`DualPolynomial.roundoff`; not to be written).

        Parameters
        ----------
        polys : sequence of DualPolynomial
            The polynomials (at least one).

        Returns
        -------
        tuple
            ``(flat, meta, W, largest, n, roundoff)``; ``meta`` is the kept array (copy it before a
            kernel overwrites it).
        """
        entry = self._entry(polys)
        flat, meta, W, largest = entry.packed
        if entry.roundoff is None:
            entry.n = int(meta[:, 1].max())
            entry.roundoff = np.array([dp.roundoff for dp in polys], dtype=float)
        return flat, meta, W, largest, entry.n, entry.roundoff

    def _entry(self, polys: Sequence[DualPolynomial]) -> _Packed:
        """The kept entry of ``polys``, its packing computed on the first call with them."""
        key = tuple(map(id, polys))
        kept = self._kept.get(key)
        if kept is not None:  # the same objects: the entry keeps them alive, so no other has their ids
            return kept
        if len(self._kept) >= self.SIZE:
            del self._kept[next(iter(self._kept))]
        entry = self._kept[key] = _Packed(tuple(polys), _packed(polys, None))
        return entry


class _Packed:
    """One entry of :class:`Packing`: the polynomials, their packing (:func:`_packed`) and, once
    :meth:`Packing.bound` asked, the largest coefficient count per axis and the round-off margins."""

    __slots__ = ("n", "packed", "polys", "roundoff")

    def __init__(self, polys: tuple[DualPolynomial, ...],
                 packed: tuple[FloatArray, NDArray[np.int64], int, int]) -> None:
        self.polys = polys
        self.packed = packed
        self.n = 0
        self.roundoff: FloatArray | None = None


def _packed(polys: Sequence[DualPolynomial], coefs: Sequence[FloatArray] | None
            ) -> tuple[FloatArray, NDArray[np.int64], int, int]:
    """:func:`_pack`, computed."""
    metas = [dp.meta for dp in polys]
    widths = {m.size for m in metas}
    if len(widths) == 1:
        meta = np.array(metas)  # np.stack's array, without its argument handling
        W = (meta.shape[1] - 3) // 2
    else:  # polynomials of problems with different numbers of vehicles: padded to the widest
        W = max((m.size - 3) // 2 for m in metas)
        meta = np.zeros((len(metas), 3 + 2 * W), dtype=np.int64)
        for p, m in enumerate(metas):
            w = (m.size - 3) // 2
            meta[p, :3 + w] = m[:3 + w]
            meta[p, 3 + W:3 + W + w] = m[3 + w:]
    flat = np.concatenate([np.asarray(c, dtype=float).ravel() for c in
                           ([dp.coef for dp in polys] if coefs is None else coefs)])
    return flat, meta, W, int(meta[:, 2].max())


def polys_values(polys: list[DualPolynomial], taus: FloatArray, coefs: list[FloatArray] | None = None,
                 packing: Packing | None = None) -> FloatArray:
    """At each row of ``taus`` (crossing times, shape ``(T, m)``; every polynomial vehicle's time in
    its piece), the largest value of the polynomials ``polys`` (``coefs``: their coefficients in
    place of ``coef``, of the same shapes, e.g. a derivative's):
    :func:`~iamp.planners.avoid.search_kernel.polys_max`, the one evaluation of these polynomials
    (``packing``: the search's :class:`Packing`)."""
    flat, meta, W, largest = _pack(polys, coefs, packing)
    out = np.empty(taus.shape[0])
    _run("polys_max", search_kernel)(flat, meta, W, float(polys[0].h), taus, out, np.empty(W), np.empty(largest))
    return out



#: :func:`grid_minimum`'s crossing times of solved candidates where it is given none (read-only)
_NO_POINTS: dict[int, FloatArray] = {}


def grid_minimum(polys: list[DualPolynomial], tau: FloatArray, vehicles: Sequence[int], lo: FloatArray,
                 hi: FloatArray, n: int, solved: FloatArray | None, tol: float,
                 packing: Packing | None = None) -> tuple[FloatArray, float]:
    """The point of a product grid where the largest value of ``polys`` is lowest, and that value
    (:func:`~iamp.planners.avoid.search_kernel.probe_grid`): ``tau`` with each vehicle of ``vehicles``
    at ``n`` samples of its interval ``[lo_v, hi_v]``; a point within ``tol`` of a row of ``solved``
    (crossing times of solved candidates, or None) is passed over unless every point is
    (:meth:`~iamp.planners.avoid.continuous.ContinuousAvoidPlanner._probe`).

    Parameters
    ----------
    polys : list of DualPolynomial
        At least one polynomial.
    tau : ndarray, shape (m,)
        The crossing times of the vehicles that do not move.
    vehicles : sequence of int
        The vehicles that move (the grid's axes, in this order).
    lo, hi : ndarray, shape (m,)
        The box.
    n : int
        Samples per moving vehicle (at least 2).
    solved : ndarray, shape (S, m), or None
        Crossing times whose points are passed over.
    tol : float
        How near a point must be to one of ``solved``, in every vehicle's time.
    packing : Packing, optional
        The search's :class:`Packing`.

    Returns
    -------
    tuple
        The point (a row of the grid, shape ``(m,)``) and its value.
    """
    flat, meta, W, largest = _pack(polys, None, packing)
    tau = np.asarray(tau, dtype=float)
    m = tau.shape[0]
    T = n ** len(vehicles)
    if solved is None:
        solved = _NO_POINTS.get(m)
        if solved is None:
            solved = _NO_POINTS[m] = np.empty((0, m))
            solved.flags.writeable = False
    pts, vals = np.empty((T, m)), np.empty(T)
    at = _run("probe_grid", search_kernel)(flat, meta, W, float(polys[0].h), tau, np.array(vehicles, dtype=np.int64),
                                           np.asarray(lo, dtype=float), np.asarray(hi, dtype=float), n, solved, tol,
                                           pts, vals, np.empty(T, dtype=np.bool_), np.empty(W), np.empty(largest))
    return pts[at], float(vals[at])

@lru_cache(maxsize=32)
def _kernel_tables(n: int) -> tuple[FloatArray, FloatArray]:
    """The bound kernels' tables for up to ``n`` coefficients per axis, from
    :mod:`~iamp.planners.avoid.bernstein`'s: ``binom[i, j] = binom(i, j)`` (zero for ``j > i``) and
    ``p2b[m, :m, :m]`` the power-to-Bernstein matrix of degree ``m - 1``
    (:func:`~iamp.planners.avoid.bernstein.power_to_bernstein`)."""
    binom = np.ascontiguousarray(_binomials(n - 1)[0].T)
    p2b = np.zeros((n + 1, n, n))
    for m in range(1, n + 1):
        p2b[m, :m, :m] = _power_to_bernstein(m - 1)
    binom.flags.writeable = False
    p2b.flags.writeable = False
    return binom, p2b


_SPACE: dict[tuple[int, int, int], tuple[FloatArray, ...]] = {}


def _space(largest: int, n: int, W: int, P: int) -> tuple[FloatArray, ...]:
    """Work space of the bound kernels (their contents are not read before written): per ``(largest,
    n, W)`` kept and grown for ``P`` polynomials; ``work``, ``spare``, ``pw_a``, ``R``, ``kept``,
    ``lam``, ``est``, ``chosen``."""
    key = (largest, n, W)
    out = _SPACE.get(key)
    if out is None or out[6].size < P:
        cap = max(P, 16, 2 * out[6].size if out is not None else 0)
        out = _SPACE[key] = (np.empty(largest), np.empty(largest), np.empty(n), np.empty((n, n)),
                             np.empty(W, dtype=np.int64), np.empty(W), np.empty(cap), np.zeros(cap, dtype=np.bool_))
    return out


def lower_bounds(polys: list[DualPolynomial], lo: FloatArray, hi: FloatArray) -> list[float]:
    """:meth:`DualPolynomial.lower_bound` of every polynomial of ``polys`` over the box ``[lo, hi]``:
    its smallest tensor Bernstein coefficient on the box less the round-off margin
    (:data:`ROUND_OFF_REL` and :attr:`DualPolynomial.roundoff`), all of them in one kernel call
    (:func:`~iamp.planners.avoid.search_kernel.poly_bounds`)."""
    if not polys:
        return []
    flat, meta, W, largest = _pack(polys)
    n = int(meta[:, 1].max())
    out = np.empty(len(polys))
    work, spare, pw_a, R, kept, _, _, _ = _space(largest, n, W, len(polys))
    _run("poly_bounds", search_kernel)(flat, meta, W, np.array([dp.roundoff for dp in polys], dtype=float),
                                       float(polys[0].h), ROUND_OFF_REL, np.asarray(lo, dtype=float),
                                       np.asarray(hi, dtype=float), *_kernel_tables(n), out, work, spare, pw_a, R, kept)
    return [float(v) for v in out]


#: Polynomials bounded first by :func:`max_lower_bound` (those with the highest values at the
#: box's centre), before the rest are screened against their bound.
MAX_BOUND_FIRST = 8


def max_lower_bound(polys: list[DualPolynomial], lo: FloatArray, hi: FloatArray,
                    packing: Packing | None = None) -> float:
    r"""The largest of :func:`lower_bounds` (``-inf`` without polynomials; a NaN bound proves nothing
    and counts as ``-inf``), bounding only the polynomials that can reach it
    (:func:`~iamp.planners.avoid.search_kernel.max_poly_bound`).

    A polynomial's bound on the box (its smallest Bernstein coefficient, less the round-off margin)
    is at most its value anywhere in the box, e.g. at the centre.  The
    :data:`MAX_BOUND_FIRST` polynomials with the highest centre values are bounded first; of
    the rest only those whose centre value, raised by a bound on its evaluation's round-off
    (:math:`10^{-12}\sum|c|`, the coefficients' magnitudes at :math:`|\lambda| \le 1`), exceeds the
    best bound so far are bounded too.  The result is the maximum over all of them, the same
    number: a polynomial left out cannot exceed it.  (A box of a long search is covered by
    hundreds of stored polynomials, whose bounds had made the search quadratic in its QPs.)
    ``packing``: the search's :class:`Packing`.
    """
    if not polys:
        return -np.inf
    if packing is not None:
        flat, kept_meta, W, largest, n, roundoff = packing.bound(polys)
        meta = kept_meta.copy()  # the kernel overwrites its sizes with starts (:func:`_pack`)
    else:
        flat, meta, W, largest = _packed(polys, None)
        n, roundoff = int(meta[:, 1].max()), np.array([dp.roundoff for dp in polys], dtype=float)
    work, spare, pw_a, R, kept, lam, est, chosen = _space(largest, n, W, len(polys))
    return float(_run("max_poly_bound", search_kernel)(
        flat, meta, W, roundoff, float(polys[0].h), ROUND_OFF_REL,
        np.asarray(lo, dtype=float), np.asarray(hi, dtype=float), *_kernel_tables(n), MAX_BOUND_FIRST, est, chosen, lam,
        work, spare, pw_a, R, kept))


class DualBounds:
    """The factored KKT matrix of one grid and :meth:`polynomial`, the bound of a solved candidate.

    Parameters
    ----------
    qp : ContinuousAvoidQP
        The grid's QP (its rows' fixed layout, :meth:`~iamp.planners.avoid.continuous.ContinuousAvoidQP.spec_rows`).
    """

    def __init__(self, qp: ContinuousAvoidQP) -> None:
        self.qp = qp
        d = qp.data
        # the node solver's symmetric P and factorisation of the same matrix when it has one
        self.P = qp.schur.P_full_csc if qp.schur is not None else full_hessian(d.P)
        #: the full Hessian's CSC arrays (:func:`~iamp.planners.avoid.dual_kernel.coefficients`)
        self._Pp = np.asarray(self.P.indptr, dtype=np.int64)
        self._Pi = np.asarray(self.P.indices, dtype=np.int64)
        self._Px = np.asarray(self.P.data, dtype=float)
        self.lu = qp.schur.lu if qp.schur is not None else spla.splu(kkt_matrix(d.P, qp.A_eq, self.P))
        self.nb = qp.degree + 1
        # σ-free values of the split piece's rows as polynomials in λ: M(0, λ) (first half-plane),
        # M(λ, 1) (second), and their bounds (:meth:`ContinuousAvoidQP.split_polynomials`)
        self.M_pre, self.M_post = qp.split_polynomials()
        D, m = qp.degree, len(qp.problem.vehicles)
        #: per polynomial vehicle ``v``: the basis columns of ``λ_v^0..λ_v^d`` (:meth:`polynomial`)
        self._basis_columns = [np.concatenate(([0], 1 + v * D + np.arange(D))) for v in range(m)]
        self._bindings: dict[int, tuple[Solved, _Binding]] = {}
        #: the four node columns of piece ``k`` of half-plane axis ``pl`` (:meth:`_split_blocks`)
        self._cols: dict[tuple[int, int], NDArray[np.int64]] = {}
        self._ix: dict[tuple[bytes, int], tuple[NDArray[np.int64], ...]] = {}
        #: b·ν0 and |b|·|ν0| of the equality optimum (:meth:`polynomial`)
        self._beq_nu = float(d.b_eq @ qp.schur._x0[d.n:]) if qp.schur is not None else 0.0
        self._beq_nu_abs = float(np.abs(d.b_eq) @ np.abs(qp.schur._x0[d.n:])) if qp.schur is not None else 0.0
        #: the coefficient positions of a polynomial without a polynomial vehicle (a constant)
        self._flat_const = np.zeros(2, dtype=np.int64)
        #: zero bounds of a half-plane with no binding row on the split piece (:meth:`_halves`)
        self._no_rhs = np.zeros((qp.degree + 1, qp.degree + 1))
        #: ``(n, n)``, rows of :math:`K^{-1}_{zz}` solved here when there is no node solver (:meth:`_kinv_rows`)
        self._own_kinv: FloatArray | None = None
        self._own_have: NDArray[np.bool_] | None = None

    @staticmethod
    def _exponents(q: int, D: int) -> tuple[tuple[NDArray[np.int64], ...], tuple[NDArray[np.int64], ...]]:
        """With ``q`` polynomial vehicles: the exponents of the basis ``1, λ_i^p`` (``p = 1..D``)
        and of the products of two basis monomials, as index tuples into the coefficient tensor
        (built once per ``(q, D)`` and process, :data:`_EXPONENTS`)."""
        out = _EXPONENTS.get((q, D))
        if out is None:
            C = 1 + q * D
            exps = np.zeros((C, q), dtype=np.int64)
            for v in range(q):
                exps[1 + v * D:1 + (v + 1) * D, v] = np.arange(1, D + 1)
            pairs = (exps[:, None, :] + exps[None, :, :]).reshape(C * C, q)
            out = _EXPONENTS[(q, D)] = (tuple(exps.T), tuple(pairs.T))
        return out

    @staticmethod
    def _flat(q: int, D: int, shape: tuple[int, ...], exps: tuple[NDArray[np.int64], ...],
              pairs: tuple[NDArray[np.int64], ...]) -> NDArray[np.int64]:
        """The flat positions in the coefficient tensor of ``exps``, then ``pairs`` (once per ``(q, D)``
        and process, :data:`_FLATS`; read-only)."""
        out = _FLATS.get((q, D))
        if out is None:
            out = np.concatenate((np.ravel_multi_index(exps, shape), np.ravel_multi_index(pairs, shape)))
            out.flags.writeable = False
            _FLATS[(q, D)] = out
        return out

    @staticmethod
    def _positions(q: int, D: int) -> NDArray[np.int64]:
        """:meth:`_flat` of ``q`` polynomial vehicles of degree ``D`` (coefficient tensor of shape
        ``(2D + 1,) * q``), looked up once per ``(q, D)`` and process."""
        out = _FLATS.get((q, D))
        if out is None:
            out = DualBounds._flat(q, D, (2 * D + 1,) * q, *DualBounds._exponents(q, D))
        return out

    def _rhs_poly(self, i: int, plane: int, k: int, pre: bool) -> FloatArray:
        """:meth:`ContinuousAvoidQP.rhs_polynomial`."""
        return self.qp.rhs_polynomial(i, plane, k, pre)

    def _binding(self, sol: Solved) -> _Binding:
        """The rows of ``sol`` with a positive multiplier, decoded from their layout numbers (once
        per solution: its piece polynomial, a box's polynomial and its gradient read the same)."""
        kept = self._bindings.get(id(sol))
        if kept is not None and kept[0] is sol:
            return kept[1]
        out = self._decode(sol)
        self._bindings[id(sol)] = (sol, out)
        return out

    def _decode(self, sol: Solved) -> _Binding:
        """The binding rows of ``sol`` (only rows with a positive multiplier enter ``g``), their
        layout numbers decoded and their multipliers summed per vehicle
        (:func:`~iamp.planners.avoid.dual_kernel.binding_rows`)."""
        qp = self.qp
        A_in, u_in, ids_all = sol.spec_rows()
        indptr, indices, data = qp.csr_arrays(A_in)
        nz, y, bern, veh, plane, piece, j, cols, mass = _run("binding_rows", dual_kernel)(
            np.asarray(sol.y[qp.data.n_eq:], dtype=float), np.asarray(ids_all, dtype=np.int64), int(qp.n_b),
            int(qp.N), int(self.nb), len(sol.spec), indptr, indices)
        mass.flags.writeable = False
        first = np.array([f for f, _, _, _ in sol.spec], dtype=np.int64)
        second = np.array([s for _, s, _, _ in sol.spec], dtype=np.int64)
        return _Binding(A_in, u_in, nz, y, bern, veh, plane, piece, j, indptr, indices, data, cols, mass, first,
                        second, tuple(x > 0 for x in mass.tolist()))

    def _split_blocks(self, sol: Solved, b: _Binding, i: int, k: int
                      ) -> list[tuple[FloatArray, FloatArray, FloatArray, float, NDArray[np.int64], FloatArray,
                                      FloatArray]]:
        """:meth:`_blocks` of ``(i, k)``, computed once per solution (kept on its binding ``b``)."""
        out = b.blocks.get((i, k))
        if out is None:
            out = b.blocks[(i, k)] = [(M, yj, rhs, sigma, cols, sigma * (yj @ M).T, rhs @ yj)
                                      for M, yj, rhs, sigma, cols in self._blocks(sol, b, i, k)]
        return out

    def _blocks(self, sol: Solved, b: _Binding, i: int, k: int
                ) -> Iterator[tuple[FloatArray, FloatArray, FloatArray, float, NDArray[np.int64]]]:
        """Vehicle ``i``'s two half-planes on piece ``k``, split at its crossing time (first on
        ``[0, λ]``, second on ``[λ, 1]``): per half-plane with a binding row there, ``(M, yj, rhs,
        σ, cols)`` — the σ-free row values as polynomials in ``λ``
        (:meth:`~iamp.planners.avoid.continuous.ContinuousAvoidQP.split_polynomials`), the
        multipliers per Bernstein index, the bounds as polynomials in ``λ``
        (:meth:`~iamp.planners.avoid.continuous.ContinuousAvoidQP.rhs_polynomial`), the sign and
        the piece's four node columns (the one loop of :meth:`gradient` and :meth:`polynomial`,
        through :meth:`_split_blocks`)."""
        d = self.qp.data
        f, s = sol.spec[i][0], sol.spec[i][1]
        for pl, M, pre in ((f, self.M_pre, True), (s, self.M_post, False)):
            rows = b.split_rows(i, pl, k)
            if not rows.size:
                continue
            yj = np.zeros(self.nb)
            yj[b.j[rows]] = b.y[rows]
            yield M, yj, self._rhs_poly(i, pl, k, pre), d.planes[i][pl].sigma, self._node_cols(pl, k)

    def _node_cols(self, pl: int, k: int) -> NDArray[np.int64]:
        """The four node columns ``s, v`` at ``t_k`` and ``t_{k+1}`` of half-plane axis ``pl`` (kept)."""
        cols = self._cols.get((pl, k))
        if cols is None:
            d = self.qp.data
            cols = self._cols[(pl, k)] = np.array([d.idx_s(pl, k), d.idx_v(pl, k), d.idx_s(pl, k + 1),
                                                   d.idx_v(pl, k + 1)])
        return cols

    def gradient(self, sol: Solved) -> FloatArray:
        r"""``∂J/∂τ`` at the candidate ``sol`` (its ``spec`` has ``a = b = τ_c``), by the envelope
        theorem: only the rows of the piece split at :math:`\tau_i` depend on :math:`\tau_i`, so
        :math:`\partial J/\partial\tau_i = \sum_r y_r\, \partial_{\tau_i}(a_r(\tau) z - u_r(\tau))`
        with the candidate's ``z`` and multipliers ``y`` — the slope of its piece polynomial at
        :math:`\tau_c` (:meth:`DualPolynomial.slope`) without building it.

        Returns
        -------
        ndarray, shape (m,)
        """
        qp = self.qp
        N, h = qp.N, qp.h
        b = self._binding(sol)
        out = np.zeros(len(sol.spec))
        for i, (_, _, a, _) in enumerate(sol.spec):
            k = piece_of(float(a), float(a), h, N)
            assert k is not None
            first, second = self._halves(sol, b, i, k)
            out[i] = _run("slope", dual_kernel)(b.y, b.j, sol.z, (float(a) - k * h) / h, *first, *second) / h
        return out

    def _kinv(self, cols: NDArray[np.int64]) -> FloatArray:
        """Rows ``cols`` of the primal block of ``K⁻¹`` (shape ``(len(cols), n)``; ``K`` symmetric:
        the primal parts of its columns ``cols``), from the node solver's columns when it has them."""
        qp = self.qp
        if qp.schur is not None:
            qp.schur._columns(cols)
            return np.asarray(qp.schur._Kinv[cols], dtype=float)
        n, n_eq = qp.data.n, qp.data.n_eq
        E = np.zeros((n + n_eq, cols.size))
        E[cols, np.arange(cols.size)] = 1.0
        return np.asarray(self.lu.solve(E), dtype=float)[:n].T

    def tangent(self, sol: Solved, i: int, k: int) -> FloatArray:
        r"""``∂y/∂λ_i`` of the candidate's multipliers on its binding rows (the order of
        ``_binding(sol).nz``) as vehicle ``i``'s crossing time moves in its piece ``k``
        (:math:`\tau_i = t_k + \lambda_i h`), the binding set held: with :math:`S` the rows of a
        positive multiplier, :math:`K` the equality-constrained KKT matrix and :math:`W = K^{-1}_{zz}
        G_S^\top`, differentiating :math:`Pz + E^\top\nu + G_S^\top y_S = 0`, :math:`Ez = e`,
        :math:`G_S(\lambda) z = h_S(\lambda)` gives

        .. math::  (G_S W)\,\dot y_S = G_S K^{-1}_{zz}(-\dot G_S^\top y_S) - (\dot h_S - \dot G_S z),

        where only the rows of the piece split at :math:`\tau_i` move (:math:`\dot G_S`,
        :math:`\dot h_S`: their derivatives in :math:`\lambda`, from
        :meth:`~iamp.planners.avoid.continuous.ContinuousAvoidQP.split_polynomials`).  Zero where no
        split row binds, or where :math:`G_S W` is singular to working precision (rows binding
        dependently).  Any value keeps the bound of :meth:`polynomial` valid (weak duality holds
        for every nonnegative ``y``); this one makes it exact to second order in
        :math:`\lambda - \lambda_c`, so that it falls off as :math:`(\lambda - \lambda_c)^4`
        (``tests/test_avoid_dual.py``).

        Returns
        -------
        ndarray, shape (number of binding rows,)
        """
        b = self._binding(sol)
        kept = b.tangents.get((i, k))
        if kept is None:
            kept = b.tangents[(i, k)] = self._tangent(sol, b, i, k)
            kept.flags.writeable = False
        return kept

    def _tangent(self, sol: Solved, b: _Binding, i: int, k: int) -> FloatArray:
        """:meth:`tangent` (:func:`~iamp.planners.avoid.dual_kernel.tangent`)."""
        out = np.zeros(b.nz.size)
        halves = self._halves(sol, b, i, k)
        if not halves[0][0].size + halves[1][0].size:
            return out
        h = self.qp.h
        lam0 = (float(sol.spec[i][2]) - k * h) / h
        Kinv = self._kinv_rows(self._entries(b, i, k), b, (i, k))
        _run("tangent", dual_kernel)(b.indptr, b.indices, b.data, b.nz, b.y, b.j, sol.z, Kinv, lam0, *halves[0],
                                     *halves[1], out)
        return out

    def _halves(self, sol: Solved, b: _Binding, i: int, k: int
                ) -> tuple[tuple[NDArray[np.int64], FloatArray, FloatArray, float, NDArray[np.int64]], ...]:
        """Vehicle ``i``'s two half-planes on its split piece ``k`` (first on ``[0, λ]``, second on
        ``[λ, 1]``) as :mod:`~iamp.planners.avoid.dual_kernel` takes them: per half-plane its binding
        rows among ``b``'s, the σ-free row values and the bounds as polynomials in ``λ``
        (:meth:`~iamp.planners.avoid.continuous.ContinuousAvoidQP.split_polynomials`,
        :meth:`~iamp.planners.avoid.continuous.ContinuousAvoidQP.rhs_polynomial`; zeros where no
        row binds), its sign and the piece's four node columns."""
        kept = b.halves.get((i, k))
        if kept is not None:
            return kept
        d = self.qp.data
        f, s = sol.spec[i][0], sol.spec[i][1]
        out = []
        for pl, M, pre in ((f, self.M_pre, True), (s, self.M_post, False)):
            rows = b.split_rows(i, pl, k)
            rhs = self._rhs_poly(i, pl, k, pre) if rows.size else self._no_rhs
            out.append((rows, M, rhs, float(d.planes[i][pl].sigma), self._node_cols(pl, k)))
        kept = b.halves[(i, k)] = tuple(out)
        return kept

    def _entries(self, b: _Binding, i: int, k: int) -> NDArray[np.int64]:
        """The columns of :math:`K^{-1}_{zz}` that vehicle ``i``'s tangent and polynomial on its split
        piece ``k`` read: the binding rows' entries, then the piece's node columns of its two
        half-planes (:meth:`_halves` must have been computed; once per solution and ``(i, k)``)."""
        out = b.entries.get((i, k))
        if out is None:
            first, second = b.halves[(i, k)]
            out = b.entries[(i, k)] = np.concatenate((b.cols, first[4], second[4]))
        return out

    def _kinv_rows(self, cols: NDArray[np.int64], b: _Binding | None = None,
                   key: tuple[int, int] | None = None) -> FloatArray:
        """An ``(n, n)`` array whose rows ``cols`` are those of :math:`K^{-1}_{zz}` (``K`` symmetric:
        its columns): the node solver's own array once it solved them, else one kept here.  With
        ``b`` and ``key`` (``cols`` is ``b``'s :meth:`_entries` of ``key``) the node solver is
        asked once per solution (its columns, once solved, stay)."""
        qp = self.qp
        if qp.schur is not None:
            if b is None or key is None or key not in b.solved:
                qp.schur._columns(cols)
                if b is not None and key is not None:
                    b.solved.add(key)
            return np.asarray(qp.schur._Kinv)
        if self._own_kinv is None:
            n = qp.data.n
            self._own_kinv, self._own_have = np.zeros((n, n)), np.zeros(n, dtype=bool)
        assert self._own_have is not None
        missing = np.unique(cols[~self._own_have[cols]])
        if missing.size:
            self._own_kinv[missing] = self._kinv(missing)
            self._own_have[missing] = True
        return self._own_kinv

    def tangent_interval(self, sol: Solved, i: int, k: int) -> tuple[float, float]:
        r"""The interval of :math:`\lambda_i` in piece ``k`` (within ``[0, 1]``) where every multiplier on
        its tangent, :math:`y_c + (\lambda - \lambda_c)\dot y`, stays nonnegative: there the
        polynomial of :meth:`polynomial` keeps every slope and is exact to second order at the
        candidate (outside it, a slope is cut)."""
        b = self._binding(sol)
        mu = self.tangent(sol, i, k)
        lam0 = min(max((float(sol.spec[i][2]) - k * self.qp.h) / self.qp.h, 0.0), 1.0)
        lo, hi = 0.0, 1.0
        # the smallest y / |μ| of the falling and of the rising multipliers (numpy.min's)
        down, has_down, up, has_up = _run("ratio_limits", dual_kernel)(b.y, mu)
        if has_down:
            hi = min(hi, lam0 + float(down))
        if has_up:
            lo = max(lo, lam0 - float(up))
        return min(lo, lam0), max(hi, lam0)

    def polynomial(self, sol: Solved, lo: FloatArray, hi: FloatArray) -> DualPolynomial:
        """The dual bound ``g(y; τ)`` over the box ``[lo, hi]`` of the solved candidate ``sol``
        (its crossing times in the box), as a polynomial (module docstring).

        Parameters
        ----------
        sol : Solved
            An optimal candidate ``J(τ_c)`` (its ``spec`` has ``a = b = τ_c``).
        lo, hi : ndarray, shape (m,)
            The box.

        Returns
        -------
        DualPolynomial
        """
        qp, d = self.qp, self.qp.data
        N, h, D = qp.N, qp.h, qp.degree
        b = self._binding(sol)
        u_in, nz, y = b.u_in, b.nz, b.y
        poly_vehicles: list[int] = []
        pieces: list[int] = []
        m = len(sol.spec)
        split = np.empty(m, dtype=np.int64)
        for i in range(m):
            k = piece_of(float(lo[i]), float(hi[i]), h, N)
            split[i] = -1 if k is None else k
            if k is not None:
                poly_vehicles.append(i)
                pieces.append(k)
        first_pl, second_pl = b.first, b.second
        # the limit rows, and the Bernstein rows that every crossing in the box imposes (module docstring)
        keep = np.empty(nz.size, dtype=np.bool_)
        _run("kept_rows", dual_kernel)(b.bern, b.veh, b.plane, b.piece, first_pl, second_pl, split,
                                       np.asarray(lo, dtype=float), np.asarray(hi, dtype=float), h, 1e-9 * h, keep)
        q = len(poly_vehicles)
        if q == 1:
            # the multipliers on their tangent (module docstring): basis 1, λ, .., λ^(d+2)
            i, k = poly_vehicles[0], pieces[0]
            Dp = D + 1
            C = Dp + 1
            R = np.zeros((d.n + d.n_eq, C))
            hc = np.zeros(C)
            lam0 = (float(sol.spec[i][2]) - k * h) / h
            la = min(max((float(lo[i]) - k * h) / h, 0.0), 1.0)
            lb = min(max((float(hi[i]) - k * h) / h, la), 1.0)
            first, second = self._halves(sol, b, i, k)
            _run("tangent_terms", dual_kernel)(b.indptr, b.indices, b.data, nz, y, b.j, u_in, keep,
                                               self.tangent(sol, i, k), lam0, la, lb, *first, *second, R[:d.n], hc)
            R[d.n:, 0] = d.b_eq
            # R's rows with an entry: among the kept rows' columns and the piece's node columns
            entries: NDArray[np.int64] | None = self._entries(b, i, k)
            entry_key: tuple[int, int] | None = (i, k)
        else:
            Dp = D
            C = 1 + q * D  # basis: 1, then λ_i^p (p = 1..D) per polynomial vehicle
            entries = entry_key = None
            R = np.zeros((d.n + d.n_eq, C))
            # -A_keepᵀ y_keep from the CSR arrays of the kept rows (the node solver's kernel: from 0.0,
            # the rows in order, each row's entries in stored order)
            rows_k, y_k = nz[keep], y[keep]
            Aty = np.empty(d.n)
            _run("row_transpose_dot")(b.indptr, b.indices, b.data, rows_k, y_k, rows_k.size, Aty)
            R[:d.n, 0] = -Aty
            R[d.n:, 0] = d.b_eq
            hc = np.zeros(C)
            hc[0] = float(y_k @ u_in[rows_k])
            for v, (i, k) in enumerate(zip(poly_vehicles, pieces)):
                cs = self._basis_columns[v]  # the basis columns of λ_i^0..λ_i^D
                for _, _, _, _, cols, yM, ry in self._split_blocks(sol, b, i, k):
                    ix = self._ix.get((cols.tobytes(), v))
                    if ix is None:
                        ix = self._ix[(cols.tobytes(), v)] = np.ix_(cols, cs)
                    R[ix] -= yM  # σ (y_j M)ᵀ
                    hc[cs] += ry  # rhs · y_j
        schur = qp.schur
        lin = np.empty(C)
        if schur is None:
            X = self.lu.solve(R)
            Z, nu = np.ascontiguousarray(X[:d.n], dtype=float), X[d.n:]
            lin[:] = nu.T @ d.b_eq + hc
            lin_abs = float(np.sum(np.abs(nu).T @ np.abs(d.b_eq)))
        else:
            # K⁻¹R from the node solver's columns of K⁻¹ (K symmetric): R's primal rows are zero
            # but on the kept rows' columns and the split pieces' node columns, its dual rows are
            # b (column 0), and K⁻¹[0; b] = (z0, ν0) is the equality optimum; νᵀb by symmetry:
            # (K⁻¹r)_ν · b = r · K⁻¹[0; b] = r_z · z0 + r_ν · ν0
            Rp = R[:d.n]
            if entries is None:
                schur._columns(np.flatnonzero(np.abs(Rp) @ np.ones(C)))
            else:
                self._kinv_rows(entries, b, entry_key)
            Z = np.empty((d.n, C))
            lin_abs = _run("primal", dual_kernel)(Rp, schur._Kinv, schur.z0, hc, self._beq_nu, self._beq_nu_abs, Z,
                                                  lin)
        # g = -½ zᵀPz - νᵀe - yᵀh with z, ν, h polynomial in λ: each product of two basis monomials
        # adds to the coefficient of their product; with the size of the terms that cancel in g
        # (its round-off scales with them, not with g: a nearly infeasible candidate's
        # multipliers of 5e7 give coefficients of 1e15 for a g of 2)
        shape = (2 * Dp + 1,) * q
        flat = self._positions(q, Dp) if q else self._flat_const
        out = np.zeros(math.prod(shape))
        terms = _run("coefficients", dual_kernel)(Z, lin, lin_abs, hc, self._Pp, self._Pi, self._Px, flat, out)
        coef = out.reshape(shape) if q else np.array(out[0])
        return DualPolynomial(tuple(poly_vehicles), tuple(pieces), coef, h, self.mass(sol), q == 1,
                              ROUND_OFF_TERMS * terms)

    def mass(self, sol: Solved) -> FloatArray:
        """Per vehicle, the sum of ``sol``'s multipliers on its Bernstein rows (:attr:`DualPolynomial.mass`
        of every polynomial of ``sol``, without building one)."""
        return self._binding(sol).mass

    def binds(self, sol: Solved) -> tuple[bool, ...]:
        """Per vehicle, whether ``sol``'s multipliers on its Bernstein rows sum to a positive number
        (:meth:`mass` ``> 0``, as Python booleans; once per solution)."""
        return self._binding(sol).binds


class DualStore:
    r"""Every solved candidate's *piece polynomial*, each with the region of crossing times where
    it bounds :math:`J` (shared by every box of one search).

    The piece polynomial of a candidate at :math:`\tau_c` is :meth:`DualBounds.polynomial` over
    the grid pieces containing :math:`\tau_c` (every vehicle polynomial): it bounds
    :math:`J(\tau)` for every :math:`\tau` with each binding vehicle ``i`` (a positive multiplier
    on its rows) in its piece and in the candidate's order, whatever the box that asked for it.
    A vehicle with no multiplier on its rows drops out of the dual function, so the bound holds
    for every crossing time and order of that vehicle.  A box takes the largest bound of the
    polynomials whose region contains it (:meth:`valid`), not only its ancestors'.  A candidate
    enters the store with its region (:meth:`add`: its multipliers' sums per vehicle say which
    vehicles bind); its polynomial is built the first time a box or the search asks for it (the
    same function of the same solution: the same coefficients whenever it is built).

    Parameters
    ----------
    dual : DualBounds
        The grid's factored KKT matrix.
    """

    def __init__(self, dual: DualBounds) -> None:
        self.dual = dual
        qp = dual.qp
        self.h, self.N, self.tf = qp.h, qp.N, qp.tf
        #: per stored spec, its position in the rows below
        self._by_spec: dict[object, int] = {}
        self._orders: list[tuple[tuple[int, int], ...]] = []
        #: the stored regions as :func:`~iamp.planners.avoid.search_kernel.valid_polys` takes them,
        #: one row per stored polynomial (the first :meth:`__len__` rows; grown by doubling): their
        #: bounds, per vehicle whether it binds, and the orders
        self._LO: FloatArray = np.empty((0, 0))
        self._HI: FloatArray = np.empty((0, 0))
        self._B: NDArray[np.bool_] = np.empty((0, 0), dtype=np.bool_)
        self._O: NDArray[np.int64] = np.empty((0, 0, 2), dtype=np.int64)
        #: :func:`~iamp.planners.avoid.search_kernel.valid_polys`'s output (as long as the rows)
        self._out: NDArray[np.int64] = np.empty(0, dtype=np.int64)
        #: the piece polynomials, None until first asked for (:meth:`_poly`)
        self._polys: list[DualPolynomial | None] = []
        #: what builds each one: the candidate and its pieces' bounds
        self._sources: list[tuple[Solved, FloatArray, FloatArray]] = []
        self._order_arrays: dict[tuple[tuple[int, int], ...], NDArray[np.int64]] = {}
        #: per stored candidate (its position), the position of its tangent polynomial on the
        #: interval where no slope is cut (one vehicle, :meth:`add`)
        self._near: dict[int, int] = {}
        #: the search's packings of polynomial lists for the bound and probe kernels (:class:`Packing`)
        self.packing = Packing()

    def __len__(self) -> int:
        """The number of stored polynomials (built or not): it grows with every :meth:`add` of a
        new candidate, and :meth:`valid` depends on nothing else."""
        return len(self._polys)

    def _row(self, orders: tuple[tuple[int, int], ...], binds: Sequence[bool], lo: Sequence[float],
             hi: Sequence[float], source: tuple[Solved, FloatArray, FloatArray]) -> None:
        """Store one region (its row of the arrays) and what builds its polynomial."""
        at = len(self._polys)
        if at == self._LO.shape[0]:
            m = len(orders)
            cap = max(8, 2 * at)
            LO, HI = np.empty((cap, m)), np.empty((cap, m))
            B, O = np.zeros((cap, m), dtype=np.bool_), np.zeros((cap, m, 2), dtype=np.int64)
            if at:
                LO[:at], HI[:at], B[:at], O[:at] = self._LO, self._HI, self._B, self._O
            self._LO, self._HI, self._B, self._O = LO, HI, B, O
            self._out = np.empty(cap, dtype=np.int64)
        self._LO[at] = lo
        self._HI[at] = hi
        self._B[at] = binds
        self._O[at] = orders
        self._orders.append(orders)
        self._polys.append(None)
        self._sources.append(source)

    def add(self, sol: Solved) -> int:
        """Store the optimal candidate ``sol`` (its ``spec`` has ``a = b = τ_c``; once per spec)
        with the region where its piece polynomial bounds ``J``; returns its position.  The
        polynomial itself is built when first asked for (:meth:`piece`, :meth:`valid`)."""
        at = self._by_spec.get(sol.spec)
        if at is not None:
            return at
        h, N = self.h, self.N
        # per vehicle its piece k and that piece's ends k h, (k + 1) h (as floats)
        ks = [piece_of(float(a), float(a), h, N) for _, _, a, _ in sol.spec]
        lo = [float(k) * h for k in ks]  # type: ignore[arg-type]
        hi = [(float(k) + 1.0) * h for k in ks]  # type: ignore[arg-type]
        binds = self.dual.binds(sol)
        at = self._by_spec[sol.spec] = len(self._polys)
        orders = tuple((int(f), int(s)) for f, s, _, _ in sol.spec)
        slack = 1e-12 * self.tf
        self._row(orders, binds, [a - slack if b else -np.inf for a, b in zip(lo, binds)],
                  [a + slack if b else np.inf for a, b in zip(hi, binds)], (sol, np.array(lo), np.array(hi)))
        if len(ks) == 1 and binds[0]:
            # one vehicle: the polynomial with every multiplier on its tangent, on the interval
            # where none is cut (exact to second order at the candidate), beside the piece's
            # (some slopes cut to keep the multipliers nonnegative over the whole piece)
            la, lb = self.dual.tangent_interval(sol, 0, int(ks[0]))  # type: ignore[arg-type]
            if lb > la and (la > 0.0 or lb < 1.0):
                near_lo, near_hi = lo[0] + la * h, lo[0] + lb * h
                self._near[at] = len(self._polys)
                self._row(orders, binds, [near_lo - slack], [near_hi + slack],
                          (sol, np.array([near_lo]), np.array([near_hi])))
        return at

    def _poly(self, at: int) -> DualPolynomial:
        """The piece polynomial stored at ``at``, built on first use."""
        dp = self._polys[at]
        if dp is None:
            sol, lo, hi = self._sources[at]
            dp = self._polys[at] = self.dual.polynomial(sol, lo, hi)
        return dp

    def piece(self, sol: Solved) -> DualPolynomial:
        """The piece polynomial of the optimal candidate ``sol`` (computed once per spec; its
        ``spec`` has ``a = b = τ_c``), added to the store (:meth:`add`)."""
        return self._poly(self.add(sol))

    def near(self, sol: Solved) -> DualPolynomial:
        """The polynomial of ``sol`` exact to second order at its crossing time (every multiplier
        on its tangent, :meth:`DualBounds.tangent`) where the store has one, else its piece
        polynomial; ``sol`` is added to the store (:meth:`add`)."""
        at = self.add(sol)
        return self._poly(self._near.get(at, at))

    def valid(self, orders: tuple[tuple[int, int], ...], lo: FloatArray, hi: FloatArray) -> list[DualPolynomial]:
        """The stored polynomials that bound every crossing in the box ``[lo, hi]`` with
        ``orders`` (each binding vehicle in its polynomial's piece and order)."""
        P = len(self._polys)
        if not P:
            return []
        want = self._order_arrays.get(orders)
        if want is None:
            want = self._order_arrays[orders] = np.asarray(orders, dtype=np.int64).reshape(-1, 2)
        out = self._out
        n = _run("valid_polys", search_kernel)(self._LO[:P], self._HI[:P], self._B[:P], self._O[:P], want,
                                               np.asarray(lo, dtype=float), np.asarray(hi, dtype=float), out)
        polys, build = self._polys, self._poly
        return [polys[c] or build(c) for c in out[:n].tolist()]
