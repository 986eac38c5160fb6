r"""The one discretised-QP core: :class:`~iamp.planners.qp_data.QPData` (matrices built
once) on one backend of :mod:`iamp.planners.backends`, re-solved per candidate by value
updates, every solution verified from recomputed KKT residuals.

A candidate puts vehicle ``i``'s contact at grid node ``k_i``: the selector entries of ``A``
and the corner values of ``b`` change (a few numbers); a new grid (``refine``'s aligned
grids) changes the values of ``P`` and ``A``.  Only the changed values go to the backend,
which keeps its factorisation structure (``kkt``: its whole factorisation while the grid is
unchanged).  OSQP is warm-started from the previous candidate.

Verification (every solve): the KKT residuals ``r_p, r_d, r_g`` (relative; formulas in
:mod:`iamp.planners.backends.base`) are recomputed from ``P, q, A, b`` and the returned
``(z, y)``, and compared with the backend's tolerance in
:data:`iamp.core.tolerances.TOLERANCES` (``tolerance_key``).  A solver that says "solved"
but misses a tolerance is reported INACCURATE, with the check and its value.
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from iamp.core import status as st
from iamp.core.problem import Problem
from iamp.core.tolerances import tol
from iamp.planners.backends import QPBackend, get_backend
from iamp.planners.backends.base import FloatArray, KKTResiduals
from iamp.planners.hold import HoldTrajectory, aligned_grid
from iamp.planners.qp_data import QPData


@dataclass
class CandidateResult:
    """One solve of the QP with the contacts at given grid nodes.

    ``status`` is verified (see the module docstring); ``cost`` is ``J`` of the held input
    when the status is OPTIMAL and ``inf`` otherwise.  Times: ``solve_call_s`` the backend's
    ``solve()`` call, ``backend_s`` the value update plus that call (what a solver costs per
    candidate), ``wall_time_s`` everything (selector update, solve, verification, unpacking).
    ``checks`` maps each verified condition to ``{"value", "tol", "ok"}``; ``failed_check``
    names the first that failed.
    """

    nodes: tuple[int, ...]
    status: str
    solver_status: str
    raw_status: str
    cost: float
    contact_times: FloatArray
    iterations: int = 0
    solver_time_s: float | None = None
    solve_call_s: float = 0.0
    backend_s: float = 0.0
    wall_time_s: float = 0.0
    polished: bool | None = None
    trajectory: HoldTrajectory | None = None
    multipliers: FloatArray | None = None
    z: FloatArray | None = None
    y: FloatArray | None = None
    kkt: KKTResiduals | None = None
    checks: dict[str, dict[str, Any]] = field(default_factory=dict)
    failed_check: str | None = None

    @property
    def ok(self) -> bool:
        return self.status == st.OPTIMAL


def verify(kkt: KKTResiduals | None, tolerance: float, solver_status: str) -> tuple[str, dict[str, dict[str, Any]],
                                                                                  str | None]:
    """Status after checking the recomputed KKT residuals against ``tolerance``.

    Returns ``(status, checks, failed_check)``: a solver failure keeps its status; a
    "solved" whose residual exceeds the tolerance becomes INACCURATE.
    """
    checks: dict[str, dict[str, Any]] = {}
    if kkt is None:
        return solver_status, checks, None
    failed = None
    for name, value in (("kkt_primal_rel", kkt.primal_rel), ("kkt_dual_rel", kkt.dual_rel),
                        ("kkt_gap_rel", kkt.gap_rel)):
        ok = math.isfinite(value) and value <= tolerance
        checks[name] = {"value": float(value), "tol": tolerance, "ok": ok}
        if not ok and failed is None:
            failed = name
    if solver_status != st.OPTIMAL:
        return solver_status, checks, failed
    return (st.OPTIMAL, checks, None) if failed is None else (st.INACCURATE, checks, failed)


class CandidateSolver(Protocol):
    """What the sweep and the refinement need: :class:`DiscretisedQP`, or the cvxpy
    cross-check :class:`iamp.comparison.cvxpy_qp.CvxpyQP`."""

    problem: Problem
    N: int
    hold: str
    n_solves: int
    setup_time_s: float

    @property
    def t_nodes(self) -> FloatArray: ...

    def set_grid(self, t_nodes: Sequence[float] | FloatArray) -> None: ...

    def set_uniform_grid(self) -> None: ...

    def candidate_nodes(self) -> Iterator[tuple[int, ...]]: ...

    def n_candidates(self) -> int: ...

    def solve_nodes(self, nodes: Sequence[int]) -> CandidateResult: ...

    def solve_times(self, times: Sequence[float] | FloatArray) -> CandidateResult: ...


class DiscretisedQP:
    """The QP of one problem on one backend, re-solved per candidate.

    Parameters
    ----------
    problem : Problem
    steps : int
        Number of intervals ``N``.
    hold : {"foh", "zoh"}
    solver : str
        A name in :data:`iamp.planners.backends.BACKENDS`.
    settings : mapping, optional
        Overrides of the backend's default settings.
    """

    def __init__(self, problem: Problem, steps: int = 100, hold: str = "foh", solver: str = "clarabel",
                 settings: Mapping[str, Any] | None = None) -> None:
        cls = get_backend(solver)
        self.problem = problem
        self.data = QPData(problem, steps, hold)
        self.N, self.hold, self.solver = self.data.N, hold, solver
        t0 = time.perf_counter()
        d = self.data
        self.backend: QPBackend = cls(d.P, d.q, d.A, d.b, d.b, settings)
        self.setup_time_s = time.perf_counter() - t0
        self.tolerance = tol(cls.tolerance_key)
        self.n_solves = 0
        self._grid_dirty = False
        self._last: tuple[FloatArray, FloatArray] | None = None

    @property
    def t_nodes(self) -> FloatArray:
        return self.data.t_nodes

    def set_grid(self, t_nodes: Sequence[float] | FloatArray) -> None:
        """Move to another grid (a value update of ``P`` and ``A``)."""
        t = np.asarray(t_nodes, dtype=float)
        if np.array_equal(t, self.data.t_nodes):
            return
        nodes = self.data.nodes
        self.data.set_grid(t)
        self._grid_dirty = True
        if nodes is not None:  # keep the selector consistent with A
            self.data.selector_update(nodes)

    def set_uniform_grid(self) -> None:
        self.set_grid(np.linspace(0.0, self.problem.tf, self.N + 1))

    def candidate_nodes(self) -> Iterator[tuple[int, ...]]:
        """Every ordered combination of distinct interior nodes, one per vehicle."""
        return itertools.permutations(range(1, self.N), self.problem.m)

    def n_candidates(self) -> int:
        return math.perm(self.N - 1, self.problem.m)

    def solve_nodes(self, nodes: Sequence[int]) -> CandidateResult:
        """Solve with the contacts at the given nodes of the current grid, and verify."""
        t0 = time.perf_counter()
        d, b = self.data, self.backend
        pos, vals = d.selector_update(nodes)
        tb = time.perf_counter()
        if self._grid_dirty:
            b.update(Px=d.P.data, Ax=d.A.data, l=d.b, u=d.b)
            self._grid_dirty = False
        else:
            b.update(Ax=vals, Ax_idx=pos, l=d.b, u=d.b)
        if b.warm_starts and self._last is not None:
            b.warm_start(*self._last)
        sol = b.solve()
        backend_s = time.perf_counter() - tb
        self.n_solves += 1
        nd = tuple(int(k) for k in nodes)
        times = d.t_nodes[np.asarray(nd, dtype=np.int64)].copy()
        finite = sol.finite
        kkt = d.kkt_residuals(sol.z, sol.y) if finite else None
        if finite:
            self._last = (sol.z, sol.y)
        status, checks, failed = verify(kkt, self.tolerance, sol.status)
        r = CandidateResult(nodes=nd, status=status, solver_status=sol.status, raw_status=sol.raw_status,
                            cost=np.inf, contact_times=times, iterations=sol.iterations,
                            solver_time_s=sol.solver_time_s, solve_call_s=sol.solve_call_s, polished=sol.polished,
                            backend_s=backend_s, kkt=kkt, checks=checks, failed_check=failed)
        if finite:
            r.z, r.y = sol.z, sol.y
        if status == st.OPTIMAL:
            X, U = d.unpack(sol.z)
            r.trajectory = HoldTrajectory(d.t_nodes.copy(), X, U, self.hold)
            r.cost = r.trajectory.cost()
            r.multipliers = d.collision_multipliers(sol.y)
        r.wall_time_s = time.perf_counter() - t0
        return r

    def solve_times(self, times: Sequence[float] | FloatArray) -> CandidateResult:
        """Solve on a grid aligned with the (off-grid) contact times ``times``."""
        t_nodes, idx = aligned_grid(times, self.problem.tf, self.N)
        self.set_grid(t_nodes)
        return self.solve_nodes([int(k) for k in idx])
