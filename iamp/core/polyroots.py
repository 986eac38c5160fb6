r"""Many polynomials at once: real roots on ``[0, 1]`` and row-wise coefficient algebra.

Every array holds one polynomial per row in **ascending** powers,
:math:`p_r(\sigma) = \sum_{k=0}^{D} C_{r,k}\,\sigma^k`.  Roots come from the eigenvalues of
the companion matrix of each row (rows grouped by their true degree, so one batched
``eigvals`` per degree), polished by Newton steps :math:`\sigma \leftarrow \sigma -
p(\sigma)/p'(\sigma)` that are kept only where they lower :math:`|p|`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["pad_coeffs", "poly_deriv", "poly_mul", "polyval_rows", "roots_in_unit_interval"]

FloatArray = NDArray[np.float64]


def polyval_rows(C: FloatArray, x: FloatArray) -> FloatArray:
    """:math:`p_r(x_r)` for every row ``r`` (Horner)."""
    out = np.zeros_like(x)
    for k in range(C.shape[1] - 1, -1, -1):
        out = out * x + C[:, k]
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
    """
    C = np.asarray(C, dtype=float)
    D1 = C.shape[1]
    scale = np.max(np.abs(C), axis=1)
    big = np.abs(C) > 1e-12 * scale[:, None]
    deg = np.where(big.any(axis=1), D1 - 1 - np.argmax(big[:, ::-1], axis=1), 0)
    rows_out: list[NDArray[np.intp]] = []
    roots_out: list[FloatArray] = []
    for d in np.unique(deg):
        d = int(d)
        if d == 0:
            continue
        idx = np.flatnonzero(deg == d)
        lead = C[idx, d]
        if d == 1:
            r = (-C[idx, 0] / lead)[:, None].astype(complex)
        else:
            comp = np.zeros((idx.size, d, d))
            comp[:, 1:, :-1] = np.eye(d - 1)
            comp[:, :, -1] = -C[idx, :d] / lead[:, None]
            r = np.linalg.eigvals(comp)
        ok = (np.abs(r.imag) <= imag_tol) & (r.real >= -1e-9) & (r.real <= 1 + 1e-9)
        ii, jj = np.nonzero(ok)
        rows_out.append(idx[ii])
        roots_out.append(np.clip(r.real[ii, jj], 0.0, 1.0))
    if not rows_out:
        return np.zeros(0, dtype=np.intp), np.zeros(0)
    rows, x = np.concatenate(rows_out), np.concatenate(roots_out)
    if rows.size:
        Cr = C[rows]
        dC = Cr[:, 1:] * np.arange(1, D1)
        for _ in range(3):
            f = polyval_rows(Cr, x)
            fp = polyval_rows(dC, x)
            with np.errstate(divide="ignore", invalid="ignore"):
                step = np.where(fp != 0, f / fp, 0.0)
            xn = np.clip(x - step, 0.0, 1.0)
            better = np.abs(polyval_rows(Cr, xn)) < np.abs(f)
            x = np.where(better & np.isfinite(xn), xn, x)
    return rows, x


def poly_mul(A: FloatArray, B: FloatArray) -> FloatArray:
    """Row-wise product of ascending coefficient arrays."""
    out = np.zeros((A.shape[0], A.shape[1] + B.shape[1] - 1))
    for i in range(A.shape[1]):
        out[:, i:i + B.shape[1]] += A[:, [i]] * B
    return out


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
