r"""The exact direct backend: the KKT system of an equality-constrained QP, solved directly.

For :math:`\min \tfrac12 z^\top P z + q^\top z` s.t. :math:`Az = b` the optimum and its
multipliers solve the linear KKT system

.. math::

    \begin{bmatrix} P & A^\top \\ A & 0 \end{bmatrix}
    \begin{bmatrix} z \\ y \end{bmatrix} =
    \begin{bmatrix} -q \\ b \end{bmatrix} ,

exactly (no iteration, no tolerance): this backend is the reference the iterative ones are
measured against.  Inequalities are refused (:class:`UnsupportedProblemError`).

Structure used
--------------
Rows of ``A`` whose stored pattern is long (more than ``border_row_nnz`` entries, default
8 — in the lane-change QP the contact *selector* rows, whose pattern holds every interior
node) are treated as a **border**; the remaining *core* KKT matrix :math:`K_0` (dynamics,
boundary rows and ``P``) is banded after a reverse Cuthill–McKee ordering computed once from
the pattern (bandwidth 3–7 for the lane-change QP at any ``N``; reported as
:attr:`KKTBackend.bandwidth`).  With the border rows :math:`C = [A_1\ 0]`,

.. math::

    K_0 w_0 = r_0,\quad K_0 W = C^\top,\quad S = C W,\quad
    S\,y_1 = C w_0 - b_1,\quad w = w_0 - W y_1 ,

a Schur complement of size (number of border rows).  :math:`K_0` is factorised by LAPACK's
banded LU (``dgbtrf``, partial pivoting) only when ``P`` or the core of ``A`` changes — a
new grid — so every candidate of a sweep on one grid reuses **one** factorisation (symbolic
and numeric) and costs one banded triangular solve (``dgbtrs``) with ``1 + #border``
right-hand sides.  Optionally (setting ``refine_above``, relative; default ``None`` = off)
one step of iterative refinement on the full system follows when the recomputed residual
exceeds it.  Off by default because it is not needed: the recomputed relative KKT residuals
of the unrefined solutions of the lane-change QP are ~1e-14 (tests assert < 1e-12), and the
caller (:class:`~iamp.planners.qp_core.DiscretisedQP`) verifies every solution anyway.

Status: OPTIMAL when the factorisation is regular and the solution finite; otherwise
NUMERICAL_ERROR (a singular KKT matrix: ``A`` rank-deficient or ``P`` not positive definite
on the null space of ``A``).  ``solver_time_s`` is the measured time of :meth:`solve`.
"""

from __future__ import annotations

import time
from typing import Any, ClassVar

import numpy as np
import scipy.sparse as sp
from scipy.linalg import lapack
from scipy.sparse.csgraph import reverse_cuthill_mckee

from iamp.core import status as st
from iamp.planners.backends.base import IntArray, QPBackend, QPSolution


class KKTBackend(QPBackend):
    """Direct banded solve of the equality QP's KKT system (module docstring)."""

    name: ClassVar[str] = "kkt"
    distribution: ClassVar[str] = ""  # numpy/scipy only
    supports_inequalities: ClassVar[bool] = False
    tolerance_key: ClassVar[str] = "cmp_kkt_rel_clarabel"

    @classmethod
    def default_settings(cls) -> dict[str, Any]:
        return {"border_row_nnz": 8, "refine_above": None}

    # --- symbolic analysis (once) --------------------------------------------------------
    def _setup(self) -> None:
        n, mrows = self.q.size, self.l.size
        A = self.A
        row_nnz = np.bincount(A.indices, minlength=mrows)
        self._border = np.flatnonzero(row_nnz > int(self.settings["border_row_nnz"]))
        self._core = np.flatnonzero(row_nnz <= int(self.settings["border_row_nnz"]))
        core_of_row = np.full(mrows, -1, dtype=np.int64)
        core_of_row[self._core] = np.arange(self._core.size)
        nk = n + self._core.size
        self._nk = nk
        # COO of A.data with its rows/cols
        a_cols = np.repeat(np.arange(n), np.diff(A.indptr))
        a_rows = A.indices.astype(np.int64)
        in_core = core_of_row[a_rows] >= 0
        self._a_core_pos = np.flatnonzero(in_core)
        self._a_in_core = in_core
        kr = n + core_of_row[a_rows[in_core]]
        kc = a_cols[in_core]
        # COO of P.data (upper triangle)
        P = self.P
        p_cols = np.repeat(np.arange(n), np.diff(P.indptr))
        p_rows = P.indices.astype(np.int64)
        # symmetric pattern of K0 and its RCM order
        pr = np.concatenate([p_rows, p_cols, kr, kc, np.arange(nk)])
        pc = np.concatenate([p_cols, p_rows, kc, kr, np.arange(nk)])
        pattern = sp.csr_matrix((np.ones(pr.size), (pr, pc)), shape=(nk, nk))
        perm = np.asarray(reverse_cuthill_mckee(pattern, symmetric_mode=True), dtype=np.int64)
        inv = np.empty(nk, dtype=np.int64)
        inv[perm] = np.arange(nk)
        self._perm, self._inv = perm, inv
        bw = int(np.max(np.abs(inv[pr] - inv[pc])))
        self.bandwidth = bw
        kl = ku = bw
        self._kl, self._ku = kl, ku
        ldab = 2 * kl + ku + 1

        def flat(i: np.ndarray, j: np.ndarray) -> np.ndarray:
            ii, jj = inv[i], inv[j]
            return np.asarray((kl + ku + ii - jj) * nk + jj, dtype=np.int64)

        self._ab_shape = (ldab, nk)
        # P entry d -> (d, d') positions; off-diagonal entries also mirrored
        self._p_pos = flat(p_rows, p_cols)
        off = p_rows != p_cols
        self._p_off = np.flatnonzero(off)
        self._p_pos_mirror = flat(p_cols[off], p_rows[off])
        self._a_pos = flat(kr, kc)
        self._a_pos_t = flat(kc, kr)
        # border rows: positions in A.data and their columns
        b_mask = ~in_core
        self._b_pos = np.flatnonzero(b_mask)
        border_of_row = np.full(mrows, -1, dtype=np.int64)
        border_of_row[self._border] = np.arange(self._border.size)
        self._b_row = border_of_row[a_rows[b_mask]]
        self._b_col = a_cols[b_mask]
        self._b_range = np.arange(self._border.size)
        self._factor: tuple[np.ndarray, np.ndarray] | None = None
        self._info = 0
        self.factorisations = 0  # numeric factorisations so far (one per grid)
        self._P_full: sp.csr_matrix | None = None
        self._AT = self.A.T  # a CSR view sharing A.data (updated in place)

    # --- numeric factorisation (per grid) ------------------------------------------------
    def _factorise(self) -> None:
        ab = np.zeros(self._ab_shape)
        flat = ab.reshape(-1)
        flat[self._p_pos] = self.P.data
        flat[self._p_pos_mirror] = self.P.data[self._p_off]
        ad = self.A.data[self._a_core_pos]
        flat[self._a_pos] = ad
        flat[self._a_pos_t] = ad
        lu, piv, info = lapack.dgbtrf(ab, self._kl, self._ku, overwrite_ab=True)
        self.factorisations += 1
        self._factor = (lu, piv)
        self._info = int(info)
        self._uses = 0
        self._all_cols: np.ndarray | None = None
        self._col_block = np.zeros((0, 0))
        self._w0: tuple[np.ndarray, np.ndarray] | None = None

    def _push(self, P: bool, A: bool, A_idx: IntArray | None, q: bool, bounds: bool) -> None:
        if P:
            self._factor = None
            self._P_full = None
        if A:
            if A_idx is None:
                self._factor = None
            elif A_idx.size and bool(self._a_in_core[A_idx].any()):
                self._factor = None

    def _k0_solve(self, rhs: np.ndarray) -> np.ndarray:
        assert self._factor is not None
        lu, piv = self._factor
        x, info = lapack.dgbtrs(lu, self._kl, self._ku, np.asfortranarray(rhs[self._perm]), piv, overwrite_b=True)
        if info != 0:  # pragma: no cover - only for malformed input
            raise ValueError("dgbtrs failed")
        return np.asarray(x[self._inv])

    def _columns(self, cols: np.ndarray) -> np.ndarray:
        """``K0⁻¹ e_c`` for the columns ``cols``, cached for the current factorisation.

        The first solve on a factorisation computes only the columns it needs; the second
        one (a sweep: the same grid, another candidate) computes every column of the border
        rows' pattern in one multi-right-hand-side solve, so the rest of the sweep only
        gathers columns.
        """
        self._uses += 1
        if self._all_cols is None and self._uses >= 2:
            pattern = np.unique(self._b_col)
            E = np.zeros((self._nk, pattern.size))
            E[pattern, np.arange(pattern.size)] = 1.0
            self._all_cols = np.full(self._nk, -1, dtype=np.int64)
            self._all_cols[pattern] = np.arange(pattern.size)
            self._col_block = self._k0_solve(E)
        if self._all_cols is not None:
            return np.asarray(self._col_block[:, self._all_cols[cols]])
        E = np.zeros((self._nk, cols.size))
        E[cols, np.arange(cols.size)] = 1.0
        return np.asarray(self._k0_solve(E))

    def _core_solve(self, r0: np.ndarray) -> np.ndarray:
        """``K0⁻¹ r0``, remembered for a repeated right-hand side (the candidates of a
        sweep share it: only the border rows' values and right-hand sides change)."""
        if self._w0 is not None and np.array_equal(self._w0[0], r0):
            return self._w0[1]
        w0 = self._k0_solve(r0)
        self._w0 = (r0.copy(), w0)
        return w0

    def _full_solve(self, rhs_z: np.ndarray, b: np.ndarray, cache: bool = True) -> tuple[np.ndarray, np.ndarray]:
        n, nb = self.q.size, self._border.size
        r0 = np.concatenate([rhs_z, b[self._core]])
        w0 = self._core_solve(r0) if cache else self._k0_solve(r0)
        if nb == 0:
            w, y1 = w0, np.zeros(0)
        else:
            vals = self.A.data[self._b_pos]
            nz = vals != 0
            rows, cols, v = self._b_row[nz], self._b_col[nz], vals[nz]
            # W = K0⁻¹ Cᵀ: column r = Σ_j v_j K0⁻¹ e_{col_j} over border row r's nonzeros
            Wc = self._columns(cols) * v
            if rows.size == nb and np.array_equal(rows, self._b_range):
                W = Wc  # one nonzero per border row (the selector rows): C = diag(v) E_colsᵀ
                S = v[:, None] * W[cols, :]
                Cw0 = v * w0[cols]
            else:
                W = np.zeros((self._nk, nb))
                np.add.at(W.T, rows, Wc.T)
                S = np.zeros((nb, nb))
                np.add.at(S, rows, v[:, None] * W[cols, :])  # S = C W
                Cw0 = np.bincount(rows, weights=v * w0[cols], minlength=nb)
            y1 = np.linalg.solve(S, Cw0 - b[self._border])
            w = w0 - W @ y1
        y = np.empty(self.l.size)
        y[self._core] = w[n:]
        y[self._border] = y1
        return w[:n], y

    def solve(self) -> QPSolution:
        t0 = time.perf_counter()
        status, raw, iters = st.OPTIMAL, "solved", 1
        try:
            if self._factor is None:
                self._factorise()
            if self._info != 0:
                raise np.linalg.LinAlgError(f"singular core KKT matrix (dgbtrf info {self._info})")
            z, y = self._full_solve(-self.q, self.l)
            refine = self.settings["refine_above"]
            if refine is not None:  # residual of the full system; refine once if needed
                z, y, iters = self._refine(z, y, float(refine))
            if not (np.isfinite(z).all() and np.isfinite(y).all()):
                raise np.linalg.LinAlgError("non-finite solution")
        except np.linalg.LinAlgError as exc:
            status, raw = st.NUMERICAL_ERROR, f"singular: {exc}"
            z, y = np.full(self.q.size, np.nan), np.full(self.l.size, np.nan)
        call = time.perf_counter() - t0
        return QPSolution(z=z, y=y, status=status, raw_status=raw, iterations=iters, solver_time_s=call,
                          solve_call_s=call)

    def _refine(self, z: np.ndarray, y: np.ndarray, threshold: float) -> tuple[np.ndarray, np.ndarray, int]:
        """One step of iterative refinement when the recomputed residual exceeds ``threshold``."""
        if self._P_full is None:
            self._P_full = sp.csr_matrix(self.P + sp.triu(self.P, 1).T)
        rz = -self.q - (self._P_full @ z + self._AT @ y)
        rb = self.l - self.A @ z
        scale = max(1.0, float(np.max(np.abs(self.q), initial=0.0)), float(np.max(np.abs(self.l), initial=0.0)))
        if max(float(np.max(np.abs(rz), initial=0.0)), float(np.max(np.abs(rb), initial=0.0))) <= threshold * scale:
            return z, y, 1
        dz, dy = self._full_solve(rz, rb, cache=False)
        return z + dz, y + dy, 2
