r"""One interface for every QP backend: the general OSQP form with value updates.

Every backend solves

.. math::

    \min_z\ \tfrac12 z^\top P z + q^\top z \quad\text{s.t.}\quad l \le A z \le u ,

(an equality row has :math:`l_i = u_i`; an absent bound is :math:`\pm\infty`) with the
Lagrangian :math:`L = \tfrac12 z^\top P z + q^\top z + y^\top A z` plus the support terms of
the box, so its KKT conditions are

.. math::

    Pz + q + A^\top y = 0, \qquad l \le Az \le u, \qquad
    y_i > 0 \Rightarrow (Az)_i = u_i, \quad y_i < 0 \Rightarrow (Az)_i = l_i .

``P`` is given as its **upper triangle** (CSC), ``A`` as CSC.  Their sparsity patterns are
fixed at construction; afterwards only values change (:meth:`QPBackend.update`), which is
what lets a backend keep its symbolic factorisation (and, for the direct backend, the
numeric one) across the candidates of a sweep.

Residuals are recomputed from the data (:func:`kkt_residuals`; qpbenchmark's definitions),
never taken from a solver's word:

.. math::

    r_p = \|Az - \Pi_{[l,u]}(Az)\|_\infty, \qquad
    r_d = \|Pz + q + A^\top y\|_\infty, \qquad
    r_g = \big|z^\top P z + q^\top z + \textstyle\sum_i (u_i y_i^+ - l_i y_i^-)\big| ,

(:math:`y^\pm = \max(\pm y, 0)`; for an equality row the last sum is :math:`b^\top y`).  The
relative versions divide by the largest magnitude among each expression's terms (at least
1), like OSQP's relative criteria.
"""

from __future__ import annotations

import abc
import functools
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from importlib import metadata
from typing import Any, ClassVar

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

try:  # scipy's compiled sparse routines (private; another scipy may move them: then its public API)
    from scipy.sparse import _sparsetools
except ImportError:  # pragma: no cover - every scipy iamp supports has it
    _sparsetools = None

from iamp.core.errors import IampError, MissingDependencyError

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


class UnsupportedProblemError(IampError, ValueError):
    """A backend was given a problem it does not solve (e.g. inequalities to ``kkt``)."""


@dataclass(frozen=True)
class KKTResiduals:
    """Absolute and relative KKT residuals (see the module docstring for the formulas)."""

    primal: float
    dual: float
    gap: float
    primal_rel: float
    dual_rel: float
    gap_rel: float

    def as_dict(self) -> dict[str, float]:
        return {k: float(v) for k, v in asdict(self).items()}

    def worst_rel(self) -> tuple[str, float]:
        """The largest relative residual and its name (``"kkt_primal_rel"``, …)."""
        items = (("kkt_primal_rel", self.primal_rel), ("kkt_dual_rel", self.dual_rel),
                 ("kkt_gap_rel", self.gap_rel))
        name, value = max(items, key=lambda kv: kv[1] if np.isfinite(kv[1]) else np.inf)
        return name, float(value)


def kkt_residuals(P: sp.spmatrix, q: FloatArray, A: sp.spmatrix, l: FloatArray, u: FloatArray,
                  z: FloatArray, y: FloatArray, *, symmetric: bool = False,
                  lower: sp.spmatrix | None = None) -> KKTResiduals:
    """KKT residuals of ``(z, y)`` for ``min ½zᵀPz + qᵀz`` s.t. ``l ≤ Az ≤ u``.

    ``P`` holds the upper triangle only (the symmetric matrix ``P + triu(P, 1)ᵀ`` is used)
    unless ``symmetric=True`` says it is already the whole matrix; ``lower``, when the caller
    keeps it, is ``triu(P, 1)ᵀ`` of this ``P`` (the same numbers, not built again).  A multiplier
    pushing against an infinite bound makes the gap infinite.
    """
    z, y = np.asarray(z, dtype=float), np.asarray(y, dtype=float)
    if symmetric:
        Pz = P @ z
    else:
        Pu = sp.csc_matrix(P)
        Pz = Pu @ z + (sp.triu(Pu, 1).T if lower is None else lower) @ z
    Az, Aty = A @ z, A.T @ y
    rp = float(np.max(np.abs(Az - np.clip(Az, l, u)), initial=0.0))
    rd = float(np.max(np.abs(Pz + q + Aty), initial=0.0))
    yp, ym = np.maximum(y, 0.0), np.maximum(-y, 0.0)
    with np.errstate(invalid="ignore"):
        up = np.where(yp > 0, u * yp, 0.0)
        lo = np.where(ym > 0, l * ym, 0.0)
    support = float(np.sum(up) - np.sum(lo))
    zPz, qz = float(z @ Pz), float(q @ z)
    rg = abs(zPz + qz + support) if np.isfinite(support) else np.inf
    bound = np.where(np.isfinite(u), np.abs(u), 0.0) + 0.0
    bound = np.maximum(bound, np.where(np.isfinite(l), np.abs(l), 0.0))
    sp_ = max(1.0, float(np.max(np.abs(Az), initial=0.0)), float(np.max(bound, initial=0.0)))
    sd = max(1.0, float(np.max(np.abs(Pz), initial=0.0)), float(np.max(np.abs(q), initial=0.0)),
             float(np.max(np.abs(Aty), initial=0.0)))
    sg = max(1.0, abs(zPz), abs(qz), abs(support) if np.isfinite(support) else 1.0)
    return KKTResiduals(rp, rd, rg, rp / sp_, rd / sd, rg / sg)


def farkas_residuals(A: sp.spmatrix, l: FloatArray, u: FloatArray, dy: FloatArray) -> tuple[float, float]:
    r"""How well ``δy`` certifies that ``l <= Az <= u`` has no solution (Farkas' lemma).

    ``δy`` is a certificate when :math:`A^\top \delta y = 0` and its support is negative,
    :math:`\sum_i u_i \delta y_i^+ - l_i \delta y_i^- < 0` (then
    :math:`0 = z^\top A^\top \delta y \le` the support for any feasible ``z``: a contradiction).
    Returns ``(stationarity, support)`` after scaling ``δy`` to unit max-norm:
    :math:`\|A^\top\delta y\|_\infty / \|A\|_{\max}` and the support divided by
    :math:`\max(1, \|l, u\|_\infty)`.  A certificate is accepted when the first is tiny and the
    second clearly negative (the caller's tolerances); a pushing multiplier against an
    infinite bound gives ``+inf``.
    """
    dy = np.asarray(dy, dtype=float)
    norm = float(np.max(np.abs(dy), initial=0.0))
    if not np.isfinite(norm) or norm == 0.0:
        return float("inf"), float("inf")
    dy = dy / norm
    Amax = max(1e-300, float(abs(sp.csc_matrix(A)).max()))
    stat = float(np.max(np.abs(A.T @ dy), initial=0.0)) / Amax
    yp, ym = np.maximum(dy, 0.0), np.maximum(-dy, 0.0)
    if np.any((yp > 0) & ~np.isfinite(u)) or np.any((ym > 0) & ~np.isfinite(l)):
        return stat, float("inf")
    finite = np.concatenate((np.abs(l[np.isfinite(l)]), np.abs(u[np.isfinite(u)])))
    scale = max(1.0, float(np.max(finite, initial=0.0)))
    pos, neg = yp > 0, ym > 0  # only rows that push (their bounds are finite, checked above)
    support = float(np.sum(u[pos] * yp[pos]) - np.sum(l[neg] * ym[neg]))
    return stat, support / scale


@dataclass(frozen=True)
class QPSolution:
    """What one :meth:`QPBackend.solve` returns.

    Attributes
    ----------
    z, y : ndarray
        Primal vector and multipliers of the rows of ``A`` (the sign convention of the
        module docstring; for an equality row ``a_iᵀz = b_i``, ``y_i`` is the multiplier of
        ``a_iᵀz − b_i`` in ``L = ½zᵀPz + qᵀz + yᵀ(Az − b)``).
    status : str
        In the :mod:`iamp.core.status` vocabulary, as mapped from the solver's own status
        (not yet verified: see :meth:`kkt_residuals`).
    raw_status : str
        The solver's own status word.
    iterations : int
    solver_time_s : float or None
        The solver's own reported time.
    solve_call_s : float
        Wall time of the ``solve`` call, measured here.
    polished : bool or None
        OSQP only: whether solution polishing succeeded.
    certificate : ndarray or None
        With status INFEASIBLE, the solver's primal infeasibility certificate ``δy`` in the
        convention of ``y`` (osqp, clarabel; not yet verified: :func:`farkas_residuals`).
    """

    z: FloatArray
    y: FloatArray
    status: str
    raw_status: str
    iterations: int
    solver_time_s: float | None
    solve_call_s: float
    polished: bool | None = None
    certificate: FloatArray | None = None

    def kkt_residuals(self, P: sp.spmatrix, q: FloatArray, A: sp.spmatrix, l: FloatArray,
                      u: FloatArray) -> KKTResiduals:
        """Recompute the KKT residuals of ``(z, y)`` from the data (:func:`kkt_residuals`)."""
        return kkt_residuals(P, q, A, l, u, self.z, self.y)

    @property
    def finite(self) -> bool:
        return bool(np.isfinite(self.z).all() and np.isfinite(self.y).all())


def csc_copy(M: sp.spmatrix) -> sp.csc_matrix:
    """``M`` as a CSC float matrix of its own, indices sorted: ``sp.csc_matrix(M, dtype=float,
    copy=True)`` then ``sort_indices()``.  A ``csc_matrix`` of floats (what the planners pass) has its
    three arrays copied directly, without scipy's conversion and format checks of a matrix that
    is already one (about 3 µs instead of 13 µs): the same arrays either way.  Its flags are found
    again, as for a new matrix, but for sorted indices that ``M`` already knows of (scipy's own
    ``sort_indices`` or ``tocsc`` set it, or :func:`csr_to_csc`'s callers): the copy's are the
    same indices, so ``sort_indices`` below would find them sorted and change nothing."""
    if type(M) is sp.csc_matrix and M.dtype == np.float64:
        out = _clone(M)
        out.data, out.indices, out.indptr = M.data.copy(), M.indices.copy(), M.indptr.copy()
        for flag in ("_has_sorted_indices", "_has_canonical_format"):  # found again, as for a new matrix
            out.__dict__.pop(flag, None)
        if M.__dict__.get("_has_sorted_indices") is True:  # known sorted: the same indices
            out._has_sorted_indices = True
    else:
        out = sp.csc_matrix(M, dtype=float, copy=True)
    out.sort_indices()
    return out


def _clone(M: Any) -> Any:
    """``copy.copy(M)`` of a scipy sparse matrix (a new object of its class sharing its attributes,
    as ``copy.copy`` builds it from ``__reduce_ex__``: ``object.__new__``, scipy's classes defining
    none of their own, and its ``__dict__``), without ``copy``'s dispatch (about 1 µs instead of 5 µs)."""
    out = object.__new__(type(M))
    out.__dict__.update(M.__dict__)
    return out


def compressed(kind: type[sp.csr_matrix] | type[sp.csc_matrix], data: FloatArray, indices: NDArray[np.int32],
               indptr: NDArray[np.int32], shape: tuple[int, int]) -> sp.csr_matrix | sp.csc_matrix:
    """``kind((data, indices, indptr), shape=shape)`` (``kind`` ``sp.csr_matrix`` or
    ``sp.csc_matrix``) for arrays that are already what scipy's constructor would keep: ``data``
    float64, ``indices`` and ``indptr`` int32 (scipy's choice below 2³¹ entries), ``indptr`` of
    ``shape``'s compressed dimension plus one entries, ending at ``indices.size == data.size``.
    Then the matrix is a copy of one that the constructor built, given these arrays and shape
    (about 1 µs instead of 14 µs: the constructor's checks and index-type search, over a dozen
    times per avoidance plan); the arrays are the same objects as the constructor keeps.  Any
    other input goes to the constructor itself (``tests/test_backends.py`` compares the two)."""
    n_ptr = shape[0] if kind is sp.csr_matrix else shape[1]
    if (kind in _TEMPLATES and data.dtype == np.float64 and indices.dtype == np.int32
            and indptr.dtype == np.int32 and data.ndim == indices.ndim == indptr.ndim == 1
            and indptr.size == n_ptr + 1 and data.size == indices.size and int(indptr[-1]) == indices.size
            and int(indptr[0]) == 0 and max(shape) < 2**31 - 1 and min(shape) >= 0):
        out = _clone(_TEMPLATES[kind])
        out.data, out.indices, out.indptr, out._shape = data, indices, indptr, (int(shape[0]), int(shape[1]))
        return out
    return kind((data, indices, indptr), shape=shape)


#: One matrix of each kind built by scipy's constructor (:func:`compressed` copies it): its
#: attributes other than the arrays and the shape; no flag of its indices (found again, as
#: for a new matrix).
_TEMPLATES: dict[type, sp.csr_matrix | sp.csc_matrix] = {}
for _kind in (sp.csr_matrix, sp.csc_matrix):
    _TEMPLATES[_kind] = _kind((np.zeros(0), np.zeros(0, dtype=np.int32), np.zeros(2, dtype=np.int32)), shape=(1, 1))
    for _flag in ("_has_sorted_indices", "_has_canonical_format"):
        _TEMPLATES[_kind].__dict__.pop(_flag, None)


_INT32_MAX = int(np.iinfo(np.int32).max)


def csr_to_csc(indptr: NDArray[Any], indices: NDArray[Any], data: FloatArray,
               shape: tuple[int, int]) -> tuple[NDArray[Any], NDArray[Any], FloatArray]:
    """The CSC arrays ``(indptr, indices, data)`` of the CSR matrix of ``shape`` with these arrays,
    as ``tocsc()`` of that matrix computes them (its CSC constructor then narrows int64 indices
    that fit to int32: :func:`compressed` of the result does the same).

    Parameters
    ----------
    indptr, indices : ndarray of int
        The CSR row pointers (``shape[0] + 1`` of them, starting at 0) and column indices.
    data : ndarray of float64
        The stored values (``indptr[-1]`` of them).
    shape : tuple of int
        ``(rows, columns)``.

    Returns
    -------
    tuple of ndarray
        The column pointers, row indices and values of the CSC form: scipy's compiled
        ``csr_tocsc`` itself, called on the index type ``tocsc`` picks (int32 when both index arrays
        are int32 or narrower and ``max(nnz, rows)`` fits, else int64), so each column's entries are
        in the order of their rows (a stable sort by column of the row-major entries; sorted
        indices) and the numbers are the same, bit for bit, without the conversion's wrapper
        (the matrix's construction, checks and index-type search).
    """
    M, N = int(shape[0]), int(shape[1])
    if _sparsetools is None:  # another scipy: its own conversion (the same arrays)
        C = sp.csr_matrix((data, indices, indptr), shape=(M, N)).tocsc()
        return C.indptr, C.indices, C.data
    nnz = int(indptr[-1])
    idx = (np.int32 if (np.can_cast(indptr.dtype, np.int32) and np.can_cast(indices.dtype, np.int32)
                        and max(nnz, M) <= _INT32_MAX) else np.int64)
    out_ptr = np.empty(N + 1, dtype=idx)
    out_ind = np.empty(nnz, dtype=idx)
    out_data = np.empty(nnz, dtype=data.dtype)
    _sparsetools.csr_tocsc(M, N, indptr.astype(idx, copy=False), indices.astype(idx, copy=False), data,
                           out_ptr, out_ind, out_data)
    return out_ptr, out_ind, out_data


#: scipy's compiled products of a CSR and a CSC matrix with a vector (what ``@`` calls)
_MATVEC: dict[type, Any] = ({} if _sparsetools is None else
                            {sp.csr_matrix: _sparsetools.csr_matvec, sp.csc_matrix: _sparsetools.csc_matvec})


def matvec(M: sp.spmatrix, x: FloatArray) -> FloatArray:
    """``M @ x`` of a sparse float matrix and a float vector, without scipy's dispatch.

    Parameters
    ----------
    M : scipy.sparse matrix
        Any sparse matrix; a ``csr_matrix``, ``csc_matrix`` or ``coo_matrix`` of float64 takes
        the direct path.
    x : ndarray
        The vector (``M.shape[1]`` entries).

    Returns
    -------
    ndarray
        ``M @ x``: for a float64 CSR, CSC or COO matrix and a float64 vector of its width, the
        compiled product scipy's ``@`` calls (``csr_matvec``, ``csc_matvec``, ``coo_matvec``) on
        the same arrays into zeros of the same type, so the same numbers bit for bit (each
        row's sum in the same order); any other operand goes to ``@`` itself.
    """
    if x.__class__ is np.ndarray and x.dtype == np.float64 and M.dtype == np.float64:
        m, n = M.shape
        if x.shape == (n,):
            kind = type(M)
            fn = _MATVEC.get(kind)
            if fn is not None:
                out = np.zeros(m)
                fn(m, n, M.indptr, M.indices, M.data, x, out)
                return out
            if kind is sp.coo_matrix and _sparsetools is not None:
                out = np.zeros(m)
                _sparsetools.coo_matvec(len(M.data), M.row, M.col, M.data, x, out)
                return out
    return np.asarray(M @ x)


def csc_rows(A: sp.csc_matrix, rows: IntArray) -> sp.csc_matrix:
    """``sp.csc_matrix(A[rows])`` of a CSC ``A`` and increasing ``rows``, every stored entry kept
    (explicit zeros too): the same arrays, gathered from ``A``'s own (each kept entry's row
    renumbered, each column's count of kept entries) without scipy's fancy indexing."""
    at = np.full(A.shape[0], -1, dtype=np.int64)
    at[rows] = np.arange(rows.size)
    new = at[A.indices]
    kept = new >= 0
    indptr = np.concatenate(([0], np.cumsum(kept)))[A.indptr].astype(A.indptr.dtype)
    return compressed(sp.csc_matrix, A.data[kept], new[kept].astype(A.indices.dtype), indptr, (rows.size, A.shape[1]))


@functools.cache
def dist_version(name: str) -> str | None:
    """Installed version of the distribution ``name`` (``None`` if absent).

    Cached for the process: reading the package metadata cost 3 ms a call, once per QP set-up
    (measured under ``python -m cProfile`` on the ``avoid_bounded`` bench plan: 1.5 s of 7 s).
    """
    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return None


class QPBackend(abc.ABC):
    """A QP solver behind one signature (module docstring for the problem form).

    Parameters
    ----------
    P : scipy.sparse matrix
        Upper triangle of the cost Hessian (CSC); its pattern is fixed from here on.
    q, l, u : ndarray
    A : scipy.sparse matrix
        Constraint matrix (CSC); its pattern (explicit zeros included) is fixed.
    settings : mapping, optional
        Overrides of :meth:`default_settings`.

    Use ``backend.update(Ax=values, Ax_idx=positions, l=…, u=…)`` to change values on the
    fixed pattern, ``backend.warm_start(z, y)`` (ignored by interior-point and direct
    solvers) and ``backend.solve() -> QPSolution``.  :meth:`residuals` recomputes the KKT
    residuals of a solution on the backend's current data.
    """

    name: ClassVar[str] = ""
    distribution: ClassVar[str] = ""
    #: Does the backend accept rows with ``l_i < u_i``?
    supports_inequalities: ClassVar[bool] = True
    #: Does :meth:`warm_start` do anything?
    warm_starts: ClassVar[bool] = False
    #: Name of the relative KKT tolerance in :data:`iamp.core.tolerances.TOLERANCES`.
    tolerance_key: ClassVar[str] = "cmp_kkt_rel_clarabel"

    def __init__(self, P: sp.spmatrix, q: FloatArray, A: sp.spmatrix, l: FloatArray, u: FloatArray,
                 settings: Mapping[str, Any] | None = None) -> None:
        self.require()
        self.P = csc_copy(P)
        self.A = csc_copy(A)
        self.q = np.array(q, dtype=float)
        self.l = np.array(l, dtype=float)
        self.u = np.array(u, dtype=float)
        if self.A.shape != (self.l.size, self.q.size) or self.u.shape != self.l.shape:
            raise ValueError("A must be (len(l), len(q)) and l, u of the same length")
        self._given = frozenset(settings or ())  # the settings the caller chose explicitly
        self.settings: dict[str, Any] = {**self.default_settings(), **dict(settings or {})}
        self.applied_settings: dict[str, Any] = dict(self.settings)
        self._check_form()
        self._setup()

    # --- to implement ------------------------------------------------------------------
    @classmethod
    def default_settings(cls) -> dict[str, Any]:
        return {}

    @abc.abstractmethod
    def _setup(self) -> None:
        """Build the solver from ``self.P, q, A, l, u`` and ``self.settings``."""

    @abc.abstractmethod
    def _push(self, P: bool, A: bool, A_idx: IntArray | None, q: bool, bounds: bool) -> None:
        """Send the changed data (already stored on ``self``) to the solver."""

    @abc.abstractmethod
    def solve(self) -> QPSolution:
        """Solve with the current data."""

    # --- shared --------------------------------------------------------------------------
    @classmethod
    def version(cls) -> str | None:
        return dist_version(cls.distribution) if cls.distribution else None

    @classmethod
    def require(cls) -> None:
        """Raise :class:`MissingDependencyError` (with the pip command) if not installed."""
        if cls.distribution and cls.version() is None:
            raise MissingDependencyError(
                f"QP backend {cls.name!r} needs the package {cls.distribution!r}: pip install {cls.distribution}")

    def _check_form(self) -> None:
        if not self.supports_inequalities and not np.array_equal(self.l, self.u):
            bad = int(np.flatnonzero(self.l != self.u)[0])
            raise UnsupportedProblemError(
                f"QP backend {self.name!r} solves equality-constrained QPs only (l == u), but row {bad} has "
                f"l = {self.l[bad]:g} < u = {self.u[bad]:g}; use osqp, clarabel or piqp for inequalities")

    def update(self, *, Px: FloatArray | None = None, Ax: FloatArray | None = None,
               Ax_idx: IntArray | None = None, q: FloatArray | None = None, l: FloatArray | None = None,
               u: FloatArray | None = None) -> None:
        """Change values on the fixed patterns.

        ``Px``: the whole ``P.data`` (upper triangle, CSC order).  ``Ax``: the whole
        ``A.data``, or, with ``Ax_idx``, the values at those positions of ``A.data``.
        ``q, l, u``: whole vectors.
        """
        if Px is not None:
            if Px.shape != self.P.data.shape:
                raise ValueError("Px must have one value per stored entry of P")
            self.P.data[:] = Px
        idx = None
        if Ax is not None:
            if Ax_idx is None:
                if Ax.shape != self.A.data.shape:
                    raise ValueError("Ax must have one value per stored entry of A (or give Ax_idx)")
                self.A.data[:] = Ax
            else:
                idx = np.asarray(Ax_idx, dtype=np.int64)
                self.A.data[idx] = Ax
        if q is not None:
            self.q[:] = q
        if l is not None:
            self.l[:] = l
        if u is not None:
            self.u[:] = u
        if (l is not None or u is not None) and l is not u:  # the same array twice: equalities
            self._check_form()
        self._push(Px is not None, Ax is not None, idx, q is not None, l is not None or u is not None)

    def warm_start(self, z: FloatArray, y: FloatArray) -> None:  # noqa: B027 - optional hook
        """Start the next solve from ``(z, y)`` (no-op unless :attr:`warm_starts`)."""

    def residuals(self, sol: QPSolution) -> KKTResiduals:
        """KKT residuals of ``sol`` on the backend's current data."""
        return sol.kkt_residuals(self.P, self.q, self.A, self.l, self.u)

    def _apply_settings(self, equality_only: bool, equality: Mapping[str, Any]) -> dict[str, Any]:
        """``self.settings`` plus, when every row is an equality, the backend's measured
        ``equality`` settings except those the caller gave explicitly; kept as
        ``applied_settings`` (what :meth:`describe` reports)."""
        settings = dict(self.settings)
        if equality_only:
            settings.update({k: v for k, v in equality.items() if k not in self._given})
        self.applied_settings = settings
        return settings

    def describe(self) -> dict[str, Any]:
        """Name, version and the settings applied (for reports)."""
        return {"name": self.name, "version": self.version(), "settings": dict(self.applied_settings)}
