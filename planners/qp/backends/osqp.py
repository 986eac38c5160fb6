r"""OSQP (ADMM with an LDLᵀ of the quasi-definite KKT matrix; first order, warm-startable).

Set up once; :meth:`update` sends only the changed values (``Ax``/``Ax_idx``, ``l``, ``u``)
so OSQP refactorises numerically on the same symbolic structure, and every solve is
warm-started from the previous solution when :meth:`warm_start` is called.

Settings for the equality-only QP of SPEC §3: :func:`equality_settings` (the defaults, used
for any problem) plus, when every row is an equality, :func:`polish_first_settings` (unless
a setting is given explicitly; :meth:`OSQPBackend.describe` reports what was applied).

The accuracy comes from the **polish**: with only equality rows every row is "active", so a
successful polish solves the reduced KKT system directly (a fresh LDLᵀ plus
``polish_refine_iter`` refinement steps) and the solution is exact to ~1e-13 whatever ADMM's
``eps_abs`` was; ADMM only has to bring the iterate close enough for the polish to succeed.
So the ADMM part is made as short as it can be:

* ``eps_abs = 0.1`` checked every iteration (``check_termination = 1``; the default checks
  every 25, so ADMM ran 50 iterations whatever the tolerance);
* ``alpha = 1.0`` (no over-relaxation): from the neighbouring candidate's solution
  (warm start) ADMM meets 0.1 in 3 iterations instead of 22 with OSQP's 1.6;
* ``scaling = 0``: with Ruiz scaling every value update rescales the data (~0.2 ms of the
  update); the lane-change QP is well scaled and verifies without it.

Measured on ``paper-1-poly``, FOH, ``N = 100``, all 99 candidates of a warm-started sweep per
row, KKT residuals recomputed (verified: relative residuals within ``cmp_kkt_rel_osqp`` =
1e-7), OSQP 1.1.3.  Times: medians of update + solve per candidate, rows interleaved over
four rounds in one run on the shared, loaded 2-core machine (compare rows, not absolute
values: ``iamp bench`` gives the quiet-machine numbers); iteration counts are deterministic.

==========================================================  ========  ========  ============  =========  =======
settings (besides eps_rel 0, check_dualgap off, polishing,  verified  polished  iterations    max KKT    time
polish_refine_iter 10)                                                          median (max)
==========================================================  ========  ========  ============  =========  =======
before: eps_abs 1e-5, check every 25, alpha 1.6, scaling    99        99        50 (75)       1.9e-13    1.90 ms
**default now** (eps_abs 0.1, check every 1, alpha 1.0,    99        99        3 (67)        1.9e-13    0.96 ms
scaling 0)
… eps_abs 1e-2 (1e-3: same, ≤ 91 iterations)                 99        99        3 (79)        1.9e-13    0.99 ms
… with Ruiz scaling (``scaling = 10``)                       99        99        3 (54)        1.9e-13    1.24 ms
… with over-relaxation ``alpha = 1.6``                       99        99        22 (58)       1.9e-13    1.56 ms
… ``adaptive_rho`` off (no refactorisation on rho updates)  99        99        3 (2410)      1.9e-13    ≈ same
… without warm start (``warm_starting`` off)                 99        99        3 (67)        1.9e-13    0.97 ms
… ``polish_refine_iter = 3``                                  97        99        3 (67)        2.3e-05    0.78 ms
… ``polish_refine_iter = 1``                                  77        96        3 (67)        1.0e-01    ≈ 0.67 ms
… ``polishing`` off                                           0         0         3 (67)        1.0e-01    0.22 ms
==========================================================  ========  ========  ============  =========  =======

What the rest buys or costs:

* ``adaptive_rho`` stays on: off, a few candidates stall (up to 2410 iterations; the same
  with ``alpha`` 1.6: 1506); on, the worst is 67.  ``rho`` 1.0 instead of 0.1 and the polish
  ``delta`` (1e-6 … 1e-12) change nothing measurable.
* ``polish_refine_iter = 10`` is needed: 3 leaves two candidates unverified (2.3e-5), 1 a
  quarter of them.  ``eps_abs`` tighter than 1e-5 makes ADMM stall (earlier study: at 1e-6
  one candidate, at 1e-7 nine run to ``max_iter``; 1e-7 without polishing still fails ten
  candidates); a large ``rho`` (10 … 1e4, unpolished, ``eps_abs`` 1e-8 … 1e-10) verifies at
  most 71 of 99.
* An unpolished solution is accurate only to about ``eps_abs``: it fails the KKT check and
  is reported INACCURATE, never optimal.
* Over 600 random candidates (``random_problem``, FOH and ZOH, ``N`` 10–100, one and two
  vehicles, on and off the grid) the defaults verify every one (worst 6.3e-13; ADMM median
  4, max 66 iterations).
* Where the time goes now, per candidate (OSQP's own timers): the value update with its
  numeric refactorisation ~50 µs, 3 ADMM iterations ~70 µs, the polish ~450 µs (its fresh
  factorisation of the reduced KKT matrix ~300 µs, ten refinement solves ~140 µs).  The
  0.5 ms target is therefore out of reach with a verified solution: the polish alone is
  about that on a quiet machine, and it is what makes the answer exact.  The unverified
  0.2 ms is not offered.
* Problems with inequalities (the avoidance QP) keep :func:`equality_settings` alone: with a
  loose ADMM the polish's active-set guess could be wrong.

Status mapping (OSQP word → :mod:`iamp.core.status`): ``solved`` → OPTIMAL;
``solved inaccurate`` → INACCURATE; ``maximum iterations reached`` → MAX_ITER;
``run time limit reached`` → TIME_LIMIT; ``primal infeasible (inaccurate)`` → INFEASIBLE;
``non convex`` / ``dual infeasible`` / anything else → SOLVER_ERROR.
"""

from __future__ import annotations

import functools
import time
from typing import Any, ClassVar

import numpy as np

from iamp.core import status as st

from .base import IntArray, QPBackend, QPSolution, dist_version

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


def polish_first_settings() -> dict[str, Any]:
    """Added to :func:`equality_settings` when every row is an equality (module docstring):
    ADMM only brings the iterate near the solution (loose ``eps_abs``, checked every
    iteration, no over-relaxation, no scaling to redo on each update); the exact answer is
    the polish."""
    return {"eps_abs": 0.1, "check_termination": 1, "alpha": 1.0, "scaling": 0}


@functools.cache
def _algebra() -> dict[str, Any]:
    """``OSQP()``'s keyword choosing its linear algebra: OSQP >= 1 picks the first of cuda, mkl,
    builtin that imports, trying the imports on every ``OSQP()`` (the failed ones search the whole
    path again: about 80 µs a set-up); the same choice, made once per process.  Empty for OSQP < 1."""
    try:
        from osqp import interface
    except ImportError:  # pragma: no cover - an OSQP without the module
        return {}
    default = getattr(interface, "default_algebra", None)
    return {"algebra": default()} if default is not None else {}


class OSQPBackend(QPBackend):
    """OSQP behind :class:`~iamp.planners.qp.backends.base.QPBackend`."""

    name: ClassVar[str] = "osqp"
    distribution: ClassVar[str] = "osqp"
    warm_starts: ClassVar[bool] = True
    tolerance_key: ClassVar[str] = "cmp_kkt_rel_osqp"

    @classmethod
    def default_settings(cls) -> dict[str, Any]:
        return equality_settings()

    def _setup(self) -> None:
        import osqp

        settings = self._apply_settings(bool(np.array_equal(self.l, self.u)), polish_first_settings())  # polish first
        self.solver = osqp.OSQP(**_algebra())
        self.solver.setup(self.P, self.q, self.A, self.l, self.u, **settings)
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
        status = map_status(raw)
        cert = getattr(res, "prim_inf_cert", None)
        certificate = np.array(cert, dtype=float) if status == st.INFEASIBLE and cert is not None else None
        return QPSolution(z=z, y=y, status=status, raw_status=raw, iterations=int(info.iter),
                          solver_time_s=float(info.run_time), solve_call_s=call, polished=polished,
                          certificate=certificate)
