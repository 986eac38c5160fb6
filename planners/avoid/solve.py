r"""The avoidance QP's solver adapter: OSQP or Clarabel, set up once, then bound updates only.

The problem is :math:`\min \tfrac12 z^\top P z` s.t. equality rows :math:`A_{eq} z = b` and
one-sided rows :math:`A_{in} z \le u` (:mod:`iamp.planners.avoid.data`); a sweep candidate
changes ``u`` only.  Multipliers follow OSQP's convention (:math:`Pz + q + A^\top y = 0`,
``y >= 0`` on a binding upper bound), which is also Clarabel's for the stacked cones
``Zero(n_eq) × Nonnegative(n_in)`` on :math:`Az + s = (b, u)`, so ``y`` is Clarabel's dual
vector unchanged.

* OSQP: ``update(u=…)`` and a warm start from the previous candidate; settings
  ``eps_abs = 1e-7, eps_rel = 0``, polishing on (the polish solves the KKT system of the
  guessed active set exactly; without it OSQP is accurate to ``eps_abs`` only and the plan's
  KKT check reports it ``inaccurate``).
* Clarabel: ``update(b=…)`` on the set-up solver (its data-update API; no warm start),
  tolerances 1e-12.

Every other backend comes from the project's QP backend registry
(:mod:`iamp.planners.qp.backends`; e.g. PIQP) through its general form ``l <= Az <= u`` with
``update(u=…)``; a backend that solves equality-constrained QPs only (``kkt``) is refused with
:class:`~iamp.core.errors.OptionError`.  OSQP and Clarabel keep the specialised adapters above
because a bound update must not rebuild the stacked Clarabel matrix (measured: the generic
update re-stacks ``A`` on every candidate).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from functools import cache, lru_cache
from importlib import metadata
from typing import Any

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from iamp.core import status as st
from iamp.core.errors import MissingDependencyError

from ..qp.backends import QPBackend, get_backend
from .options import check_avoid_solver

FloatArray = NDArray[np.float64]

OSQP_STATUS = {"solved": st.OPTIMAL, "solved inaccurate": st.INACCURATE, "maximum iterations reached": st.MAX_ITER,
               "run time limit reached": st.TIME_LIMIT, "primal infeasible": st.INFEASIBLE,
               "primal infeasible inaccurate": st.INFEASIBLE}
CLARABEL_STATUS = {"Solved": st.OPTIMAL, "AlmostSolved": st.INACCURATE, "PrimalInfeasible": st.INFEASIBLE,
                   "AlmostPrimalInfeasible": st.INFEASIBLE, "MaxIterations": st.MAX_ITER, "MaxTime": st.TIME_LIMIT,
                   "NumericalError": st.NUMERICAL_ERROR, "InsufficientProgress": st.NUMERICAL_ERROR}


@cache
def _require(dist: str) -> None:
    try:
        metadata.version(dist)
    except metadata.PackageNotFoundError:
        raise MissingDependencyError(f"solver {dist!r} needs the package {dist!r}: pip install {dist}") from None


@lru_cache(maxsize=1)
def _osqp_major() -> int:
    return int((metadata.version("osqp") or "1").split(".")[0])


def osqp_settings() -> dict[str, Any]:
    """OSQP for the avoidance QP (module docstring)."""
    major = _osqp_major()
    polish = "polishing" if major >= 1 else "polish"
    out: dict[str, Any] = {"eps_abs": 1e-7, "eps_rel": 0.0, polish: True, "polish_refine_iter": 10,
                           "max_iter": 50_000, "verbose": False}
    if major >= 1:
        out["check_dualgap"] = False
    return out


def clarabel_settings() -> dict[str, Any]:
    """Clarabel: gap and feasibility tolerances 1e-12."""
    return {"tol_gap_abs": 1e-12, "tol_gap_rel": 1e-12, "tol_feas": 1e-12, "tol_ktratio": 1e-10,
            "max_iter": 200, "verbose": False}


@dataclass(frozen=True)
class Solution:
    z: FloatArray
    y: FloatArray
    status: str
    raw_status: str
    iterations: int
    solve_call_s: float
    polished: bool | None = None

    @property
    def finite(self) -> bool:
        return bool(np.isfinite(self.z).all() and np.isfinite(self.y).all())


class BoundSolver:
    """One set-up solver for ``½zᵀPz`` s.t. ``A[:n_eq] z = b``, ``A[n_eq:] z <= u[n_eq:]``.

    Parameters
    ----------
    name : str
        A registered QP backend that accepts inequalities (osqp and clarabel: specialised
        adapters; others, e.g. piqp: the registry's general form).
    P : sparse
        Upper triangle of the cost Hessian.
    A : sparse
    b_eq : ndarray, shape (n_eq,)
    u_in : ndarray
        Initial upper bounds of the inequality rows.
    settings : dict, optional
        Overrides of the solver's settings.
    """

    def __init__(self, name: str, P: sp.spmatrix, A: sp.spmatrix, b_eq: FloatArray, u_in: FloatArray,
                 settings: dict[str, Any] | None = None) -> None:
        check_avoid_solver(name)
        self.name = name
        self.n_eq = b_eq.size
        self.b_eq = np.asarray(b_eq, dtype=float)
        P = sp.csc_matrix(P)
        A = sp.csc_matrix(A)
        n = P.shape[0]
        self._generic: QPBackend | None = None
        if name not in ("osqp", "clarabel"):  # any other registered backend, in the general form
            cls = get_backend(name)
            l = np.r_[self.b_eq, np.full(u_in.size, -np.inf)]
            self._generic = cls(P, np.zeros(n), A, l, np.r_[self.b_eq, u_in], settings)
            self.settings = dict(self._generic.settings)
            return
        _require(name)
        if name == "osqp":
            import osqp

            self.settings = {**osqp_settings(), **(settings or {})}
            self._s = osqp.OSQP()
            l = np.r_[self.b_eq, np.full(u_in.size, -np.inf)]
            self._s.setup(P, np.zeros(n), A, l, np.r_[self.b_eq, u_in], **self.settings)
        else:
            import clarabel

            self.settings = {**clarabel_settings(), **(settings or {})}
            cs = clarabel.DefaultSettings()
            for k, v in self.settings.items():
                setattr(cs, k, v)
            cones = [clarabel.ZeroConeT(int(self.n_eq)), clarabel.NonnegativeConeT(int(u_in.size))]
            self._s = clarabel.DefaultSolver(P, np.zeros(n), A, np.r_[self.b_eq, u_in], cones, cs)
            self._update_ok = bool(self._s.is_data_update_allowed())
            self._rebuild = (P, A, cones, cs)

    def set_upper(self, u_in: FloatArray) -> None:
        """New upper bounds of the inequality rows."""
        if self._generic is not None:
            self._generic.update(u=np.r_[self.b_eq, u_in])
        elif self.name == "osqp":
            self._s.update(u=np.r_[self.b_eq, u_in])
        elif self._update_ok:
            self._s.update(b=np.r_[self.b_eq, u_in])
        else:  # pragma: no cover - a Clarabel without data updates
            import clarabel

            P, A, cones, cs = self._rebuild
            self._s = clarabel.DefaultSolver(P, np.zeros(P.shape[0]), A, np.r_[self.b_eq, u_in], cones, cs)

    def set_values(self, A: sp.spmatrix, u_in: FloatArray) -> None:
        """New values of ``A`` on the pattern it was set up with, and new upper bounds."""
        A = sp.csc_matrix(A)
        u = np.r_[self.b_eq, u_in]
        if self._generic is not None:
            self._generic.update(Ax=np.array(A.data, dtype=float), u=u)
        elif self.name == "osqp":
            self._s.update(Ax=np.array(A.data, dtype=float), u=u)
        else:
            import clarabel

            P, _, cones, cs = self._rebuild
            self._s = clarabel.DefaultSolver(P, np.zeros(P.shape[0]), A, u, cones, cs)
            self._rebuild = (P, A, cones, cs)

    def warm_start(self, z: FloatArray, y: FloatArray) -> None:
        """OSQP (and any registry backend that warm-starts); Clarabel, an interior-point method, has none."""
        if self._generic is not None:
            if np.all(np.isfinite(z)) and np.all(np.isfinite(y)):
                self._generic.warm_start(z, y)
        elif self.name == "osqp" and np.all(np.isfinite(z)) and np.all(np.isfinite(y)):
            self._s.warm_start(x=z, y=y)

    def solve(self) -> Solution:
        if self._generic is not None:
            g = self._generic.solve()
            return Solution(g.z, g.y, g.status, g.raw_status, g.iterations, g.solve_call_s, g.polished)
        t0 = time.perf_counter()
        if self.name == "osqp":
            res = self._s.solve(raise_error=False)
            call = time.perf_counter() - t0
            raw = str(res.info.status)
            n = self._s_n()
            z = np.array(res.x, dtype=float) if res.x is not None else np.full(n, np.nan)
            y = np.array(res.y, dtype=float) if res.y is not None else np.full(self.n_eq, np.nan)
            return Solution(z, y, OSQP_STATUS.get(raw.strip().lower(), st.SOLVER_ERROR), raw, int(res.info.iter), call,
                            int(getattr(res.info, "status_polish", 0)) == 1)
        sol = self._s.solve()
        call = time.perf_counter() - t0
        raw = str(sol.status)
        return Solution(np.array(sol.x, dtype=float), np.array(sol.z, dtype=float),
                        CLARABEL_STATUS.get(raw, st.SOLVER_ERROR), raw, int(sol.iterations), call)

    def _s_n(self) -> int:
        dims = self._s.get_dimensions() if hasattr(self._s, "get_dimensions") else None
        return int(dims[0]) if dims else 0
