"""The runs a comparison judges: one planner configuration, timed, with its fingerprints.

A :class:`QPConfig` names one QP configuration (solver, hold, ``N``, contact search, path);
:func:`run_pmp` and :func:`run_qp` plan the same :class:`~iamp.core.problem.Problem` and time
full plans; :func:`run_qp` then recomputes the KKT residuals of the reported solution from
the QP matrices (never the solver's own report).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from iamp.comparison.timing import TimingStats
from iamp.comparison.trajectories import hold_trajectory
from iamp.core.plan import Plan
from iamp.core.problem import Problem
from iamp.core.tolerances import tol
from iamp.planners import registry
from iamp.planners.qp.core import CandidateSolver
from iamp.planners.qp.diagnostics import QPDiagnostics
from iamp.planners.qp.planner import QPPlanner

from .fingerprints import problem_fingerprint, x_poly_fingerprint
from .records import KKTJSON, RunJSON

__all__ = ["QPConfig", "Run", "default_configs", "run_pmp", "run_qp"]


@dataclass(frozen=True)
class QPConfig:
    """One QP configuration.

    ``path`` is ``"cvxpy"`` (the cross-check :class:`iamp.comparison.cvxpy_qp.CvxpyQPPlanner`)
    or ``"native"`` (:class:`iamp.planners.qp.planner.QPPlanner`); ``settings`` override the solver's
    settings (e.g. a deliberately loose OSQP) and should come with a ``tag``.
    """

    solver: str = "clarabel"
    hold: str = "foh"
    steps: int = 100
    path: str = "cvxpy"
    contact: str = "grid"
    settings: dict[str, object] | None = field(default=None, compare=False, hash=False)
    tag: str | None = None

    @property
    def label(self) -> str:
        parts = ["qp", self.solver, self.hold, str(self.steps)]
        if self.contact != "grid":
            parts.append(self.contact)
        if self.path != "cvxpy":
            parts.append(self.path)
        if self.tag:
            parts.append(self.tag)
        return "-".join(parts)

    def planner(self) -> QPPlanner:
        """A fresh planner object for this configuration."""
        if self.path == "native":
            native = registry.make_planner("qp", steps=self.steps, hold=self.hold, solver=self.solver,
                                           contact=self.contact, solver_settings=self.settings)
            assert isinstance(native, QPPlanner)
            return native
        if self.path != "cvxpy":
            raise ValueError(f"unknown path {self.path!r}; choose cvxpy or native")
        from iamp.comparison.cvxpy_qp import CvxpyQPPlanner

        return CvxpyQPPlanner(steps=self.steps, hold=self.hold, solver=self.solver, contact=self.contact,
                              solver_settings=self.settings)


def default_configs(steps: tuple[int, ...] | list[int] = (100,), solvers: tuple[str, ...] = ("osqp", "clarabel"),
                    holds: tuple[str, ...] = ("foh", "zoh"), native: bool = False) -> list[QPConfig]:
    """Every combination of solver, hold and ``N`` (cvxpy path; plus native if asked)."""
    paths = ("cvxpy", "native") if native else ("cvxpy",)
    return [QPConfig(solver=s, hold=h, steps=int(n), path=p)
            for n in steps for h in holds for s in solvers for p in paths]


@dataclass
class Run:
    """One planner run: its result, timing and fingerprints."""

    label: str
    planner: str
    result: Plan
    time: TimingStats | None
    config: QPConfig | None = None
    kkt: KKTJSON | None = None
    fingerprint: str = ""
    x_poly_fingerprint: str = ""
    notes: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        """The run finished with a verified optimum."""
        return self.result is not None and self.result.status == "optimal"

    def to_json(self) -> RunJSON:
        """The run as in SPEC §5b's ``runs`` (more keys than the minimum)."""
        r, c = self.result, self.config
        ok = self.ok
        qp = r.diagnostics.find(QPDiagnostics)
        out: RunJSON = {
            "label": self.label, "planner": self.planner,
            "solver": c.solver if c else None, "hold": c.hold if c else None,
            "steps": c.steps if c else None, "path": c.path if c else None,
            "contact": c.contact if c else None,
            "settings": dict(c.settings) if c and c.settings else None,
            "status": r.status,
            "cost": float(r.cost) if ok and r.cost is not None else None,
            "contact_times": [float(t) for t in r.contact_times] if ok else [],
            "jumps": [[float(j[0]), float(j[1])] for j in r.jumps] if ok else [],
            "time_s": self.time.to_dict() if self.time is not None else None,
            "x_poly_sha256": self.x_poly_fingerprint,
            "problem_sha256": self.fingerprint,
            "residuals": {k: float(v) for k, v in (r.residuals or {}).items()} if ok else {},
            "kkt": self.kkt,
            "notes": list(self.notes),
        }
        if c is not None:
            failures = (qp.failures if qp is not None else None) or []
            out["n_solves"] = int((qp.n_solves if qp is not None else None) or 0)
            out["failed_candidates"] = len(failures)
            out["failed_statuses"] = sorted({str(s) for _, s in failures})
            out["unpolished_candidates"] = int((qp.unpolished if qp is not None else None) or 0)
        return out


def _finish_run(run: Run) -> Run:
    problem = run.result.problem
    run.fingerprint = problem_fingerprint(problem)
    run.x_poly_fingerprint = x_poly_fingerprint(problem)
    return run


def _measure(fn: Callable[[], Plan], repeats: int, warmup: int,
             budget_s: float | None = None) -> tuple[TimingStats, Plan | None]:
    from iamp.comparison.timing import measure

    stats, last = measure(fn, repeats, warmup, budget_s)
    return stats, last


def run_pmp(problem: Problem, repeats: int = 20, warmup: int = 2, budget_s: float | None = None) -> Run:
    """Plan with the PMP (global contact time), timed (the residual report is computed on a
    final untimed call; ``budget_s`` as for :func:`iamp.comparison.timing.measure`)."""
    timed = registry.make_planner("pmp", diagnostics=False)
    planner = registry.make_planner("pmp")

    def fn() -> Plan:
        return timed.plan(problem)
    stats: TimingStats | None
    try:
        stats, _ = _measure(fn, repeats, warmup, budget_s)
        result = planner.plan(problem)
    except Exception as exc:  # a failed PMP is reported as a status, never a cost
        from iamp.core.errors import SolverError
        from iamp.core.plan import Plan

        if not isinstance(exc, SolverError):
            raise
        result = Plan(problem=problem, planner="pmp", status=str(exc.status), cost=None,
                            contact_times=np.full(problem.m, np.nan), jumps=np.full((problem.m, 2), np.nan),
                            trajectory=None)
        stats = None
    return _finish_run(Run("pmp", "pmp", result, stats))


def run_qp(problem: Problem, config: QPConfig, repeats: int = 3, warmup: int = 1,
           budget_s: float = 30.0) -> Run:
    """Plan with one QP configuration (its own contact-time search), timed over full plans
    (build + search), then recompute the KKT residuals of the reported solution."""
    planner = config.planner()
    keep: dict[str, CandidateSolver] = {}

    def fn() -> Plan:
        qp = planner.build(problem)
        keep["qp"] = qp
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return planner.plan(problem, qp=qp)

    stats, result = _measure(fn, repeats, warmup, budget_s)
    assert result is not None  # measure calls fn at least once
    run = _finish_run(Run(config.label, "qp", result, stats, config=config))
    if run.ok:
        run.kkt = _kkt_of_result(problem, config, keep["qp"], result, run)
    return run


def _kkt_of_result(problem: Problem, config: QPConfig, qp: CandidateSolver, result: Plan,
                   run: Run) -> KKTJSON | None:
    """Re-solve the reported candidate on the planner's own QP object and recompute the KKT
    residuals from the QP matrices (built by :class:`iamp.planners.qp.data.QPData`, the same
    rows as the cvxpy model) and the returned primal and dual vectors (both paths return them
    in that row order)."""
    from iamp.planners.qp.data import QPData

    traj = hold_trajectory(result)
    t_nodes = np.asarray(traj.t_nodes)
    nodes = [int(np.argmin(np.abs(t_nodes - t))) for t in result.contact_times]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        qp.set_grid(t_nodes)
        r = qp.solve_nodes(nodes)
    if r.status != "optimal" or r.z is None or r.y is None:
        run.notes.append(f"re-solve for the KKT check returned {r.status}")
        return None
    cost = float(result.cost) if result.cost is not None else float("nan")
    if not abs(r.cost - cost) <= tol(f"cmp_cost_rel_{config.solver}") * max(1.0, abs(cost)):
        run.notes.append("re-solve for the KKT check changed the cost beyond the solver tolerance")
    data = QPData(problem, config.steps, config.hold)
    data.set_grid(t_nodes)
    data.selector_update(nodes)
    comp: float | None = None
    if problem.limits is not None and not problem.limits.empty:  # the stacked rows [A; A_L] (SPEC §14)
        from iamp.planners.qp.bounded import bounded_kkt
        from iamp.planners.qp.limits import limit_rows

        k, comp = bounded_kkt(data, limit_rows(data, t_nodes, config.hold, problem.limits), r.z, r.y)
    else:
        k = data.kkt_residuals(r.z, r.y)
    out: KKTJSON = {"primal": float(k.primal), "dual": float(k.dual), "gap": float(k.gap),
                    "primal_rel": float(k.primal_rel), "dual_rel": float(k.dual_rel), "gap_rel": float(k.gap_rel),
                    "source": "recomputed from the QP matrices and the returned (x, y)"}
    if comp is not None:
        out["complementarity_rel"] = float(comp)
    return out


# --------------------------------------------------------------------------------------
# Judging
# --------------------------------------------------------------------------------------
