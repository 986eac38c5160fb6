r"""OSQP (ADMM with an LDLᵀ of the quasi-definite KKT matrix; first order, warm-startable).

Set up once; :meth:`update` sends only the changed values (``Ax``/``Ax_idx``, ``l``, ``u``)
so OSQP refactorises numerically on the same symbolic structure, and every solve is
warm-started from the previous solution when :meth:`warm_start` is called.

Settings for the equality-only QP of SPEC §3 (:func:`equality_settings`, the default).
Measured on ``paper-1-poly``, FOH, ``N = 100``, one warm-started sweep over all 99 candidates
per row, KKT residuals recomputed (``iamp bench`` prints this table as "OSQP settings";
OSQP 1.1.3; counts are deterministic, times were taken on a loaded 2-core machine):

=====================================  ========  ========  ==========  ============
setting                                verified  polished  iterations  max KKT rel
=====================================  ========  ========  ==========  ============
eps_abs 1e-3 … 1e-5, refine_iter 10    99        99        50 (≤ 75)   1.9e-13
eps_abs 1e-3 … 1e-5, refine_iter 3     99        97        50          6.9e-08
eps_abs 1e-3 … 1e-5, refine_iter 1     76        76        50          5.0e-07
eps_abs 1e-5, polishing off            2         0         50          7.2e-07
eps_abs 1e-6, refine_iter 10           98        99        50 (10000)  4.9e-07
eps_abs 1e-7, polishing off            89        0         50 (10000)  3.4e-07
=====================================  ========  ========  ==========  ============

(verified: the recomputed relative KKT residuals are within ``cmp_kkt_rel_osqp`` = 1e-7.)
What each setting buys:

* ``polishing = True`` does the accuracy: with only equality rows every row is "active",
  so a successful polish solves the reduced KKT system directly and the solution is exact
  to ~1e-13 whatever ADMM's ``eps_abs`` was; ADMM only has to get close enough for the
  polish to succeed.  ``polish_refine_iter = 10`` is needed for that: 3 leaves residuals up
  to 7e-8, 1 fails the check on a quarter of the candidates.
* ``eps_abs`` between 1e-3 and 1e-5 costs the same: OSQP checks termination every 25
  iterations and stops at 50 either way; 1e-5 is kept.  Tighter is worse: at 1e-6 one
  candidate, at 1e-7 nine, run to ``max_iter`` (ADMM stalls; 1e-7 without polishing takes
  ~2.8 s per sweep and still fails ten candidates).  ``eps_rel = 0`` and, in OSQP 1.x,
  ``check_dualgap = False`` (the gap criterion cannot be met with ``eps_rel = 0`` on the
  expensive candidates).
* Per candidate, OSQP costs about 1 ms at ``N = 100``: the value update refactorises the KKT
  matrix (~0.2 ms), 50 ADMM iterations (~0.55 ms) and the polish (~0.45 ms) — the 0.5 ms
  target is out of reach without giving up the exact polish.
* An unpolished solution is accurate only to about ``eps_abs``: it fails the KKT check and
  is reported INACCURATE, not optimal.

Status mapping (OSQP word → :mod:`iamp.core.status`): ``solved`` → OPTIMAL;
``solved inaccurate`` → INACCURATE; ``maximum iterations reached`` → MAX_ITER;
``run time limit reached`` → TIME_LIMIT; ``primal infeasible (inaccurate)`` → INFEASIBLE;
``non convex`` / ``dual infeasible`` / anything else → SOLVER_ERROR.
"""

from __future__ import annotations

import time
from typing import Any, ClassVar

import numpy as np

from iamp.core import status as st
from iamp.planners.backends.base import IntArray, QPBackend, QPSolution, dist_version

OSQP_STATUS: dict[str, str] = {
    "solved": st.OPTIMAL,
    "solved inaccurate": st.INACCURATE,
    "maximum iterations reached": st.MAX_ITER,
    "run time limit reached": st.TIME_LIMIT,
    "primal infeasible": st.INFEASIBLE,
    "primal infeasible inaccurate": st.INFEASIBLE,
    "dual infeasible": st.SOLVER_ERROR,
    "dual infeasible inaccurate": st.SOLVER_ERROR,
    "problem non convex": st.SOLVER_ERROR,
    "non convex": st.SOLVER_ERROR,
    "interrupted": st.SOLVER_ERROR,
    "unsolved": st.SOLVER_ERROR,
}


def map_status(raw: str) -> str:
    """OSQP's status word → the iamp vocabulary (unknown words → SOLVER_ERROR)."""
    return OSQP_STATUS.get(raw.strip().lower(), st.SOLVER_ERROR)


def _polish_key() -> str:
    v = dist_version("osqp") or "1"
    return "polishing" if int(v.split(".")[0]) >= 1 else "polish"


def equality_settings(eps_abs: float = 1e-5, max_iter: int = 10_000) -> dict[str, Any]:
    """OSQP settings for the equality-only QP (module docstring: what each one buys)."""
    key = _polish_key()
    settings: dict[str, Any] = {"eps_abs": eps_abs, "eps_rel": 0.0, key: True, "max_iter": max_iter,
                                "polish_refine_iter": 10, "verbose": False}
    if key == "polishing":
        settings["check_dualgap"] = False
    return settings


class OSQPBackend(QPBackend):
    """OSQP behind :class:`~iamp.planners.backends.base.QPBackend`."""

    name: ClassVar[str] = "osqp"
    distribution: ClassVar[str] = "osqp"
    warm_starts: ClassVar[bool] = True
    tolerance_key: ClassVar[str] = "cmp_kkt_rel_osqp"

    @classmethod
    def default_settings(cls) -> dict[str, Any]:
        return equality_settings()

    def _setup(self) -> None:
        import osqp

        self.solver = osqp.OSQP()
        self.solver.setup(self.P, self.q, self.A, self.l, self.u, **self.settings)
        self._warm: tuple[np.ndarray, np.ndarray] | None = None

    def _push(self, P: bool, A: bool, A_idx: IntArray | None, q: bool, bounds: bool) -> None:
        kw: dict[str, Any] = {}
        if P:
            kw["Px"] = self.P.data.copy()
        if A:
            if A_idx is None:
                kw["Ax"] = self.A.data.copy()
            elif A_idx.size:
                kw["Ax"] = self.A.data[A_idx].copy()
                kw["Ax_idx"] = A_idx
        if q:
            kw["q"] = self.q.copy()
        if bounds:
            kw["l"] = self.l.copy()
            kw["u"] = self.u.copy()
        if kw:
            self.solver.update(**kw)

    def warm_start(self, z: np.ndarray, y: np.ndarray) -> None:
        if np.all(np.isfinite(z)) and np.all(np.isfinite(y)):
            self.solver.warm_start(x=z, y=y)

    def solve(self) -> QPSolution:
        t0 = time.perf_counter()
        res = self.solver.solve(raise_error=False)
        call = time.perf_counter() - t0
        info = res.info
        raw = str(info.status)
        polished = int(getattr(info, "status_polish", 0)) == 1
        z = np.array(res.x, dtype=float) if res.x is not None else np.full(self.q.size, np.nan)
        y = np.array(res.y, dtype=float) if res.y is not None else np.full(self.l.size, np.nan)
        return QPSolution(z=z, y=y, status=map_status(raw), raw_status=raw, iterations=int(info.iter),
                          solver_time_s=float(info.run_time), solve_call_s=call, polished=polished)
