r"""The one discretised-QP core: :class:`~iamp.planners.qp.data.QPData` (matrices built
once) on one backend of :mod:`iamp.planners.qp.backends`, re-solved per candidate by value
updates, every solution verified from recomputed KKT residuals.

A candidate puts vehicle ``i``'s contact at grid node ``k_i``: the selector entries of ``A``
and the corner values of ``b`` change (a few numbers); a new grid (``refine``'s aligned
grids) changes the values of ``P`` and ``A``.  Only the changed values go to the backend,
which keeps its factorisation structure (``kkt``: its whole factorisation while the grid is
unchanged).  OSQP is warm-started from the previous candidate.

Sweeps (:meth:`DiscretisedQP.solve_many`): on the ``kkt`` backend the candidates of one grid
after the first are solved as one *family* — for each, the formulas of a single solve on the
same factorisation and column block, evaluated for all candidates at once
(:meth:`~iamp.planners.qp.backends.kkt.KKTBackend.solve_family`) — and each candidate's KKT
residuals are recomputed from ``P`` and its own ``A`` and ``b`` (:func:`family_residuals`,
the formulas of :meth:`QPData.kkt_residuals` with each candidate's selector terms added to a
product with the selector entries zeroed).  Results, verdicts and costs are those of one-by-
one solves (equal to round-off; tested); only the times are per family, shared equally.

Verification (every solve): the KKT residuals ``r_p, r_d, r_g`` (relative; formulas in
:mod:`iamp.planners.qp.backends.base`) are recomputed from ``P, q, A, b`` and the returned
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

from .backends import QPBackend, get_backend
from .backends.base import FloatArray, IntArray, KKTResiduals, QPSolution
from .backends.kkt import KKTBackend
from .data import QPData
from .hold import HoldTrajectory, aligned_grid


@dataclass(slots=True)  # no per-instance dict: a sweep holds up to ~10⁶ of them
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
    #: INFEASIBLE with a verified Farkas certificate (the bounded QP, :mod:`iamp.planners.qp.bounded`).
    infeasible_certified: bool = False

    @property
    def ok(self) -> bool:
        return self.status == st.OPTIMAL

    def drop_solution(self) -> None:
        """Forget the solution's arrays (``z``, ``y``, ``trajectory``, ``multipliers``) and keep
        the verdict: nodes, status, cost, times, KKT residuals and checks.  A sweep keeps the
        arrays of its best candidate only (:func:`~iamp.planners.qp.sweep.run_sweep`): with three
        vehicles and ``N = 100`` it has 941,094 candidates, whose arrays took the process past 15 GB."""
        self.z = self.y = self.multipliers = None
        self.trajectory = None

    @classmethod
    def of_solve(cls, nodes: tuple[int, ...], status: str, contact_times: FloatArray, sol: QPSolution, backend_s: float,
                 kkt: KKTResiduals | None, checks: dict[str, dict[str, Any]], failed: str | None) -> CandidateResult:
        """The result of one backend solve ``sol`` (:class:`~iamp.planners.qp.backends.base.QPSolution`)
        with its verified ``status``, before the trajectory is unpacked: ``cost`` ``inf`` until then;
        the primal and dual vectors are kept when the residuals were recomputed (``kkt``)."""
        r = cls(nodes=nodes, status=status, solver_status=sol.status, raw_status=sol.raw_status, cost=np.inf,
                contact_times=contact_times, iterations=sol.iterations, solver_time_s=sol.solver_time_s,
                solve_call_s=sol.solve_call_s, polished=sol.polished, backend_s=backend_s, kkt=kkt, checks=checks,
                failed_check=failed)
        if kkt is not None:
            r.z, r.y = sol.z, sol.y
        return r


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
        A name in :data:`iamp.planners.qp.backends.BACKENDS`.
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
        kkt = d.kkt_residuals(sol.z, sol.y) if sol.finite else None
        r = self._result(tuple(int(k) for k in nodes), sol, kkt, backend_s)
        r.wall_time_s = time.perf_counter() - t0
        return r

    def _result(self, nd: tuple[int, ...], sol: QPSolution, kkt: KKTResiduals | None,
                backend_s: float, unpacked: tuple[FloatArray, FloatArray, float, FloatArray] | None = None
                ) -> CandidateResult:
        """The verified :class:`CandidateResult` of one solution (module docstring).

        ``unpacked``: ``(X, U, cost, ν)`` of ``sol`` computed for a family at once
        (:func:`family_unpacked`: the same numbers as :meth:`QPData.unpack`,
        :meth:`HoldTrajectory.cost` and :meth:`QPData.collision_multipliers`)."""
        d = self.data
        times = d.t_nodes[np.asarray(nd, dtype=np.int64)].copy()
        if kkt is not None:
            self._last = (sol.z, sol.y)
        status, checks, failed = verify(kkt, self.tolerance, sol.status)
        r = CandidateResult.of_solve(nd, status, times, sol, backend_s, kkt, checks, failed)
        if status == st.OPTIMAL:
            if unpacked is None:
                X, U = d.unpack(sol.z)
                r.trajectory = HoldTrajectory(d.t_nodes.copy(), X, U, self.hold)
                r.cost = r.trajectory.cost()
            else:
                r.trajectory = HoldTrajectory(d.t_nodes.copy(), unpacked[0], unpacked[1], self.hold)
                r.cost = unpacked[2]
            r.multipliers = d.collision_multipliers(sol.y) if unpacked is None else unpacked[3]
        return r

    def solve_many(self, candidates: Sequence[Sequence[int]]) -> list[CandidateResult]:
        """:meth:`solve_nodes` for every candidate, in order.

        On the direct ``kkt`` backend, the candidates after the first are solved as one
        family (:meth:`~iamp.planners.qp.backends.kkt.KKTBackend.solve_family`: the same
        factorisation and column block as one by one, all candidates at once) and verified
        together (:func:`family_residuals`: every candidate's KKT
        residuals recomputed from ``P``, its own ``A`` and ``b``); their times are the
        family's, shared equally.  Elsewhere, and whenever the family solve does not apply,
        one by one.
        """
        out: list[CandidateResult] = []
        rest = list(candidates)
        if rest:
            out.append(self.solve_nodes(rest.pop(0)))
        if rest and isinstance(self.backend, KKTBackend):
            fam = _solve_family(self, rest)
            if fam is not None:
                self.n_solves += len(fam)
                return out + fam
        return out + [self.solve_nodes(c) for c in rest]

    def solve_times(self, times: Sequence[float] | FloatArray) -> CandidateResult:
        """Solve on a grid aligned with the (off-grid) contact times ``times``."""
        t_nodes, idx = aligned_grid(times, self.problem.tf, self.N)
        self.set_grid(t_nodes)
        return self.solve_nodes([int(k) for k in idx])


#: Candidates per family solve (bounds the memory: a few MB at N = 100).
FAMILY_CHUNK = 256


def family_residuals(d: QPData, Z: FloatArray, Y: FloatArray, cols: IntArray, B1: FloatArray) -> list[KKTResiduals]:
    """The KKT residuals of :meth:`QPData.kkt_residuals` for many candidates at once.

    Candidate ``j`` is the current data with its selector rows ``row_collision + r`` holding
    a single 1 in column ``cols[j, r]`` and the right-hand sides ``B1[j]``.  The products
    ``Pz, Aᵀy, Az`` come from the stacked matrix with every selector entry zeroed, plus each
    candidate's own selector terms (``(Az)_row += z_col``, ``(Aᵀy)_col += y_row``); the
    formulas are :func:`iamp.planners.qp.data.equality_residuals`'."""
    n, r0, J = d.n, d.row_collision, Z.shape[0]
    M0 = d._M.copy()
    M0.data[d._m_of_a[d._sel_pos.reshape(-1)].reshape(-1)] = 0.0
    out = np.asarray((M0 @ np.hstack([Z, Y]).T).T)
    ar = np.arange(J)
    for r in range(cols.shape[1]):
        out[ar, 2 * n + r0 + r] += Z[ar, cols[:, r]]
        out[ar, n + cols[:, r]] += Y[:, r0 + r]
    Pz, Aty, Az = out[:, :n], out[:, n:2 * n], out[:, 2 * n:]
    B = np.broadcast_to(d.b, (J, d.b.size)).copy()
    B[:, r0:] = B1
    rp = np.abs(Az - B).max(axis=1)
    rd = np.abs(Pz + Aty).max(axis=1)
    zPz, by = np.einsum("ij,ij->i", Z, Pz), np.einsum("ij,ij->i", B, Y)
    rg = np.abs(zPz + by)
    sp_ = np.maximum(1.0, np.maximum(np.abs(Az).max(axis=1), np.abs(B).max(axis=1)))
    sd = np.maximum(1.0, np.maximum(np.abs(Pz).max(axis=1), np.abs(Aty).max(axis=1)))
    sg = np.maximum(1.0, np.maximum(np.abs(zPz), np.abs(by)))
    # element-wise division of the arrays = the scalar divisions one by one; tolist() = float()
    return [KKTResiduals(a, b_, c, a1, b1, c1) for a, b_, c, a1, b1, c1 in
            zip(rp.tolist(), rd.tolist(), rg.tolist(), (rp / sp_).tolist(), (rd / sd).tolist(), (rg / sg).tolist(),
                strict=True)]


def family_unpacked(d: QPData, Z: FloatArray, hold: str, Y: FloatArray | None = None
                    ) -> tuple[FloatArray, FloatArray, list[float], FloatArray | None]:
    r""":meth:`QPData.unpack`, :meth:`HoldTrajectory.cost` and
    :meth:`QPData.collision_multipliers` of every row of ``Z`` (``Y``) at once:
    ``(X, U, costs, ν)`` with ``X[j], U[j] = d.unpack(Z[j])``, ``ν[j] =
    d.collision_multipliers(Y[j])`` and ``costs[j]`` equal to ``HoldTrajectory(d.t_nodes,
    X[j], U[j], hold).cost()`` **bit for bit**: the same element-wise operations, and each
    candidate's ``2N`` terms summed as one contiguous row (numpy sums a contiguous row,
    alone or as the last axis of a C-ordered block, with the same pairwise summation;
    tested against the one-by-one cost)."""
    nu = None if Y is None else Y[:, d.row_collision:].reshape(Y.shape[0], d.problem.m, 2).copy()
    X = Z[:, d._X_idx]
    U = Z[:, d._U_idx]
    J = Z.shape[0]
    h = np.diff(d.t_nodes)[:, None]
    if hold == "zoh":
        terms = np.ascontiguousarray(h * U**2).reshape(J, -1)
        costs = (0.5 * terms.sum(axis=1)).tolist()
    else:
        u0, u1 = U[:, :-1], U[:, 1:]
        terms = np.ascontiguousarray(h / 6 * (u0**2 + u0 * u1 + u1**2)).reshape(J, -1)
        costs = terms.sum(axis=1).tolist()
    return X, U, costs, nu


def _checked_nodes(d: QPData, cands: Sequence[Sequence[int]]) -> list[tuple[int, ...]]:
    """``[d.check_nodes(c) for c in cands]`` (tuples of ints), checked for all at once; an
    invalid candidate raises :meth:`QPData.check_nodes`'s error."""
    try:
        K = np.asarray(cands, dtype=np.int64)
    except (TypeError, ValueError):
        K = np.zeros((0, 0), dtype=np.int64)
    if K.ndim == 2 and K.shape == (len(cands), d.problem.m) and bool(np.all((K > 0) & (K < d.N))) and \
            np.array_equal(K, np.asarray(cands, dtype=float)):
        return [tuple(row) for row in K.tolist()]
    return [d.check_nodes(c) for c in cands]


def _solve_family(qp: DiscretisedQP, cands: list[Sequence[int]]) -> list[CandidateResult] | None:
    """:meth:`DiscretisedQP.solve_many`'s family path (``None``: does not apply here)."""
    d, b = qp.data, qp.backend
    assert isinstance(b, KKTBackend)
    s = b.structure
    m = qp.problem.m
    if qp._grid_dirty or not np.array_equal(s.border, np.arange(d.row_collision, d.n_rows)):
        return None  # the selector rows are not exactly the border (small N): one by one
    ent_of_pos = np.full(d.A.nnz, -1, dtype=np.int64)
    ent_of_pos[s.b_pos] = np.arange(s.b_pos.size)
    veh = np.repeat(np.arange(m), 2)
    axis = np.tile(np.arange(2), m)
    out: list[CandidateResult] = []
    for c0 in range(0, len(cands), FAMILY_CHUNK):
        t0 = time.perf_counter()
        chunk = _checked_nodes(d, cands[c0:c0 + FAMILY_CHUNK])
        K = np.asarray(chunk, dtype=np.int64)[:, veh]  # (J, 2m): node of each selector row
        ent = ent_of_pos[d._sel_pos[veh, axis, K - 1]]
        B1 = np.where(axis == 0, d._corner_x[veh, K], d._corner_y[veh])
        cols = axis * d.block + K  # s_x(k) or s_y(k) in z
        fam = b.solve_family(ent, np.ones(ent.shape), B1)
        if fam is None:
            return None if not out else out + [qp.solve_nodes(c) for c in cands[c0:]]
        Z, Y = fam
        tb = time.perf_counter() - t0
        kkts = family_residuals(d, Z, Y, cols, B1)
        XA, UA, costs, NU = family_unpacked(d, Z, qp.hold, Y)
        assert NU is not None
        share = tb / len(chunk)
        rs = [qp._result(nd, QPSolution(z=Z[j], y=Y[j], status=st.OPTIMAL, raw_status="solved", iterations=1,
                                        solver_time_s=share, solve_call_s=share), kkts[j], share,
                         (XA[j], UA[j], costs[j], NU[j]))
              for j, nd in enumerate(chunk)]
        wall = (time.perf_counter() - t0) / len(chunk)
        for r in rs:
            r.wall_time_s = wall
        out += rs
    return out
