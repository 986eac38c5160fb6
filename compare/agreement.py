r"""Do the PMP and the QP baselines agree on one problem?  A comparison that can fail.

:func:`compare_problem` runs the PMP planner and every requested QP configuration
(:class:`QPConfig`: OSQP or Clarabel, FOH or ZOH, ``N`` steps, through cvxpy or the native
path, e.g. ``qp-clarabel-foh-100``) on the **same** :class:`~iamp.core.problem.Problem`
object, records a fingerprint of the problem each planner reports having solved (the exact
``x_poly`` coefficients, :func:`problem_fingerprint`), and judges every pair.

References
----------
A QP is never compared with the continuous optimum alone: the discretisation has an exact
reference at the QP's *own* contact times ``t_Q`` (grid nodes) —

* **FOH** is exact (SPEC §3.1): its reference is the PMP's fixed-time solution at ``t_Q``
  (:func:`iamp.planners.pmp.solve_fixed_times`), and on the grid the PMP's value function
  :math:`J(t)` (:class:`iamp.planners.pmp.ValueFunction`) is the exact sweep cost;
* **ZOH** restricts the input to piecewise constants; with the contact times on nodes the
  QP is the moment problem :math:`\min \tfrac12\int u^2` s.t. :math:`\int \varphi_j u = c_j`
  over piecewise-constant ``u``, with :math:`\varphi \in \{1,\ t_f-\tau,\ (t_i-\tau)_+\}`
  (final speed, final position, contact positions).  Its solution is
  :math:`u = \sum_j \mu_j \Pi_h\varphi_j` with :math:`(G - E)\mu = c`, where
  :math:`G_{jk} = \int\varphi_j\varphi_k` is the continuous (PMP) Gram matrix and
  :math:`E_{jk} = \int(\varphi_j - \Pi_h\varphi_j)(\varphi_k - \Pi_h\varphi_k)
  = \sum_k \tfrac{h_k^3}{12}\varphi_j'\varphi_k'` (each :math:`\varphi` is linear on every
  interval).  So :math:`J_{ZOH} = \tfrac12\sum_{axes} c^\top (G-E)^{-1} c` exactly, the
  multipliers are :math:`\nu_i = -\mu_i`, and (with :math:`\lambda = G^{-1}c`,
  the PMP's input :math:`u^* = \sum\lambda_j\varphi_j`, and
  :math:`\rho = \lambda_{\max}(G^{-1}E) = O(h^2)`)

  .. math::  \Delta_1 \le J_{ZOH} - J_{PMP} \le \frac{\Delta_1}{1-\rho},\qquad
             \Delta_1 = \tfrac12\lambda^\top E\lambda = \frac{h^2}{24}\int_0^{t_f}|\dot u^*|^2\,dt

  (uniform grid) — the ``O(h²)`` gap of SPEC §3.2 with its constant and a rigorous bracket
  (:func:`zoh_reference`).

Verdict rules (pair ``pmp`` / QP run; every rule must pass for ``agree``)
-------------------------------------------------------------------------
0. *Same problem*: both planners report the identical problem (fingerprints of the
   ``x_poly`` coefficients and of all other data are equal).
1. *Status*: both runs are ``optimal``.  The PMP's own conditions hold: every residual of
   :meth:`~iamp.planners.pmp.PMPSolution.residuals` ``≤ pmp_condition_residual·scale`` and the
   Hamiltonian-jump residual at ``t*`` ``≤ pmp_hjump_at_optimum·max(1, J*)``.
2. *Solver precision at the QP's contact times* ``t_Q``: cost, nodal states and inputs, and
   multipliers ``ν`` match the exact reference (FOH: the PMP at ``t_Q``; ZOH: the closed form)
   within the solver's ``cmp_cost_rel_*``, ``cmp_state_rel_*``, ``cmp_jump_rel_*``.
3. *KKT*: primal, dual and duality-gap residuals recomputed from the QP matrices and the
   returned primal/dual solution (:func:`iamp.planners.backends.kkt_residuals`; never the
   solver's own report) are below ``cmp_kkt_rel_*``.
4. *Constraints*: the QP trajectory's boundary and collision residuals are below
   ``cmp_residual_rel_*``.
5. *Search* (grid sweeps): the QP's candidate is the grid optimum of the exact sweep cost —
   ``J_ref(t_Q) ≤ min_grid J_ref + tol`` (ties within solver precision allowed).  For FOH this
   is "the sweep's best equals the PMP's global optimum restricted to the grid" (SPEC §3.4).
6. *Continuous optimum*: ``J_PMP(t_Q) ≥ J* − tol`` (the PMP's ``t*`` is a lower bound over the
   grid; this fails if the PMP missed the global minimum) and ``J_QP ≤ min J_ref`` over the
   ``2^m`` grid candidates bracketing ``t*`` ``+ tol`` (the sweep saw them).  The contact-time
   gap to ``t*`` is expected ``≤ h`` (not ``h/2``: of the two nodes bracketing ``t*`` the
   cheaper need not be the nearer when ``J`` is asymmetric); a larger gap with rule 6's cost
   bounds satisfied is a near-tie between basins and is reported as a note, not a failure.
   ``refine`` runs instead need, for FOH, ``|J_QP − J*| ≤ refine_cost_rel·J*``.
7. *ZOH only*: ``J_QP ≥ J_PMP(t_Q)`` and ``J_QP − J_PMP(t_Q)`` inside the bracket above.

Pairs of QP runs (same hold and ``N``, e.g. OSQP vs Clarabel, native vs cvxpy): rules 0–1,
rule 3 for each run at its own solver's tolerance, the same grid contact times (or equal costs
within precision: a tie), and cost, states and multipliers equal within the looser solver's
tolerances.

Signs (SPEC §2, identity 4) are reported for the PMP's ``Φ_i`` and every QP's ``ν_i`` through
:mod:`iamp.comparison.signs`.  That module derives the meaning from
:math:`\partial J/\partial \text{corner} = -\Phi`: ``Φ_x > 0`` means the unconstrained ego would
be *ahead of* the corner.  This differs from the parenthetical in SPEC §2.4 ("for a ``front``
corner, ``Φ_x > 0`` means the ego would otherwise be behind the corner"); the derivation is
kept (it is what identity 2 implies and what the numbers show: in ``paper-1-poly`` the
unconstrained ego is 2.8 m ahead of the corner at ``t*`` and ``Φ_x = +7.4``).

Headline numbers (SPEC §5b) compare the two runs **as they came out**, each at its own contact
times: ``cost_rel_gap = (J_QP − J_PMP)/|J_PMP|`` (``J_PMP`` at ``t*``), ``contact_time_gap =
max|t_Q − t*|``, ``state_sup_gap`` the sup-norm of the nodal state difference between the two
trajectories on the QP's grid, ``jump_gap = max|ν − Φ(t*)|`` (absolute).  The identity at the
QP's own contact times ``t_Q`` (the PMP re-solved there: FOH exact to solver precision, ZOH the
``O(h²)`` excess) goes under ``at_same_contact_times`` with the same four gaps and
``contact_time_gap_to_grid_optimum = max|t_Q − t_grid*|``.  ``verdict_basis`` says what the
verdict judged.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from iamp.comparison.fingerprints import problem_fingerprint, x_poly_fingerprint
from iamp.comparison.references import grid_cost_table, zoh_reference
from iamp.comparison.runs import QPConfig, Run, default_configs, run_pmp, run_qp
from iamp.core.plan import Plan
from iamp.core.problem import Problem, SurroundingVehicle
from iamp.core.tolerances import tol
from iamp.planners.pmp import ValueFunction, solve_fixed_times

__all__ = ["VERDICT_AGREE", "VERDICT_DISAGREE", "ProblemComparison", "QPConfig", "Run", "compare_pmp_qp",
           "compare_problem", "compare_qp_qp", "default_configs", "run_pmp", "run_qp"]

VERDICT_AGREE, VERDICT_DISAGREE = "agree", "disagree"


class _Checks:
    """Collects named checks ``value ≤ limit`` and free-text notes."""

    def __init__(self) -> None:
        self.items: dict[str, dict[str, Any]] = {}
        self.reasons: list[str] = []
        self.notes: list[str] = []

    def check(self, name: str, value: Any, limit: Any, ok: bool | None = None, why: str = "") -> bool:
        v = float(value) if value is not None else None
        lim = float(limit) if limit is not None else None
        if ok is None:
            ok = v is not None and lim is not None and bool(np.isfinite(v)) and v <= lim
        passed = bool(ok)
        self.items[name] = {"value": v, "limit": lim, "ok": passed}
        if not passed:
            self.reasons.append(f"{name}: {v:.3g} > {lim:.3g}" + (f" ({why})" if why else "")
                                if v is not None and lim is not None else f"{name} failed ({why})")
        return passed

    def fail(self, text: str) -> None:
        self.reasons.append(text)

    def verdict(self) -> str:
        return VERDICT_AGREE if not self.reasons else VERDICT_DISAGREE


def _solver_tol(kind: str, solver: str) -> float:
    return tol(f"cmp_{kind}_{solver}")


def _same_problem(a: Run, b: Run, checks: _Checks) -> None:
    if a.x_poly_fingerprint != b.x_poly_fingerprint:
        checks.fail(f"the planners received different x_poly (sha256 {a.x_poly_fingerprint[:12]} vs "
                    f"{b.x_poly_fingerprint[:12]})")
    elif a.fingerprint != b.fingerprint:
        checks.fail(f"the planners received different problem data (sha256 {a.fingerprint[:12]} vs "
                    f"{b.fingerprint[:12]})")


def _pmp_own_checks(pmp: Run, checks: _Checks) -> None:
    res = pmp.result
    cost = _cost(res)
    scale = max(1.0, abs(cost), float(np.max(np.abs(res.problem.ego.final))))
    for name in ("linear_system", "boundary", "interior_constraint", "h_minimisation", "costate_jump"):
        if name in res.residuals:
            checks.check(f"pmp_{name}_residual", res.residuals[name] / scale, tol("pmp_condition_residual"))
    if "hamiltonian_jump" in res.residuals:
        checks.check("pmp_hamiltonian_jump_at_t*", res.residuals["hamiltonian_jump"] / max(1.0, cost),
                     tol("pmp_hjump_at_optimum"))


def _cost(plan: Plan) -> float:
    """The cost of a verified plan (callers check ``Run.ok`` first)."""
    return float("nan") if plan.cost is None else float(plan.cost)


def _nodes_of(traj: Any, times: NDArray[np.float64]) -> list[int]:
    t_nodes = np.asarray(traj.t_nodes)
    return [int(np.argmin(np.abs(t_nodes - t))) for t in times]


def compare_pmp_qp(problem: Problem, pmp: Run, qp: Run,
                   tables: dict[tuple[int, str], tuple[Any, Any]] | None = None) -> dict[str, Any]:
    """Judge one ``pmp`` / QP pair (module docstring, rules 0–7).  ``tables`` caches
    :func:`grid_cost_table` results by ``(steps, hold)``."""
    checks = _Checks()
    cfg = qp.config
    out: dict[str, Any] = {"a": pmp.label, "b": qp.label, "cost_rel_gap": None, "contact_time_gap": None,
                           "state_sup_gap": None, "input_sup_gap": None, "jump_gap": None}
    _same_problem(pmp, qp, checks)
    if not pmp.ok:
        checks.fail(f"pmp status {pmp.result.status}")
    if not qp.ok:
        checks.fail(f"{qp.label} status {qp.result.status}")
    if not (pmp.ok and qp.ok) or cfg is None:
        out.update(verdict=checks.verdict(), reasons=checks.reasons, notes=checks.notes, checks=checks.items)
        return out
    _pmp_own_checks(pmp, checks)
    solver, hold = cfg.solver, cfg.hold
    res = qp.result
    traj = res.trajectory
    t_nodes = np.asarray(traj.t_nodes)
    N = len(t_nodes) - 1
    h_max = float(np.max(np.diff(t_nodes)))
    nodes = _nodes_of(traj, res.contact_times)
    tQ = t_nodes[nodes]
    if np.max(np.abs(tQ - res.contact_times)) > 1e-12 * problem.tf:
        checks.fail("the QP's contact times are not nodes of its grid")
    J_star, t_star = _cost(pmp.result), pmp.result.contact_times
    J_qp = _cost(res)
    # PMP at the QP's contact times (FOH's exact reference)
    pmp_at = solve_fixed_times(problem, tQ)
    J_pmp_tQ = pmp_at.cost()
    X_qp, U_qp = traj.states(t_nodes), traj.inputs(t_nodes)
    X_p, U_p = pmp_at.states(t_nodes), pmp_at.inputs(t_nodes)
    # SPEC §5b headline: run b against run a as they came out (each at its own contact times)
    X_run, U_run = pmp.result.trajectory.states(t_nodes), pmp.result.trajectory.inputs(t_nodes)
    out["cost_rel_gap"] = float((J_qp - J_star) / abs(J_star))
    out["contact_time_gap"] = float(np.max(np.abs(res.contact_times - pmp.result.contact_times)))
    out["state_sup_gap"] = float(np.max(np.abs(X_qp - X_run)))
    out["input_sup_gap"] = float(np.max(np.abs(U_qp - U_run)))
    out["jump_gap"] = float(np.max(np.abs(res.jumps - pmp.result.jumps)))
    # the identity at the QP's own contact times (FOH exact, SPEC §3.1): a separate, named key
    same: dict[str, Any] = {"reference": "PMP re-solved at the QP's contact times",
            "contact_times": [float(t) for t in tQ],
            "cost_rel_gap": float((J_qp - J_pmp_tQ) / abs(J_pmp_tQ)),
            "state_sup_gap": float(np.max(np.abs(X_qp - X_p))),
            "input_sup_gap": float(np.max(np.abs(U_qp - U_p))),
            "jump_gap": float(np.max(np.abs(res.jumps - pmp_at.jumps))),
            "nu_minus_phi": (res.jumps - pmp_at.jumps).tolist()}  # per vehicle (x, y), Φ at t_Q
    out["at_same_contact_times"] = same
    # the exact reference at t_Q
    if hold == "foh":
        ref: dict[str, Any] = {"cost": J_pmp_tQ, "X": X_p, "U": U_p, "nu": pmp_at.jumps,
                               "what": "PMP at the QP's contact times"}
        U_cmp = U_qp
    else:
        z = zoh_reference(problem, t_nodes, nodes)
        ref = {"cost": z["cost"], "X": z["X"], "U": z["U"], "nu": z["nu"],
               "what": "closed-form ZOH optimum at the QP's contact times"}
        U_cmp = np.asarray(traj.U)
    out["reference"] = ref["what"]
    # rule 2: solver precision
    checks.check("cost_vs_reference_rel", abs(J_qp - ref["cost"]) / abs(ref["cost"]),
                 _solver_tol("cost_rel", solver))
    xs = max(1.0, float(np.max(np.abs(ref["X"]))))
    checks.check("state_vs_reference_rel", np.max(np.abs(X_qp - ref["X"])) / xs, _solver_tol("state_rel", solver))
    us = max(1.0, float(np.max(np.abs(ref["U"]))))
    checks.check("input_vs_reference_rel", np.max(np.abs(U_cmp - ref["U"])) / us, _solver_tol("state_rel", solver))
    js = max(1.0, float(np.max(np.abs(ref["nu"]))))
    checks.check("jump_vs_reference_rel", np.max(np.abs(res.jumps - ref["nu"])) / js, _solver_tol("jump_rel", solver))
    # rule 3: KKT
    if qp.kkt is None:
        checks.fail("KKT residuals unavailable")
    else:
        for k in ("primal_rel", "dual_rel", "gap_rel"):
            checks.check(f"kkt_{k}", qp.kkt[k], _solver_tol("kkt_rel", solver))
    # rule 4: constraints
    bscale = max(1.0, float(np.max(np.abs(np.r_[problem.ego.initial, problem.ego.final]))))
    checks.check("boundary_residual_rel", res.boundary_residual() / bscale, _solver_tol("residual_rel", solver))
    checks.check("collision_residual_rel", res.corner_residual() / bscale, _solver_tol("residual_rel", solver))
    # signs
    out["signs"] = [_sign_entry(v, j[0]) for v, j in zip(problem.vehicles, res.jumps)]
    ctol = _solver_tol("cost_rel", solver)
    # rule 6 (lower bound, both contact searches): t* is the global optimum
    J_vf_tQ = float(ValueFunction(problem)(tQ[None, :])[0])
    checks.check("pmp_global_lower_bound", (J_star - J_vf_tQ) / abs(J_star), ctol,
                 why="the QP's candidate has a lower PMP cost than t*: the PMP's search missed the global optimum")
    cont: dict[str, Any] = {"h": h_max}
    if cfg.contact == "grid":
        key = (N, hold)
        if tables is not None and key in tables:
            cands, Jtab = tables[key]
        else:
            cands, Jtab = grid_cost_table(problem, N, hold)
            if tables is not None:
                tables[key] = (cands, Jtab)
        lookup = {tuple(c): j for c, j in zip(cands.tolist(), Jtab)}
        J_ref_tQ = lookup.get(tuple(nodes), np.inf)
        k_best = int(np.argmin(Jtab))
        J_grid_best = float(Jtab[k_best])
        # t_grid*: the PMP's optimum restricted to the grid (for the headline gap)
        uniform = np.linspace(0.0, problem.tf, N + 1)  # the QP's own grid
        if hold == "foh":
            t_grid_star = uniform[cands[k_best]]
        else:
            if tables is not None and (N, "foh") in tables:
                _, Jf = tables[(N, "foh")]
            else:
                _, Jf = grid_cost_table(problem, N, "foh")
                if tables is not None:
                    tables[(N, "foh")] = (cands, Jf)
            t_grid_star = uniform[cands[int(np.argmin(Jf))]]
        same["contact_time_gap_to_grid_optimum"] = float(np.max(np.abs(tQ - t_grid_star)))
        # rule 5: the sweep found the grid optimum of the exact sweep cost
        checks.check("search_grid_optimum_rel", (J_ref_tQ - J_grid_best) / abs(J_grid_best), ctol,
                     why="the QP's best candidate is not the grid optimum")
        # rule 6 (upper bound): the candidates bracketing t* were swept
        h = problem.tf / N
        lo = np.clip(np.floor(t_star / h).astype(int), 1, N - 1)
        hi = np.clip(np.ceil(t_star / h).astype(int), 1, N - 1)
        brackets = [c for c in itertools.product(*[sorted({int(a), int(b)}) for a, b in zip(lo, hi)])
                    if len(set(c)) == len(c)]
        if brackets:
            J_bracket = min(lookup.get(tuple(c), np.inf) for c in brackets)
            checks.check("bracket_upper_bound_rel", (J_qp - J_bracket) / abs(J_bracket), ctol,
                         why="the sweep's best is worse than a grid candidate bracketing t*")
            cont["bracket_cost"] = float(J_bracket)
            cont["bracket_nodes"] = [list(c) for c in brackets]
        if out["contact_time_gap"] > h * (1 + 1e-9):
            checks.notes.append(f"contact time {out['contact_time_gap']:.3g} s from t* (> h = {h:.3g} s): the grid "
                                "optimum lies in another basin with a cost within the grid resolution (near tie)")
    else:  # refine
        if hold == "foh":
            checks.check("refine_cost_vs_continuous_rel", abs(J_qp - J_star) / abs(J_star), tol("refine_cost_rel"))
    # rule 7: ZOH above PMP, gap inside the O(h²) bracket
    if hold == "zoh":
        gap = J_qp - J_pmp_tQ
        lower, rho = z["gap_leading"], z["rho"]
        upper = lower / (1 - rho) if rho < 1 else np.inf
        slack = ctol * abs(J_pmp_tQ)
        checks.check("zoh_above_pmp", -gap / abs(J_pmp_tQ), ctol, why="ZOH cost below the PMP's at the same times")
        checks.check("zoh_gap_in_bracket", 0.0, 0.0, ok=(lower - slack <= gap <= upper + slack),
                     why=f"gap {gap:.6g} outside [{lower:.6g}, {upper:.6g}]")
        out["zoh_gap"] = {"gap": float(gap), "leading_h2_term": float(lower), "upper_bound": float(upper),
                          "rho": float(rho), "ratio_to_leading": float(gap / lower) if lower > 0 else None}
    out["continuous"] = cont
    out["verdict_basis"] = ("solver precision at the QP's own contact times (at_same_contact_times), KKT and "
                            "constraint residuals, and the contact-time search rules against the PMP's t*")
    if res.info.get("failures"):
        checks.notes.append(f"{len(res.info['failures'])} sweep candidate(s) failed "
                            f"({', '.join(sorted({str(s) for _, s in res.info['failures']}))}); the best is taken "
                            "among the rest")
    out.update(verdict=checks.verdict(), reasons=checks.reasons, notes=checks.notes, checks=checks.items)
    return out


def compare_qp_qp(problem: Problem, a: Run, b: Run) -> dict[str, Any]:
    """Judge two QP runs with the same hold and ``N`` (e.g. OSQP vs Clarabel)."""
    checks = _Checks()
    out: dict[str, Any] = {"a": a.label, "b": b.label, "cost_rel_gap": None, "contact_time_gap": None,
           "state_sup_gap": None, "input_sup_gap": None, "jump_gap": None}
    _same_problem(a, b, checks)
    for r in (a, b):
        if not r.ok:
            checks.fail(f"{r.label} status {r.result.status}")
    if a.ok and b.ok and a.config is not None and b.config is not None:
        ra, rb = a.result, b.result
        ca, cb = a.config, b.config
        for r in (a, b):  # both must be KKT points at their own solver's precision
            if r.kkt is None:
                checks.fail(f"{r.label}: KKT residuals unavailable")
            else:
                for k in ("primal_rel", "dual_rel", "gap_rel"):
                    checks.check(f"{r.label}_kkt_{k}", r.kkt[k], _solver_tol("kkt_rel", (ca if r is a else cb).solver))
        loose = "osqp" if "osqp" in (ca.solver, cb.solver) else "clarabel"
        ctol = _solver_tol("cost_rel", loose)
        cost_gap = (_cost(rb) - _cost(ra)) / abs(_cost(ra))
        out["cost_rel_gap"] = float(cost_gap)
        dt = float(np.max(np.abs(ra.contact_times - rb.contact_times)))
        out["contact_time_gap"] = dt
        checks.check("cost_rel", abs(cost_gap), ctol)
        if dt > tol("cmp_node_time_rel") * problem.tf and ca.contact == "grid":
            checks.notes.append("different grid candidates with equal costs (a tie within solver precision)")
        else:
            tn = np.asarray(ra.trajectory.t_nodes)
            Xa, Xb = ra.trajectory.states(tn), rb.trajectory.states(tn)
            Ua, Ub = ra.trajectory.inputs(tn), rb.trajectory.inputs(tn)
            dx = float(np.max(np.abs(Xa - Xb)))
            du = float(np.max(np.abs(Ua - Ub)))
            dj = float(np.max(np.abs(ra.jumps - rb.jumps)))
            out.update(state_sup_gap=dx, input_sup_gap=du, jump_gap=dj)
            checks.check("state_rel", dx / max(1.0, float(np.max(np.abs(Xa)))), _solver_tol("state_rel", loose))
            checks.check("input_rel", du / max(1.0, float(np.max(np.abs(Ua)))), _solver_tol("state_rel", loose))
            checks.check("jump_rel", dj / max(1.0, float(np.max(np.abs(ra.jumps)))), _solver_tol("jump_rel", loose))
    out.update(verdict=checks.verdict(), reasons=checks.reasons, notes=checks.notes, checks=checks.items)
    return out


def _sign_entry(vehicle: SurroundingVehicle, phi_x: float) -> dict[str, Any]:
    from iamp.comparison.signs import constraint_is_binding_for_safety, jump_meaning

    return {"vehicle": vehicle.name, "corner": vehicle.corner, "phi_x": float(phi_x),
            "sign": int(np.sign(phi_x)), "binding_for_safety": bool(constraint_is_binding_for_safety(vehicle, phi_x)),
            "meaning": jump_meaning(vehicle, phi_x)}


# --------------------------------------------------------------------------------------
# One problem, every configuration
# --------------------------------------------------------------------------------------


@dataclass
class ProblemComparison:
    """Runs and verdicts of one problem (:func:`compare_problem`)."""

    name: str
    problem: Problem
    runs: list[Run]
    agreement: list[dict[str, Any]]
    timing: dict[str, Any] = field(default_factory=dict)

    @property
    def all_agree(self) -> bool:
        """Every pair's verdict is ``agree``."""
        return all(a["verdict"] == VERDICT_AGREE for a in self.agreement)

    @property
    def any_failed(self) -> bool:
        """Some run did not finish with a verified optimum."""
        return any(not r.ok for r in self.runs)

    def run(self, label: str) -> Run:
        """The run with this label."""
        for r in self.runs:
            if r.label == label:
                return r
        raise KeyError(label)

    def pair(self, a: str, b: str) -> dict[str, Any]:
        """The verdict of the pair ``(a, b)``."""
        for p in self.agreement:
            if p["a"] == a and p["b"] == b:
                return p
        raise KeyError((a, b))

    def to_json(self) -> dict[str, Any]:
        """One entry of SPEC §5b's ``scenarios``."""
        pmp = next((r for r in self.runs if r.planner == "pmp"), None)
        out: dict[str, Any] = {"name": self.name, "m": self.problem.m,
               "x_poly": [list(map(float, v.x_poly)) for v in self.problem.vehicles],
               "x_poly_sha256": x_poly_fingerprint(self.problem),
               "problem_sha256": problem_fingerprint(self.problem),
               "runs": [r.to_json() for r in self.runs],
               "agreement": self.agreement}
        if pmp is not None and pmp.ok:
            out["pmp"] = {
                "signs": [_sign_entry(v, j[0]) for v, j in zip(self.problem.vehicles, pmp.result.jumps)],
                "hamiltonian_jump_residuals": [float(r) for r in
                                               pmp.result.trajectory.hamiltonian_jump_residual()],
            }
        if self.timing:
            out["timing"] = self.timing
        return out


def compare_problem(problem: Problem, configs: Iterable[QPConfig], name: str | None = None, repeats: int = 3,
                    pmp_repeats: int | None = None, budget_s: float = 30.0,
                    problems: dict[str, Problem] | None = None,
                    qp_pairs: bool = True, warmup: int = 1,
                    progress: Callable[[int, int], None] | None = None) -> ProblemComparison:
    """Run the PMP and every QP configuration on ``problem`` and judge every pair.

    Parameters
    ----------
    problem : Problem
        Given, as the same object, to every planner.
    configs : iterable of QPConfig
    repeats : int
        Timed full plans per QP configuration (after one warm-up; see
        :func:`iamp.comparison.timing.measure` for ``budget_s``).
    pmp_repeats : int, optional
        Timed PMP plans (default ``max(20, 10·repeats)``; the PMP is cheap).
    warmup : int
        Untimed plans before the timed ones (each configuration).
    problems : dict, optional
        ``label → Problem`` to hand a *different* problem to one planner (used to test that
        the identical-problem check catches it).
    qp_pairs : bool
        Also judge OSQP/Clarabel and native/cvxpy pairs of the same hold and ``N``.
    progress : callable, optional
        Called as ``progress(done, total)`` after each run (the PMP and every configuration).
    """
    problems = problems or {}
    configs = list(configs)
    runs = [run_pmp(problems.get("pmp", problem), pmp_repeats or max(20, 10 * repeats), warmup=max(warmup, 1))]
    if progress is not None:
        progress(1, len(configs) + 1)
    for k, cfg in enumerate(configs):
        runs.append(run_qp(problems.get(cfg.label, problem), cfg, repeats=repeats, warmup=warmup, budget_s=budget_s))
        if progress is not None:
            progress(k + 2, len(configs) + 1)
    pmp = runs[0]
    tables: dict[tuple[int, str], tuple[Any, Any]] = {}
    agreement = [compare_pmp_qp(problem, pmp, r, tables) for r in runs[1:]]
    if qp_pairs:
        qps = runs[1:]
        for a, b in itertools.combinations(qps, 2):
            ca, cb = a.config, b.config
            if ca is not None and cb is not None and (ca.hold, ca.steps, ca.contact) == (cb.hold, cb.steps, cb.contact):
                agreement.append(compare_qp_qp(problem, a, b))
    return ProblemComparison(name or problem.name, problem, runs, agreement)
