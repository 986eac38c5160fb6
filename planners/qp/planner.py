r"""The convex baseline (SPEC §3): the lane change discretised as a QP, with its own
contact-time search, returning an :class:`iamp.core.plan.Plan`.

The QP itself — data built once (:mod:`iamp.planners.qp.data`), solved on a backend of the
one registry (:mod:`iamp.planners.qp.backends`: ``osqp``, ``clarabel``, ``piqp``, ``kkt``),
every solution verified from recomputed KKT residuals — is
:class:`~iamp.planners.qp.core.DiscretisedQP`.  The QP never sees the PMP's contact times:
``grid`` sweeps every interior node (every ordered combination of distinct nodes for
several vehicles; :mod:`iamp.planners.qp.sweep`), ``refine`` then searches off the grid,
seeded by the sweep (bounded Brent for one vehicle, Nelder–Mead for several), on grids
aligned with the candidate times (:func:`~iamp.planners.qp.hold.aligned_grid`).

A plan is OPTIMAL only if its best candidate passed the KKT check and no candidate that
failed could have beaten it (:mod:`iamp.planners.qp.sweep`); otherwise its status says what
failed and ``plan.info`` says why: ``info["checks"]`` (every check with value and
tolerance), ``info["failed_check"]``, ``info["candidates"]`` = ``{"total", "solved",
"failed": {status: count}, "inaccurate"}``.  cvxpy is not used here; it is the independent
cross-check in :mod:`iamp.comparison.cvxpy_qp`.
"""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import optimize

from iamp.core import status as st
from iamp.core.errors import ScenarioError
from iamp.core.plan import Plan
from iamp.core.problem import Problem

from .backends import BACKENDS
from .core import CandidateResult, CandidateSolver, DiscretisedQP
from .diagnostics import QPDiagnostics
from .hold import HOLDS, HoldTrajectory, aligned_grid
from .options import CONTACTS, QPOptions, check_choice, check_limits_solver
from .sweep import Progress, SweepResult, run_sweep

__all__ = ["HOLDS", "CandidateResult", "DiscretisedQP", "HoldTrajectory", "QPPlanner", "SweepResult",
           "aligned_grid", "plan_with"]


def refine_certificate(problem: Problem, best: CandidateResult, hold: str) -> dict[str, Any]:
    r"""Is the refined contact time the global minimiser over every contact time?

    The sweep is global over the grid only, and the off-grid refinement is a local search in
    the grid's best basin.  The PMP certifies its global optimum :math:`J^* = \min_t J(t)`
    (branch and bound on the closed-form value function).  With FOH the refined QP is exact
    (SPEC §3 fact 1, :math:`J_\text{QP}(t) = J(t) \ge J^*`), so the refined plan is global
    exactly when :math:`J_\text{QP}(t_\text{ref}) \le J^*(1 + \epsilon)` with
    :math:`\epsilon` = ``refine_cost_rel``.  With ZOH, :math:`J_\text{ZOH}(t) \ge J(t)` bounds
    the other basins only up to the ZOH gap, which does not certify a minimiser: ``local``.

    With physical limits (SPEC §14) the bounded QP's cost at any contact time is at least the
    unbounded one, :math:`J^\text{bounded}_\text{QP}(t) \ge J(t) \ge J^*`, so the unbounded
    PMP's :math:`J^*` is still a lower bound over every basin: the certificate holds when the
    bounds do not bind and is (correctly) refused when they raise the cost.
    """
    from iamp.core.tolerances import tol
    from iamp.planners.pmp import PMPPlanner

    if hold != "foh":
        return {"global": False, "reason": "ZOH refine: J_ZOH(t) >= J_PMP(t) bounds the other basins only up to "
                                           "the ZOH gap; the refined contact time is a local minimiser"}
    pmp = PMPPlanner().plan(problem.with_limits(None))
    if pmp.status != st.OPTIMAL or pmp.cost is None:
        return {"global": False, "reason": f"the PMP could not certify the global optimum ({pmp.status})",
                "pmp_status": pmp.status}
    eps = tol("refine_cost_rel")
    ok = best.cost <= pmp.cost * (1 + eps) + eps
    out: dict[str, Any] = {"global": bool(ok), "pmp_cost": float(pmp.cost),
                           "pmp_contact_times": [float(t) for t in pmp.contact_times], "tol_rel": eps,
                           "method": "the PMP's certified global optimum J* bounds every contact time (FOH is exact)"}
    if not ok:
        out["reason"] = (f"the refined contact times lie in another basin: J = {best.cost:.9g} > the certified "
                         f"global J* = {pmp.cost:.9g} (PMP, t* = {', '.join(f'{t:.6g}' for t in pmp.contact_times)})")
    return out


def _memo(screen: Callable[[np.ndarray], str | None] | None) -> Callable[[np.ndarray], str | None] | None:
    """``screen`` that answers each contact-time vector once (the witness's nodes recur in the sweep)."""
    if screen is None:
        return None
    seen: dict[tuple[float, ...], str | None] = {}

    def once(times: np.ndarray) -> str | None:
        key = tuple(float(t) for t in times)
        if key not in seen:
            seen[key] = screen(times)
        return seen[key]

    return once


def _checks_of(r: CandidateResult) -> dict[str, dict[str, Any]]:
    return {k: dict(v) for k, v in r.checks.items()}


@dataclass
class QPPlanner:
    """The QP/MPC baseline planner with its own contact-time search.

    Parameters
    ----------
    steps : int
        Grid intervals ``N``.
    hold : {"foh", "zoh"}
    solver : {"osqp", "clarabel", "piqp", "kkt"}
    contact : {"grid", "refine"}
        ``grid``: best of the sweep over every interior node (combination); ``refine``:
        then an off-grid search seeded by the sweep, on aligned grids.
    solver_settings : dict, optional
        Overrides of the backend's settings (e.g. ``{"eps_abs": 1e-3}`` for a loose OSQP).
    limits_between : {"nodes", "certified"}
        With ``problem.limits``: the speed and ``y`` bounds at the grid nodes only (SPEC §14;
        a plan that exceeds them between nodes is ``limits_violated``, with the exact
        violation) or certified between the nodes too (Bernstein rows,
        :mod:`iamp.planners.qp.limits`).
    """

    steps: int = 100
    hold: str = "foh"
    solver: str = "clarabel"
    contact: str = "grid"
    solver_settings: dict[str, Any] | None = None
    refine_xtol: float = 1e-9
    limits_between: str = "nodes"

    path = "native"

    @classmethod
    def from_options(cls, options: QPOptions) -> QPPlanner:
        """The planner of the registry's validated options (:class:`~iamp.planners.qp.options.QPOptions`)."""
        return cls(steps=options.steps, hold=options.hold, solver=options.solver, contact=options.contact,
                   solver_settings=options.solver_settings, limits_between=options.limits_between)

    def __post_init__(self) -> None:
        check_choice(self.contact, CONTACTS, "contact", "contact search")
        check_choice(self.hold, HOLDS, "hold", "hold")
        check_choice(self.solver, tuple(BACKENDS), "solver", "solver")

    def build(self, problem: Problem) -> CandidateSolver:
        """The QP of ``problem`` on the configured backend (built once, re-solved per candidate);
        with ``problem.limits`` the bounded QP (:class:`~iamp.planners.qp.bounded.BoundedQP`)."""
        if problem.m == 0:
            raise ScenarioError("the QP planners need at least one vehicle (a problem with zero vehicles has no "
                                "contact time: its optimum is iamp.core.free.free_plan, or planner 'pmp')", "vehicles")
        if problem.limits is not None and not problem.limits.empty:
            from iamp.planners.qp.bounded import BoundedQP

            check_limits_solver(self.solver)
            return BoundedQP(problem, self.steps, self.hold, self.solver, self.solver_settings,
                             between=self.limits_between)
        return DiscretisedQP(problem, self.steps, self.hold, self.solver, self.solver_settings)

    @staticmethod
    def _limits_info(qp: CandidateSolver) -> dict[str, Any]:
        rows = getattr(qp, "rows", None)
        if rows is None:
            return {}
        out: dict[str, Any] = {"limit_rows": rows.describe()}
        if rows.polygon_sides is not None:
            out["polygon_sides"] = rows.polygon_sides
            out["limits_polygon_sides"] = rows.polygon_sides
        return out

    def sweep(self, qp: CandidateSolver, progress: Progress | None = None,
              alone: dict[tuple[int, int], bool] | None = None,
              box: Callable[[np.ndarray], str | None] | None = None,
              known: dict[tuple[int, ...], CandidateResult] | None = None) -> SweepResult:
        """Solve one QP per candidate node combination (:func:`iamp.planners.qp.sweep.run_sweep`);
        with ``problem.limits``, a candidate whose input box is certified infeasible at its contact
        times is not solved (``box``, by default :func:`iamp.planners.qp.bounded.box_screen`), nor
        one with a vehicle at a node in ``alone`` (:func:`iamp.planners.qp.bounded.single_vehicle_screen`);
        the candidates in ``known`` (already solved on ``qp``'s uniform grid: the witness of
        :meth:`_witness`) are not solved again."""
        lim = qp.problem.limits
        if lim is None or lim.empty:
            return run_sweep(qp, progress, known=known)
        from iamp.planners.qp.bounded import box_screen

        if box is None:
            box = box_screen(qp.problem)
        pairs = alone or {}

        def screen(nodes: tuple[int, ...], times: np.ndarray) -> str | None:
            for i, k in enumerate(nodes):
                if (i, k) in pairs:
                    return (f"vehicle {qp.problem.vehicles[i].name} alone has no plan within the limits with its "
                            f"contact at node {k} (Farkas)")
            return box(times) if box is not None else None

        return run_sweep(qp, progress, screen, known=known)

    def _witness(self, qp: CandidateSolver, box: Callable[[np.ndarray], str | None] | None
                 ) -> CandidateResult | None:
        """One vehicle with limits: the candidate node nearest the middle of the grid that the box
        screen does not certify infeasible, solved on ``qp`` (one solve, counted), or None when the
        screen certifies every node.  A verified (``ok``) witness proves that the bounded problem
        has a plan at a grid node, so no certificate of infeasibility before the sweep
        (:func:`~iamp.planners.qp.bounded.infeasible_before_sweep`) can hold: :meth:`plan` skips
        it and the sweep reuses the witness."""
        N = qp.N
        qp.set_uniform_grid()
        for k in sorted(range(1, N), key=lambda k: (abs(2 * k - N), k)):
            if box is None or box(qp.t_nodes[np.array([k])].copy()) is None:
                return qp.solve_nodes([k])
        return None

    def _refine(self, qp: CandidateSolver, seed: CandidateResult) -> CandidateResult:
        tf, h = qp.problem.tf, qp.problem.tf / qp.N
        t0 = seed.contact_times
        lo = np.maximum(t0 - h, 1e-6 * tf)
        hi = np.minimum(t0 + h, tf * (1 - 1e-6))
        best = {"r": seed}

        def f(t: np.ndarray) -> float:
            try:
                r = qp.solve_times(np.atleast_1d(t))
            except ValueError:
                return float(np.inf)
            if r.ok and r.cost < best["r"].cost:
                best["r"] = r
            return r.cost if r.ok else float(np.inf)

        m = qp.problem.m
        if m == 1:
            with np.errstate(invalid="ignore"):  # an infeasible trial returns inf; Brent's parabola is
                # then nan and it takes a golden-section step instead (the intended fallback, no warning)
                optimize.minimize_scalar(f, bounds=(lo[0], hi[0]), method="bounded",
                                         options={"xatol": self.refine_xtol * tf})
        else:
            simplex = np.vstack([t0] + [t0 + 0.5 * h * np.eye(m)[k] for k in range(m)])
            optimize.minimize(f, t0, method="Nelder-Mead",
                              options={"initial_simplex": simplex, "xatol": self.refine_xtol * tf,
                                       "fatol": 1e-14, "maxiter": 2000})
        return best["r"]

    def _plan(self, problem: Problem, r: CandidateResult | None, status: str, start: float,
              info: dict[str, Any]) -> Plan:
        ok = r is not None and status in st.SUCCESS and r.trajectory is not None
        m = problem.m
        res = Plan(problem=problem, planner="qp", status=status,
                   cost=r.cost if ok and r is not None else None,
                   contact_times=r.contact_times if r is not None else np.full(m, np.nan),
                   jumps=r.multipliers if ok and r is not None and r.multipliers is not None
                   else np.full((m, 2), np.nan),
                   trajectory=r.trajectory if ok and r is not None else None,
                   solve_time_s=time.perf_counter() - start, solver=self.solver, hold=self.hold,
                   steps=self.steps, diagnostics=QPDiagnostics(**QPDiagnostics.info_fields(info)))  # type: ignore[arg-type]
        if ok:
            res.residuals = {"boundary": res.boundary_residual(), "interior_constraint": res.corner_residual()}
        if r is not None and r.kkt is not None:
            res.residuals.update({f"kkt_{k}": v for k, v in r.kkt.as_dict().items() if k.endswith("_rel")})
        return res

    def plan(self, problem: Problem, qp: CandidateSolver | None = None,
             progress: Progress | None = None) -> Plan:
        """Sweep (and optionally refine) the contact times, then report the best QP."""
        start = time.perf_counter()
        qp = qp or self.build(problem)
        alone: dict[tuple[int, int], bool] | None = None
        extra = 0  # QP solves outside qp (the single-vehicle relaxations)
        box: Callable[[np.ndarray], str | None] | None = None
        known: dict[tuple[int, ...], CandidateResult] = {}
        witness: CandidateResult | None = None
        if problem.limits is not None and not problem.limits.empty:  # certified infeasible before any candidate
            from iamp.planners.qp.bounded import boundary_reason, box_screen, infeasible_before_sweep

            box = _memo(box_screen(problem))
            witness = self._witness(qp, box) if problem.m == 1 and boundary_reason(problem, problem.limits) is None \
                else None
            if witness is not None:
                known[witness.nodes] = witness
            early = None if witness is not None and witness.ok else \
                infeasible_before_sweep(problem, self.steps, self.hold, self.solver)
            if early is not None:
                reason, cert = early
                n = qp.n_candidates()
                early_info: dict[str, Any] = {
                    "path": self.path, "failures": [], "sweep": [], "unpolished": 0,
                    "candidates": {"total": n, "solved": 0, "failed": {"infeasible": n}, "inaccurate": 0,
                                   "certified_before_sweep": cert},
                    "n_solves": qp.n_solves + int(cert["qp_solves"]), "failed_check": "limits",
                    "reason": reason, "limits_infeasible": reason, **self._limits_info(qp)}
                return self._plan(problem, None, st.INFEASIBLE, start, early_info)
            if problem.m >= 2:  # each vehicle alone first: m (N - 1) solves that prune the joint sweep
                from iamp.planners.qp.bounded import single_vehicle_screen

                alone, alone_solves = single_vehicle_screen(problem, self.steps, self.hold, self.solver,
                                                            self.solver_settings)
                extra = alone_solves
                for i, v in enumerate(problem.vehicles):
                    if all((i, k) in alone for k in range(1, self.steps)):
                        n = qp.n_candidates()
                        reason = (f"vehicle {v.name} alone admits no contact node within the limits "
                                  f"({', '.join(problem.limits.given())}): {self.steps - 1} of {self.steps - 1} "
                                  f"nodes certified infeasible (Farkas), so are {n} of {n} candidate contact nodes")
                        info_alone: dict[str, Any] = {
                            "path": self.path, "failures": [], "sweep": [], "unpolished": 0,
                            "candidates": {"total": n, "solved": 0, "failed": {"infeasible": n}, "inaccurate": 0,
                                           "certified_before_sweep": {"method": "each vehicle alone (Farkas)",
                                                                      "qp_solves": alone_solves, "pmp_boxes": 0}},
                            "n_solves": qp.n_solves + alone_solves, "failed_check": "limits",
                            "reason": reason, "limits_infeasible": reason, **self._limits_info(qp)}
                        return self._plan(problem, None, st.INFEASIBLE, start, info_alone)
        sw = self.sweep(qp, progress, alone, box, known)
        cands = sw.candidates()
        if witness is not None:  # one vehicle with limits (:meth:`_witness`)
            cands["witness"] = {"nodes": list(witness.nodes), "verified": bool(witness.ok),
                                "certificate_skipped": bool(witness.ok)}
        info: dict[str, Any] = {"path": self.path, "sweep": sw.table, "failures": sw.failures,
                                "candidates": cands,
                                "unpolished": sum(r.polished is False for r in sw.results)}
        info.update(self._limits_info(qp))
        best = sw.best
        if best is None and sw.results and "limit_rows" in info:
            from iamp.planners.qp.bounded import infeasibility_reason

            n_cert = sum(r.infeasible_certified for r in sw.results)
            reason, whole = infeasibility_reason(problem, self.steps, self.hold, self.solver, len(sw.results),
                                                 n_cert)
            if whole or all(r.solver_status == st.INFEASIBLE for r in sw.results):
                info.update(n_solves=qp.n_solves + extra, failed_check="limits", reason=reason,
                            limits_infeasible=reason)
                return self._plan(problem, None, st.INFEASIBLE, start, info)
            info["reason"] = f"no candidate solved within the limits: {sw.candidates()['failed']}; {reason}"
        if best is None:
            failed = Counter(r.failed_check for r in sw.results if r.failed_check)
            worst = max(sw.results, key=lambda r: r.kkt.worst_rel()[1] if r.kkt is not None else -1.0)
            info.update(n_solves=qp.n_solves + extra, checks=_checks_of(worst),
                        failed_check=failed.most_common(1)[0][0] if failed else "sweep_candidates",
                        why="no candidate of the sweep solved to a verified optimum")
            return self._plan(problem, None, sw.failure_status(), start, info)
        info["grid_best"] = {"contact_times": best.contact_times.tolist(), "cost": best.cost}
        if self.contact == "refine":
            best = self._refine(qp, best)
        info["n_solves"] = qp.n_solves + extra
        checks = _checks_of(best)
        checks["sweep_candidates"] = {"value": len(sw.could_beat), "tol": 0, "ok": sw.certified}
        info["checks"] = checks
        if sw.certified:
            info["failed_check"] = None
            status = st.OPTIMAL
            if self.contact == "refine":
                cert = refine_certificate(problem, best, self.hold)
                info["refine_certificate"] = cert
                if not cert["global"]:
                    status = st.LOCAL
                    info["why"] = cert["reason"]
            return self._limits_checked(self._plan(problem, best, status, start, info))
        info["failed_check"] = "sweep_candidates"
        nodes, why_status, bound = min(sw.could_beat, key=lambda c: c[2])
        info["why"] = (f"{len(sw.could_beat)} candidate(s) without a verified solution could beat the best "
                       f"(J = {best.cost:.9g}): e.g. nodes {nodes} ({why_status}) has the lower bound "
                       f"J_PMP = {bound:.9g}")
        info["could_beat"] = [{"nodes": list(n), "status": s, "lower_bound": lb} for n, s, lb in sw.could_beat]
        info["best_unverified_search"] = {"contact_times": best.contact_times.tolist(), "cost": best.cost}
        return self._plan(problem, best, sw.failure_status(), start, info)

    @staticmethod
    def _limits_checked(plan: Plan) -> Plan:
        """SPEC §14: a bounded plan reports the largest violation of the ``vx`` and ``y`` bounds
        between the nodes (exact, :mod:`iamp.core.peaks`); beyond the bound tolerance an
        ``optimal`` plan becomes ``limits_violated`` with the reason."""
        lim = plan.problem.limits
        if lim is None or lim.empty or not plan.ok or plan.peaks is None:
            return plan
        between = {name: plan.peaks.peaks[name].violation for name in ("vx", "y")
                   if name in plan.peaks.peaks and plan.peaks.peaks[name].bound is not None}
        plan.annotate(limits_between_nodes=between)
        return plan.judge_limits("the QP imposes every bound at the grid nodes, so the excess lies between "
                                 "the grid nodes: use limits_between='certified' (--limits-between certified) "
                                 "or a larger N")

    def plan_at_nodes(self, problem: Problem, nodes: Sequence[int]) -> Plan:
        """Solve once with the contacts at given nodes of the uniform grid (no search)."""
        start = time.perf_counter()
        r = self.build(problem).solve_nodes(nodes)
        return self._single(problem, r, start)

    def plan_at_times(self, problem: Problem, times: Sequence[float]) -> Plan:
        """Solve once on a grid aligned with given contact times (no search)."""
        start = time.perf_counter()
        r = self.build(problem).solve_times(times)
        return self._single(problem, r, start)

    def _single(self, problem: Problem, r: CandidateResult, start: float) -> Plan:
        info: dict[str, Any] = {"path": self.path, "solver_time_s": r.solver_time_s, "polished": r.polished,
                                "iterations": r.iterations, "checks": _checks_of(r),
                                "failed_check": r.failed_check, "solver_status": r.raw_status}
        if problem.limits is not None and not problem.limits.empty and r.infeasible_certified:
            info["reason"] = "the QP at these contact times has no plan within the limits (Farkas certificate)"
        return self._plan(problem, r, r.status, start, info)


def plan_with(options: QPOptions, problem: Problem, /, progress: Progress | None = None) -> Plan:
    """``QPPlanner.from_options(options).plan(problem, progress=progress)``: the registry's one call
    (:func:`iamp.planners.registry.prepare`) that builds the planner and plans."""
    return QPPlanner.from_options(options).plan(problem, progress=progress)
