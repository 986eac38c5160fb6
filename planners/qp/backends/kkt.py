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
boundary rows and ``P``) is block diagonal — one block per connected component of its
pattern (the two axes of the lane-change QP) — and each block is banded after a reverse
Cuthill–McKee ordering computed once from the pattern (bandwidth 3–7 for the lane-change
QP at any ``N``; the largest is :attr:`KKTBackend.bandwidth`).  With the border rows
:math:`C = [A_1\ 0]`,

.. math::

    K_0 w_0 = r_0,\quad K_0 W = C^\top,\quad S = C W,\quad
    S\,y_1 = C w_0 - b_1,\quad w = w_0 - W y_1 ,

a Schur complement of size (number of border rows).

What is computed when (a sweep: one grid, many candidates):

* **symbolic** (set-up, once): the components, their RCM orders, where every stored value
  of ``P`` and ``A`` goes in the band storage, and which blocks have the same pattern;
* **numeric factorisation** (only when ``P`` or the core of ``A`` changes — a new grid):
  LAPACK's banded LU (``dgbtrf``, partial pivoting) of each block; blocks whose banded
  values are identical (the two axes: same steps, same dynamics) share **one**
  factorisation (:attr:`KKTBackend.factorisations` counts the calls, :attr:`KKTBackend.blocks`
  the distinct factors of the last one);
* **per candidate**: only the border values and ``b`` change, so :math:`w_0` is re-used
  (same right-hand side) and :math:`W` is gathered from the columns :math:`K_0^{-1}e_c` of
  the border pattern.  The first candidate on a factorisation solves for the columns it
  needs; the second computes every column of the border pattern in one multi-right-hand-side
  ``dgbtrs`` per distinct factor (each column only on its own block, and once for identical
  blocks), so the rest of the sweep does no triangular solve at all: a gather, a Schur
  complement of size (#border rows) — diagonal when the border rows touch different blocks
  (then divided, not factorised) — and one ``w_0 − W y_1``;
* **a family of candidates** (:meth:`KKTBackend.solve_family`, what a sweep uses): the same
  per-candidate formulas for many candidates at once, as array operations over the
  candidates (a batched Schur complement, one gathered update of ``w_0`` per border row).

Optionally (setting ``refine_above``, relative; default ``None`` = off) one step of
iterative refinement on the full system follows when the recomputed residual exceeds it.
Off by default because it is not needed: the recomputed relative KKT residuals of the
unrefined solutions of the lane-change QP are ~1e-14 (tests assert < 1e-12), and the caller
(:class:`~iamp.planners.qp.core.DiscretisedQP`) verifies every solution anyway.

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

from iamp.core import status as st

from .base import FloatArray, IntArray, QPBackend, QPSolution
from .kkt_symbolic import analyse


class KKTBackend(QPBackend):
    """Direct banded solve of the equality QP's KKT system (module docstring)."""

    name: ClassVar[str] = "kkt"
    distribution: ClassVar[str] = ""  # numpy/scipy only
    supports_inequalities: ClassVar[bool] = False
    tolerance_key: ClassVar[str] = "cmp_kkt_rel_clarabel"

    @classmethod
    def default_settings(cls) -> dict[str, Any]:
        return {"border_row_nnz": 8, "refine_above": None}

    # --- symbolic analysis (once per pattern: iamp.planners.qp.backends.kkt_symbolic) -------
    def _setup(self) -> None:
        s = analyse(self.P, self.A, int(self.settings["border_row_nnz"]))  # cached per pattern
        self.structure = s
        self._nk = s.nk
        self._border = s.border
        self._core = s.core
        self._a_core_pos = s.a_core_pos
        self._a_in_core = s.a_in_core
        self._perm = s.perm
        self._inv = s.inv
        self._starts = s.starts
        self._comp_of_perm = s.comp_of_perm
        self._ab_shape = s.ab_shape
        self._p_pos = s.p_pos
        self._p_off = s.p_off
        self._p_pos_mirror = s.p_pos_mirror
        self._a_pos = s.a_pos
        self._a_pos_t = s.a_pos_t
        self._twin_of = s.twin_of
        self._b_pos = s.b_pos
        self._b_row = s.b_row
        self._b_range = s.b_range
        self._b_pc = s.b_pc
        self._u_comp = s.u_comp
        self._u_loc = s.u_loc
        self._b_info = s.b_info
        self._block_max = s.block_max
        self.bandwidth = s.bandwidth
        self._kl = self._ku = s.bandwidth
        self._factor: list[tuple[int, FloatArray, IntArray]] | None = None
        self._info = 0
        self.factorisations = 0  # numeric factorisations so far (one per grid)
        self.blocks = 0  # distinct banded factors of the last factorisation
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
        st_ = self._starts
        # factor of each block: its own, or its twin's when the banded values are identical
        self._factor_of: list[int] = []
        factors: list[tuple[int, FloatArray, IntArray]] = []
        info = 0
        for c, twin in enumerate(self._twin_of):
            blk = ab[:, st_[c]:st_[c + 1]]
            if twin != c and np.array_equal(ab[:, st_[twin]:st_[twin + 1]], blk):
                self._factor_of.append(self._factor_of[twin])
                continue
            lu, piv, inf = lapack.dgbtrf(np.asfortranarray(blk), self._kl, self._ku, overwrite_ab=True)
            info = info or int(inf)
            self._factor_of.append(len(factors))
            factors.append((c, lu, piv))
        self.factorisations += 1
        self.blocks = len(factors)
        self._factor = factors
        self._info = info
        self._uses = 0
        # the distinct block solves K_b⁻¹ e_i the border needs: one per (factor, local row)
        key = np.asarray(self._factor_of, dtype=np.int64)[self._u_comp] * self._nk + self._u_loc
        self._keys, self._u_key = np.unique(key, return_inverse=True)
        self._u_key = np.asarray(self._u_key, dtype=np.int64).reshape(-1)
        self._col_all: FloatArray | None = None  # every border column, once computed
        self._w0: tuple[FloatArray, FloatArray] | None = None

    def _push(self, P: bool, A: bool, A_idx: IntArray | None, q: bool, bounds: bool) -> None:
        if P:
            self._factor = None
            self._P_full = None
        if A:
            if A_idx is None:
                self._factor = None
            elif A_idx.size and bool(self._a_in_core[A_idx].any()):
                self._factor = None

    def _block_solve(self, f: int, rhs: FloatArray) -> FloatArray:
        """``K_b⁻¹ rhs`` for the block(s) of factor ``f`` (local, permuted coordinates)."""
        assert self._factor is not None
        _, lu, piv = self._factor[f]
        x, info = lapack.dgbtrs(lu, self._kl, self._ku, rhs, piv, overwrite_b=True)
        if info != 0:  # pragma: no cover - only for malformed input
            raise ValueError("dgbtrs failed")
        return np.asarray(x)

    def _k0_solve(self, rhs_perm: FloatArray) -> FloatArray:
        """``K0⁻¹ r`` for one right-hand side given in permuted order (result permuted).

        Blocks sharing a factor are solved together, as columns of one ``dgbtrs`` call."""
        st_ = self._starts
        out = np.empty(self._nk)
        groups: dict[int, list[int]] = {}
        for c, f in enumerate(self._factor_of):
            groups.setdefault(f, []).append(c)
        for f, comps in groups.items():
            R = np.empty((st_[comps[0] + 1] - st_[comps[0]], len(comps)), order="F")
            for j, c in enumerate(comps):
                R[:, j] = rhs_perm[st_[c]:st_[c + 1]]
            X = self._block_solve(f, R)
            for j, c in enumerate(comps):
                out[st_[c]:st_[c + 1]] = X[:, j]
        return out

    def _unit_columns(self, keys: IntArray) -> FloatArray:
        """``K_b⁻¹ e_i`` for the keys ``factor·nk + i`` (``i`` a local permuted row), as the
        columns of one zero-padded ``(largest block, len(keys))`` array."""
        out = np.zeros((self._block_max, keys.size))
        fac, row = np.divmod(keys, self._nk)
        assert self._factor is not None
        for f in np.unique(fac):
            sel = np.flatnonzero(fac == f)
            c = self._factor[int(f)][0]
            size = int(self._starts[c + 1] - self._starts[c])
            E = np.zeros((size, sel.size), order="F")
            E[row[sel], np.arange(sel.size)] = 1.0
            out[:size, sel] = self._block_solve(int(f), E)
        return out

    def _full_columns(self, u: IntArray) -> FloatArray:
        """``(K0⁻¹ e_c)ᵀ`` (rows; permuted coordinates, ``(len(u), nk)``) for the distinct
        border columns ``u``: each solved on its own block only, once per distinct
        (factor, row)."""
        needed, j = np.unique(self._u_key[u], return_inverse=True)
        j = np.asarray(j, dtype=np.int64).reshape(-1)
        X = self._unit_columns(self._keys[needed])
        out = np.zeros((u.size, self._nk))
        comp = self._u_comp[u]
        st_ = self._starts
        for c in np.unique(comp):
            sel = np.flatnonzero(comp == c)
            s0, s1 = st_[c], st_[c + 1]
            out[sel, s0:s1] = X[:s1 - s0, j[sel]].T
        return out

    def _columns(self, ucols: IntArray) -> FloatArray:
        """``(K0⁻¹ e_c)ᵀ`` (rows, permuted coordinates) for the distinct border columns
        ``ucols``.

        The first solve on a factorisation computes only the columns it needs; the second
        one (a sweep: the same grid, another candidate) computes every column of the border
        rows' pattern (one multi-right-hand-side solve per distinct factor, on its block
        only), so the rest of the sweep only gathers (contiguous) rows.
        """
        self._uses += 1
        if self._col_all is None and self._uses >= 2:
            self._col_all = self._full_columns(np.arange(self._u_key.size))
        if self._col_all is not None:
            return np.asarray(self._col_all[ucols])
        return self._full_columns(ucols)

    def _core_solve(self, r0_perm: FloatArray) -> FloatArray:
        """``K0⁻¹ r0`` (permuted), remembered for a repeated right-hand side (the candidates
        of a sweep share it: only the border rows' values and right-hand sides change)."""
        if self._w0 is not None and np.array_equal(self._w0[0], r0_perm):
            return self._w0[1]
        w0 = self._k0_solve(r0_perm)
        self._w0 = (r0_perm.copy(), w0)
        return w0

    def _full_solve(self, rhs_z: FloatArray, b: FloatArray, cache: bool = True) -> tuple[FloatArray, FloatArray]:
        n, nb = self.q.size, self._border.size
        r0 = np.concatenate([rhs_z, b[self._core]])[self._perm]
        w0 = self._core_solve(r0) if cache else self._k0_solve(r0)
        if nb == 0:
            w, y1 = w0, np.zeros(0)
        else:
            vals = self.A.data[self._b_pos]
            ent = np.flatnonzero(vals)
            if ent.size == nb:  # the selector case: one entry per border row?
                ent = ent[np.argsort(self._b_row[ent])]
            rows, pc, uc = self._b_info[:, ent]
            v = vals[ent]
            # Wᵀ = (K0⁻¹ Cᵀ)ᵀ: row r = Σ_k v_k (K0⁻¹ e_{c_k})ᵀ over border row r's entries
            Wc = self._columns(uc) * v[:, None]
            if ent.size == nb and bool((rows == self._b_range).all()):
                WT = Wc  # one entry per border row: C = diag(v) E_colsᵀ
                S = v[:, None] * WT[:, pc].T
                Cw0 = v * w0[pc]
            else:
                WT = np.zeros((nb, self._nk))
                np.add.at(WT, rows, Wc)
                S = np.zeros((nb, nb))
                np.add.at(S, rows, v[:, None] * WT[:, pc].T)  # S = C W
                Cw0 = np.bincount(rows, weights=v * w0[pc], minlength=nb)
            rhs = Cw0 - b[self._border]
            d = S.diagonal()
            if np.count_nonzero(S) == np.count_nonzero(d):
                y1 = rhs / d  # S is diagonal (the border rows touch different blocks)
            else:
                y1 = np.linalg.solve(S, rhs)
            w = w0 - y1 @ WT
        w = w[self._inv]
        y = np.empty(self.l.size)
        y[self._core] = w[n:]
        y[self._border] = y1
        return w[:n], y

    def solve_family(self, ent: IntArray, vals: FloatArray, b_border: FloatArray
                     ) -> tuple[FloatArray, FloatArray] | None:
        r"""Solve a family of candidates that differ from the current data only in the border.

        Candidate ``j`` has in border row ``r`` the single entry ``ent[j, r]`` (an index into
        the border pattern, :attr:`KKTStructure.b_row` order) with value ``vals[j, r]`` and the
        right-hand side ``b_border[j, r]``; everything else is the current ``P, q, A, b``.
        Uses the current factorisation and the column block (computed here if needed): per
        candidate the formulas of a single solve, for all candidates at once,

        .. math::  S_j = V_j E_j^\top K_0^{-1} E_j V_j, \quad
                   S_j y_{1j} = V_j E_j^\top w_0 - b_{1j}, \quad
                   w_j = w_0 - K_0^{-1} E_j V_j y_{1j} .

        Returns ``(Z, Y)`` (one row per candidate) or ``None`` when it does not apply (no
        regular factorisation, no border, a singular Schur complement or a non-finite result):
        then solve them one by one.
        """
        nb = self._border.size
        if nb == 0 or ent.shape[1] != nb:
            return None
        if self._factor is None:
            self._factorise()
        if self._info != 0:
            return None
        if self._col_all is None:
            self._uses = max(self._uses, 1)
            self._col_all = self._full_columns(np.arange(self._u_key.size))
        r0 = np.concatenate([-self.q, self.l[self._core]])[self._perm]
        w0 = self._core_solve(r0)
        C, pc, uc = self._col_all, self._b_pc[ent], self._b_info[2][ent]
        S = C[uc[:, None, :], pc[:, :, None]] * vals[:, :, None] * vals[:, None, :]
        rhs = vals * w0[pc] - b_border
        diag = np.diagonal(S, axis1=1, axis2=2)
        with np.errstate(divide="ignore", invalid="ignore"):
            if np.count_nonzero(S) == np.count_nonzero(diag):
                y1 = rhs / diag  # the border rows touch different blocks: S_j diagonal
            else:
                try:
                    y1 = np.linalg.solve(S, rhs[..., None])[..., 0]
                except np.linalg.LinAlgError:
                    return None
        coef = y1 * vals
        W = np.broadcast_to(w0, (ent.shape[0], w0.size)).copy()
        for r in range(nb):
            W -= coef[:, r, None] * C[uc[:, r]]
        if not (np.isfinite(W).all() and np.isfinite(y1).all()):
            return None
        W = W[:, self._inv]
        n = self.q.size
        Y = np.empty((ent.shape[0], self.l.size))
        Y[:, self._core] = W[:, n:]
        Y[:, self._border] = y1
        return np.ascontiguousarray(W[:, :n]), Y

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

    def _refine(self, z: FloatArray, y: FloatArray, threshold: float) -> tuple[FloatArray, FloatArray, int]:
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
