r"""Many polynomials at once: real roots on ``[0, 1]`` and row-wise coefficient algebra.

Every array holds one polynomial per row in **ascending** powers,
:math:`p_r(\sigma) = \sum_{k=0}^{D} C_{r,k}\,\sigma^k`.  Roots come from the eigenvalues of
the companion matrix of each row (rows grouped by their true degree, so one batched
``eigvals`` per degree), polished by Newton steps :math:`\sigma \leftarrow \sigma -
p(\sigma)/p'(\sigma)` that are kept only where they lower :math:`|p|`.  A row whose Bernstein
coefficients on ``[0, 1]`` all exceed (in absolute value, with one sign) a bound on what the
eigenvalue solver's backward error, the complex tolerance and the round-off could make of it has no
root in the accepted window and is not sent to ``eigvals`` (:func:`~iamp.core.polyroots_kernel.root_degrees`):
the roots returned are those of the full computation, bit for bit, since each row's eigenvalues
and Newton steps do not depend on the other rows.
"""

from __future__ import annotations

from math import comb
from typing import Any

import numpy as np
from numpy.typing import NDArray

from iamp.core import jit
from iamp.core import polyroots_kernel as _kernel

__all__ = ["pad_coeffs", "poly_deriv", "poly_mul", "polyval_rows", "roots_in_unit_interval"]

FloatArray = NDArray[np.float64]


def polyval_rows(C: FloatArray, x: FloatArray) -> FloatArray:
    """:math:`p_r(x_r)` for every row ``r`` (Horner; :func:`iamp.core.polyroots_kernel.horner`)."""
    out: FloatArray = _kernel.horner(np.asarray(C, dtype=float), np.asarray(x, dtype=float))
    return out


def roots_in_unit_interval(C: FloatArray, imag_tol: float = 1e-6) -> tuple[NDArray[np.intp], FloatArray]:
    """Real roots in ``[0, 1]`` of many polynomials at once.

    Parameters
    ----------
    C : ndarray, shape (K, D + 1)
        Ascending coefficients, one polynomial per row.
    imag_tol : float
        Eigenvalues with ``|Im| <= imag_tol`` count as real (near-double roots; an extra cut
        point is harmless to every caller).

    Returns
    -------
    rows, sigma : ndarray
        Row index and root of every root found, polished by Newton steps.

    Notes
    -----
    The degrees and the Bernstein test (:func:`~iamp.core.polyroots_kernel.root_degrees`) and the
    window and Newton steps (:func:`~iamp.core.polyroots_kernel.polish_roots`) run as one kernel
    each (:func:`kernel`); the eigenvalues are numpy's, per degree.
    """
    C = np.ascontiguousarray(C, dtype=float)
    K, D1 = C.shape
    if K == 0 or D1 < 2:
        return np.zeros(0, dtype=np.intp), np.zeros(0)
    deg = _degrees(C, imag_tol, _SKIP_FAR)
    sent = deg.nonzero()[0]
    if sent.size == 0:
        return np.zeros(0, dtype=np.intp), np.zeros(0)
    rows_in: list[NDArray[np.intp]] = []
    eig: list[NDArray[np.complex128]] = []
    dsent = deg[sent]
    for d in np.bincount(dsent).nonzero()[0].tolist():  # the degrees present, ascending (numpy.unique's)
        idx = sent[dsent == d]
        Ci = C.take(idx, 0)  # C[idx] (one copy of the rows, as indexing makes it)
        lead = Ci[:, d]
        if d == 1:
            r = (-Ci[:, 0] / lead)[:, None].astype(complex)
        else:
            comp = np.zeros((idx.size, d, d))
            comp.reshape(idx.size, d * d)[:, d::d + 1] = 1.0  # the ones below the diagonal (numpy.eye(d - 1)'s)
            comp[:, :, -1] = -Ci[:, :d] / lead[:, None]
            r = _eigvals(comp)
        rows_in.append(np.repeat(idx, d))
        eig.append(r.ravel())
    rr = np.concatenate(rows_in).astype(np.int64)
    z = np.concatenate(eig)
    args = (C, rr, np.ascontiguousarray(z.real), np.ascontiguousarray(z.imag), float(imag_tol))
    if _PYTHON:
        with np.errstate(invalid="ignore"):  # NaN coefficients (kept, as numpy's eigenvalues give them)
            rows, x = kernel("polish_roots")(*args)
    else:  # compiled: no numpy error state to set (the same numbers, no warnings either way)
        rows, x = kernel("polish_roots")(*args)
    return rows.astype(np.intp), x


def _eigvals(comp: FloatArray) -> NDArray[Any]:
    r"""The eigenvalues of the stacked real matrices ``comp``, bit for bit those of
    ``numpy.linalg.eigvals(comp)`` as :func:`roots_in_unit_interval` uses them.

    ``numpy.linalg.eigvals`` checks the input, calls its LAPACK ``geev`` ufunc
    (``_umath_linalg.eigvals``, signature ``d->D``) under an error state that turns an invalid
    result (no convergence) into ``LinAlgError``, and returns the real parts alone when every
    imaginary part is zero: some 20-40 µs of Python per call around a few µs of LAPACK.  Here the
    same ufunc is called on the same array, so the same eigenvalues; an imaginary part left at
    zero (either sign) is read only through :math:`|\mathrm{Im}\,z| \le` ``imag_tol``, as the
    ``+0`` of numpy's real result would be.  A non-finite input or output goes to
    ``numpy.linalg.eigvals`` itself (its error, or its numbers), as does a numpy without the ufunc.
    """
    if _GEEV is None or not np.isfinite(comp).all():
        out: NDArray[Any] = np.linalg.eigvals(comp)
        return out
    with np.errstate(all="ignore"):
        w: NDArray[np.complex128] = _GEEV(comp, signature="d->D")
    if not np.isfinite(w).all():
        out = np.linalg.eigvals(comp)
        return out
    return w


try:  # numpy's LAPACK eigenvalue ufunc (private; numpy.linalg.eigvals where it moved)
    from numpy.linalg import _umath_linalg

    _GEEV: Any = _umath_linalg.eigvals
except (ImportError, AttributeError):  # pragma: no cover
    _GEEV = None


def _degrees(C: FloatArray, imag_tol: float, skip_far: bool = True) -> NDArray[np.int64]:
    """Each row's degree, 0 for a row not sent to the eigenvalues: a constant or, with ``skip_far``,
    a row whose Bernstein coefficients prove no eigenvalue in the accepted window
    (:func:`~iamp.core.polyroots_kernel.root_degrees`); ``C`` C-contiguous floats with >= 2 columns."""
    deg = np.empty(C.shape[0], dtype=np.int64)
    args = (C, _bernstein_matrix(C.shape[1] - 1), float(imag_tol), bool(skip_far), deg)
    if _PYTHON:
        with np.errstate(over="ignore", invalid="ignore"):  # an overflowing bound keeps its row
            kernel("root_degrees")(*args)
    else:  # compiled code raises no numpy floating-point warnings: no error state to set
        kernel("root_degrees")(*args)
    return deg


#: Skip the rows whose Bernstein coefficients prove no root in the window (``False``: every row
#: of positive degree goes to the eigenvalues, the full computation the tests compare with).
_SKIP_FAR = True
#: Run the kernels as Python: the same numbers, bit for bit, more slowly (the default: every plan's
#: safety report reaches these kernels, and an everyday ``iamp plan`` must not import numba,
#: ``tests/test_issue22.py``); :func:`load` switches to the compiled twins where numba is installed.
_PYTHON = True
_TWINS: dict[str, Any] = {}


def load() -> bool:
    """Use the numba-compiled kernels in this process from now on (opt-in, as the PMP's
    :func:`~iamp.planners.pmp.compiled.load_axis`; :func:`iamp.planners.kernels.warm_kernels`
    calls it).  Returns whether they are compiled (``False``: numba is not installed, the kernels
    stay Python).  The numbers are the same either way."""
    global _PYTHON
    _PYTHON = not jit.available()
    return not _PYTHON


def kernel(name: str) -> Any:
    """The kernel ``name`` of :mod:`iamp.core.polyroots_kernel`: compiled by numba once
    :func:`load` was called and numba is installed (:func:`iamp.core.jit.twin`, cached on disk),
    else the Python function itself: the same numbers."""
    fn = getattr(_kernel, name)
    if _PYTHON:
        return fn
    twin = _TWINS.get(name)
    if twin is None:
        twin = _TWINS[name] = jit.twin(fn, cache=True)
    return twin


def _bernstein_matrix(n: int) -> FloatArray:
    """``M`` with ``C @ M`` the Bernstein coefficients on ``[0, 1]`` of ascending ``C`` of degree ``n``:
    :math:`b_j = \\sum_{k \\le j} \\binom{j}{k} / \\binom{n}{k}\\, c_k`."""
    M = _BERNSTEIN.get(n)
    if M is None:
        M = np.zeros((n + 1, n + 1))
        for j in range(n + 1):
            for k in range(j + 1):
                M[k, j] = comb(j, k) / comb(n, k)
        _BERNSTEIN[n] = M
    return M


_BERNSTEIN: dict[int, FloatArray] = {}


def poly_mul(A: FloatArray, B: FloatArray) -> FloatArray:
    r"""Row-wise product of ascending coefficient arrays: :math:`(AB)_{r,m} = \sum_i A_{r,i} B_{r,m-i}`,
    summed from 0 in ascending :math:`i`.

    Computed on the transposed coefficients (one contiguous row per power: each in-place
    addition reads consecutive numbers, twice as fast on 200 x 4 by 200 x 3), the same products
    added in the same order, so the same numbers; returned C-contiguous, shape ``(K, D_A + D_B - 1)``.
    """
    na, nb = A.shape[1], B.shape[1]
    At, Bt = np.ascontiguousarray(A.T), np.ascontiguousarray(B.T)
    out = np.zeros((na + nb - 1, A.shape[0]))
    for i in range(na):
        out[i:i + nb] += At[i] * Bt
    return np.ascontiguousarray(out.T)


def pad_coeffs(A: FloatArray, n: int) -> FloatArray:
    """``A`` with zero coefficients appended up to ``n`` columns (degree ``n − 1``)."""
    if n < A.shape[1]:
        return np.pad(A, ((0, 0), (0, n - A.shape[1])))  # raises, as it always did
    # np.pad's result (its memory order too), without its overhead
    out = np.zeros((A.shape[0], n), dtype=A.dtype, order="F" if A.flags.fnc else "C")
    out[:, :A.shape[1]] = A
    return out


def poly_deriv(A: FloatArray) -> FloatArray:
    """Row-wise derivative: :math:`p'(\\sigma) = \\sum_k k\\,C_k\\,\\sigma^{k-1}`."""
    return A[:, 1:] * np.arange(1, A.shape[1])
