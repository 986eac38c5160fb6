r"""PIQP (proximal interior point; sparse LDLᵀ of the regularised KKT system; no warm start).

PIQP's form is ``min ½xᵀPx + cᵀx`` s.t. ``Ax = b``, ``h_l ≤ Gx ≤ h_u``: the rows with
``l = u`` go to ``(A, b)``, the others to ``(G, h_l, h_u)``; the split is fixed at set-up (a
change of which rows are equalities rebuilds the solver).  ``P`` is passed as its upper
triangle (PIQP reads the upper triangle).  Updates go through ``SparseSolver.update``
with matrices of the set-up pattern, so PIQP keeps its symbolic factorisation.  The
multipliers are mapped back to OSQP's convention: ``y`` for equality rows, ``z_u − z_l``
for the others (stationarity ``Px + c + Aᵀy + Gᵀ(z_u − z_l) = 0``).

Settings (:func:`default`): ``eps_abs = 1e-10``, ``eps_rel = 0`` (PIQP's defaults are
1e-8 / 1e-9), ``compute_timings = True`` so the solver's own time is reported.

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
from iamp.planners.backends.base import IntArray, QPBackend, QPSolution

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


class PIQPBackend(QPBackend):
    """PIQP behind :class:`~iamp.planners.backends.base.QPBackend`."""

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
        Aeq = sp.csc_matrix(self.A[self._eq])
        G = sp.csc_matrix(self.A[self._ineq])
        return Aeq, self.l[self._eq].copy(), G, self.l[self._ineq].copy(), self.u[self._ineq].copy()

    def _build(self) -> None:
        import piqp

        eq = self.l == self.u
        self._eq, self._ineq = np.flatnonzero(eq), np.flatnonzero(~eq)
        self.solver = piqp.SparseSolver()
        for k, v in self.settings.items():
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
