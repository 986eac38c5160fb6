r"""PIQP (proximal interior point; sparse LDLᵀ of the regularised KKT system; no warm start).

PIQP's form is ``min ½xᵀPx + cᵀx`` s.t. ``Ax = b``, ``h_l ≤ Gx ≤ h_u``: the rows with
``l = u`` go to ``(A, b)``, the others to ``(G, h_l, h_u)``; the split is fixed at set-up (a
change of which rows are equalities rebuilds the solver).  ``P`` is passed as its upper
triangle (PIQP reads the upper triangle).  Updates go through ``SparseSolver.update``
with matrices of the set-up pattern, so PIQP keeps its symbolic factorisation.  The
multipliers are mapped back to OSQP's convention: ``y`` for equality rows, ``z_u − z_l``
for the others (stationarity ``Px + c + Aᵀy + Gᵀ(z_u − z_l) = 0``).

Settings (:func:`default`): ``eps_abs = 1e-10``, ``eps_rel = 0`` (PIQP's defaults are
1e-8 / 1e-9), ``compute_timings = True`` so the solver's own time is reported.  When every
row is an equality (the QP of SPEC §3) :func:`equality_settings` are added unless given
explicitly: ``rho_init = delta_init = 1e-10`` (PIQP's ``reg_lower_limit``; its defaults are
1e-6 and 1e-4) and ``eps_abs = 1e-11``.  With no inequality there is no barrier to follow:
the only reason PIQP iterates is its proximal regularisation, and started at the lower limit
the first (regularised) Newton step is already the solution of the KKT system up to
~1e-10 relative, so one iteration is enough.

Measured on ``paper-1-poly``, FOH, ``N = 100``, all 99 candidates of a sweep per row, KKT
residuals recomputed (tolerance ``cmp_kkt_rel_clarabel`` = 1e-9), PIQP 0.7.0; times are
medians of update + solve per candidate on the shared, loaded 2-core machine, all rows in
one run (compare rows, not absolute values; ``tests/test_qp_speed_paths.py`` asserts that the
default verifies and equals the exact answer on random problems):

==========================================================  ========  ==========  =========  ========
settings (besides eps_abs 1e-10, eps_rel 0)                 verified  iterations  max KKT    time
==========================================================  ========  ==========  =========  ========
PIQP defaults (rho_init 1e-6, delta_init 1e-4): before      99        3 (≤ 6)     5.6e-10    310 µs
``eps_abs`` 1e-8 or 1e-9 (defaults otherwise)               99        3 (≤ 6)     6.8e-10    same
``delta_init`` 1e-7                                         99        2 (≤ 3)     1.1e-11    265 µs
``rho_init`` 1e-9, ``delta_init`` 1e-7                      99        1 (≤ 3)     5.0e-10    168 µs
``rho_init = delta_init`` 1e-10                             99        1 (≤ 2)     1.7e-12    164 µs
… and ``eps_abs`` 1e-11 (**the default here**)              99        1 (≤ 3)     1.6e-12    165 µs
… and ``preconditioner_iter`` 0                             99        1           1.7e-12    151 µs
… and ``iterative_refinement_always_enabled``               99        1 (≤ 2)     1.8e-12    191 µs
… and ``kkt_solver`` ``sparse_ldlt_ineq_cond``              99        1           1.7e-12    180 µs
``kkt_solver`` ``sparse_ldlt_eq_cond`` / ``sparse_ldlt_cond``  99     3           5.6e-10    1.5 ms
``kkt_solver`` ``sparse_multistage``                        99        3           5.6e-10    3.5 ms
==========================================================  ========  ==========  =========  ========

``eps_abs = 1e-11`` is kept because at 1e-10 one of 600 random candidates (``random_problem``,
FOH/ZOH, ``N`` 10–100, one or two vehicles, on- and off-grid) stopped after one step with a
duality-gap residual of 1.9e-9 (INACCURATE); with 1e-11 all 600 verify (worst 4.3e-11).
``preconditioner_iter = 0`` (no Ruiz scaling) gains ~10 µs, within the noise, and is not
worth the robustness on badly scaled data.  The condensed KKT solvers refactorise a denser
matrix (the selector rows' patterns hold every interior node); ``sparse_multistage`` does
not recognise stages in this variable order (axis-major).  Re-setting up instead of
updating costs ~300 µs (the symbolic analysis again).  Where the remaining time goes: the
value update (~30 µs: ``A`` and ``b``, the preconditioner recomputed) and one sparse LDLᵀ
of the ~1000 × 1000 KKT matrix with its triangular solves (~130 µs).

Status mapping: ``PIQP_SOLVED`` → OPTIMAL; ``PIQP_MAX_ITER_REACHED`` → MAX_ITER;
``PIQP_PRIMAL_INFEASIBLE`` → INFEASIBLE; ``PIQP_NUMERICS`` → NUMERICAL_ERROR; anything else
→ SOLVER_ERROR.
"""

from __future__ import annotations

import time
from typing import Any, ClassVar

import numpy as np
import scipy.sparse as sp

from iamp.core import status as st

from .base import IntArray, QPBackend, QPSolution, csc_rows

PIQP_STATUS: dict[str, str] = {
    "PIQP_SOLVED": st.OPTIMAL,
    "PIQP_MAX_ITER_REACHED": st.MAX_ITER,
    "PIQP_PRIMAL_INFEASIBLE": st.INFEASIBLE,
    "PIQP_DUAL_INFEASIBLE": st.SOLVER_ERROR,
    "PIQP_NUMERICS": st.NUMERICAL_ERROR,
    "PIQP_UNSOLVED": st.SOLVER_ERROR,
    "PIQP_INVALID_SETTINGS": st.SOLVER_ERROR,
}


def map_status(raw: str) -> str:
    """PIQP's status name (``Status.PIQP_SOLVED`` or ``PIQP_SOLVED``) → the iamp vocabulary."""
    return PIQP_STATUS.get(raw.strip().split(".")[-1], st.SOLVER_ERROR)


def default() -> dict[str, Any]:
    """PIQP settings used by iamp (module docstring)."""
    return {"eps_abs": 1e-10, "eps_rel": 0.0, "compute_timings": True, "verbose": False}


def equality_settings() -> dict[str, Any]:
    """Added to :func:`default` when every row is an equality (module docstring): start the
    proximal regularisations at PIQP's lower limit, so the first Newton step is the exact
    one."""
    return {"rho_init": 1e-10, "delta_init": 1e-10, "eps_abs": 1e-11}


class PIQPBackend(QPBackend):
    """PIQP behind :class:`~iamp.planners.qp.backends.base.QPBackend`."""

    name: ClassVar[str] = "piqp"
    distribution: ClassVar[str] = "piqp"
    tolerance_key: ClassVar[str] = "cmp_kkt_rel_clarabel"

    @classmethod
    def default_settings(cls) -> dict[str, Any]:
        return default()

    def _parts(self) -> tuple[sp.csc_matrix, np.ndarray, sp.csc_matrix | None, np.ndarray | None,
                              np.ndarray | None]:
        if self._ineq.size == 0:
            return self.A, self.l.copy(), None, None, None
        # the split's matrices keep their pattern: a value update copies the entries of each part
        # (in CSC order a subset of rows keeps the order of ``A.data``) instead of slicing ``A`` again
        self._Aeq.data[:] = self.A.data[self._eq_entries]
        self._G.data[:] = self.A.data[~self._eq_entries]
        return self._Aeq, self.l[self._eq].copy(), self._G, self.l[self._ineq].copy(), self.u[self._ineq].copy()

    def _build(self) -> None:
        import piqp

        eq = self.l == self.u
        self._eq, self._ineq = np.flatnonzero(eq), np.flatnonzero(~eq)
        if self._ineq.size:
            self._Aeq = csc_rows(self.A, self._eq)  # the arrays of sp.csc_matrix(self.A[self._eq])
            self._G = csc_rows(self.A, self._ineq)
            self._eq_entries = eq[self.A.indices]
            if self._Aeq.nnz + self._G.nnz != self.A.nnz:  # pragma: no cover - row slicing keeps every entry
                raise AssertionError("the row split lost entries of A")
        self.solver = piqp.SparseSolver()
        settings = self._apply_settings(self._ineq.size == 0, equality_settings())  # the one-step settings
        for k, v in settings.items():
            if k == "kkt_solver" and isinstance(v, str):
                v = getattr(piqp.KKTSolver, v)  # by name, e.g. "sparse_ldlt"
            setattr(self.solver.settings, k, v)
        A, b, G, hl, hu = self._parts()
        self.solver.setup(self.P, self.q, A, b, G, hl, hu)

    def _setup(self) -> None:
        self._build()

    def _push(self, P: bool, A: bool, A_idx: IntArray | None, q: bool, bounds: bool) -> None:
        if bounds and not np.array_equal(np.flatnonzero(self.l == self.u), self._eq):
            self._build()
            return
        kw: dict[str, Any] = {}
        if P:
            kw["P"] = self.P
        if A or bounds:
            Aeq, b, G, hl, hu = self._parts()
            if A:
                kw["A"] = Aeq
                if G is not None:
                    kw["G"] = G
            if bounds:
                kw["b"] = b
                if G is not None:
                    kw["h_l"], kw["h_u"] = hl, hu
        if q:
            kw["c"] = self.q.copy()
        if kw:
            self.solver.update(**kw)

    def solve(self) -> QPSolution:
        t0 = time.perf_counter()
        status = self.solver.solve()
        call = time.perf_counter() - t0
        res = self.solver.result
        raw = str(status)
        z = np.array(res.x, dtype=float)
        y = np.zeros(self.l.size)
        y[self._eq] = np.asarray(res.y, dtype=float)
        if self._ineq.size:
            y[self._ineq] = np.asarray(res.z_u, dtype=float) - np.asarray(res.z_l, dtype=float)
        return QPSolution(z=z, y=y, status=map_status(raw), raw_status=raw.split(".")[-1],
                          iterations=int(res.info.iter), solver_time_s=float(res.info.run_time),
                          solve_call_s=call)
