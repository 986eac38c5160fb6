"""The typed diagnostics of every planner family (issue 18 item 3).

Each test plans a problem and recomputes, independently of the planner's code path, the
quantities its diagnostics report: the PMP's corner / boundary / H-minimisation residuals from the
plan's own trajectory and co-states; the equality QP's KKT residuals from the QP data and the
primal/dual pair (dense numpy); the avoidance QP's four KKT residuals from the final QP it kept;
the bounded PMP's input peaks from a dense sampling of its inputs; the active set's imposed
vehicles from the plan's contact times.  A hypothesis property over generated scenarios checks
that the deprecated ``Plan.info`` view is the diagnostics, key for key, and that a plan built the
old way (``Plan(info=...)``) writes the same JSON.
"""

from __future__ import annotations

import math
import os
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from iamp.core.diagnostics import Diagnostics
from iamp.core.physical import PhysicalLimits
from iamp.core.plan import Plan
from iamp.core.problem import EgoBoundary, Problem, SurroundingVehicle
from iamp.core.scenario import load_scenario
from iamp.core.status import LOCAL, OPTIMAL, SUCCESS
from iamp.core.tolerances import TOLERANCES
from iamp.planners.active_set import ActiveSetPlanner
from iamp.planners.avoid.diagnostics import AvoidDiagnostics
from iamp.planners.avoid.planner import AvoidQPPlanner
from iamp.planners.diagnostics import ActiveSetDiagnostics
from iamp.planners.pmp.diagnostics import BoundedPMPDiagnostics, PMPDiagnostics
from iamp.planners.pmp.planner import PMPPlanner
from iamp.planners.pmp.scale import scale_problem
from iamp.planners.pmp.verify import TOLERANCE_OF
from iamp.planners.qp.core import DiscretisedQP
from iamp.planners.qp.diagnostics import QPDiagnostics
from iamp.planners.qp.planner import QPPlanner

EXAMPLES = {"ci": 10, "dev": 200}.get(os.environ.get("HYPOTHESIS_PROFILE", "ci"), 10)
SETTINGS = settings(max_examples=EXAMPLES, deadline=None, derandomize=os.environ.get("HYPOTHESIS_PROFILE") is None,
                    suppress_health_check=[HealthCheck.too_slow])


def lane_change(tf: float = 5.0, vx0: float = 20.0, dx: float = 0.0, c0: float = -15.0, dv: float = -2.0,
                second: bool = False) -> Problem:
    """A lane change by 3.75 m with a vehicle behind in the target lane (and one ahead)."""
    ego = EgoBoundary(tf=tf, x0=0.0, y0=0.0, vx0=vx0, xf=vx0 * tf + dx, yf=3.75, vxf=vx0)
    vs = [SurroundingVehicle(x_poly=(c0, vx0 + dv), corner="front-lower", y=3.75, length=4.8, width=1.8,
                             safety_x=2.0, safety_y=0.3, name="sv1")]
    if second:
        vs.append(SurroundingVehicle(x_poly=(45.0, vx0 - 4.0), corner="rear-upper", y=0.0, length=4.8, width=1.8,
                                     safety_x=2.0, safety_y=0.3, name="sv2"))
    return Problem(ego, tuple(vs), "diag")


@st.composite
def problems(draw: st.DrawFn) -> Problem:
    f = st.floats
    return lane_change(tf=draw(f(3.0, 7.0)), vx0=draw(f(10.0, 30.0)), dx=draw(f(-10.0, 15.0)),
                       c0=draw(f(-35.0, -8.0)), dv=draw(f(-6.0, 2.0)), second=draw(st.booleans()))


# --- the PMP ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("second", [False, True])
def test_pmp_diagnostics_are_the_residuals_of_its_trajectory(second: bool) -> None:
    prob = lane_change(second=second)
    plan = PMPPlanner().plan(prob)
    d = plan.diagnostics
    assert isinstance(d, PMPDiagnostics) and plan.status == OPTIMAL and d.certified_global is True
    assert d.checks is not None and d.failed_check is None and d.search is not None
    u = scale_problem(prob).units
    t = plan.contact_times
    X = plan.states(t)
    # recomputed from the trajectory: s(t_i) = c_i(t_i), the boundary states, u = -p_v at the breakpoints
    corner = float(np.max(np.abs(X[:, [0, 2]] - prob.corners(t)))) / u.L
    ends = plan.states(np.array([0.0, prob.tf]))
    scale = np.array([u.L, u.vel, u.L, u.vel])
    boundary = float(max(np.max(np.abs(ends[0] - prob.ego.initial) / scale),
                         np.max(np.abs(ends[1] - prob.ego.final) / scale)))
    bp = np.r_[0.0, t, prob.tf]
    sol = plan.require_trajectory()
    p = sol.costates(bp)  # type: ignore[attr-defined]
    h_min = float(np.max(np.abs(plan.inputs(bp) + p[:, [1, 3]]))) / u.acc
    for name, value in (("corner", corner), ("boundary", boundary), ("h_minimisation", h_min)):
        check = d.checks[name]
        assert check["tol"] == TOLERANCES[TOLERANCE_OF[name]]
        assert check["ok"] is True and value <= check["tol"]
        assert abs(check["value"] - value) <= 1e-3 * check["tol"], (name, check["value"], value)
    # every check is judged against its own tolerance
    assert all(c["ok"] == (c["value"] <= c["tol"]) for c in d.checks.values())


def test_bounded_pmp_diagnostics_report_the_sampled_peaks() -> None:
    base = load_scenario("paper-1-poly").to_problem()[0]
    free = PMPPlanner().plan(base)
    a = 0.9 * float(np.max(np.abs(free.inputs(np.linspace(0.0, base.tf, 4001))[:, 0])))
    prob = base.with_limits(PhysicalLimits(ax=(-a, a)))
    plan = PMPPlanner().plan(prob)
    d = plan.diagnostics
    assert isinstance(d, BoundedPMPDiagnostics) and plan.status in SUCCESS, (plan.status, type(d))
    assert d.bounded is not None and d.bounded["box_active"] is True and d.search is not None
    assert d.unbounded is not None and d.unbounded["cost"] == free.cost and d.unbounded["status"] == free.status
    assert plan.cost is not None and free.cost is not None and plan.cost >= free.cost  # J_b >= J_u
    assert d.limits is not None and d.limits["ax"]["ok"] is True and d.limits_violated is None
    ax = plan.inputs(np.linspace(0.0, prob.tf, 20001))[:, 0]
    lo, hi = d.limits["ax"]["peak"]
    # the exact peaks bracket the dense sampling, are attained up to the sampling step, and hold the box
    assert lo <= ax.min() + 1e-9 and hi >= ax.max() - 1e-9
    assert ax.min() - lo <= 1e-3 and hi - ax.max() <= 1e-3
    assert -a * (1 + 1e-6) <= lo and hi <= a * (1 + 1e-6)


# --- the equality QP ---------------------------------------------------------------------------------
@pytest.mark.parametrize("solver", ["clarabel", "osqp"])
def test_qp_diagnostics_are_the_kkt_residuals_of_its_data(solver: str) -> None:
    prob = lane_change()
    N = 30
    planner = QPPlanner(steps=N, hold="foh", solver=solver)
    plan = planner.plan(prob)
    d = plan.diagnostics
    assert isinstance(d, QPDiagnostics) and plan.status == OPTIMAL and d.checks is not None
    assert d.candidates is not None and d.candidates["total"] == math.perm(N - 1, prob.m)
    assert d.sweep is not None and d.failures is not None
    assert len(d.sweep) == d.candidates["solved"] == d.candidates["total"] - len(d.failures)
    assert d.grid_best is not None and d.grid_best["cost"] == pytest.approx(min(c for _, c in d.sweep), rel=1e-12)
    assert plan.cost == pytest.approx(d.grid_best["cost"], rel=1e-12)
    assert d.n_solves is not None and d.n_solves >= d.candidates["total"]
    # the KKT residuals of the best candidate, recomputed from (P, A, b) and (z, y) in dense numpy
    nodes = min(d.sweep, key=lambda e: e[1])[0]
    qp = DiscretisedQP(prob, N, "foh", solver, None)
    r = qp.solve_nodes(nodes)
    assert r.z is not None and r.y is not None
    P = qp.data.P.toarray()
    P = P + np.triu(P, 1).T if np.allclose(np.tril(P, -1), 0.0) else P
    A, b, z, y = qp.data.A.toarray(), qp.data.b, r.z, r.y
    Pz, Az, Aty = P @ z, A @ z, A.T @ y
    primal = np.max(np.abs(Az - b)) / max(1.0, np.max(np.abs(Az)), np.max(np.abs(b)))
    dual = np.max(np.abs(Pz + Aty)) / max(1.0, np.max(np.abs(Pz)), np.max(np.abs(Aty)))
    gap = abs(z @ Pz + b @ y) / max(1.0, abs(z @ Pz), abs(b @ y))
    for name, value in (("kkt_primal_rel", primal), ("kkt_dual_rel", dual), ("kkt_gap_rel", gap)):
        check = d.checks[name]
        assert check["ok"] is True and value <= check["tol"]
        assert abs(check["value"] - value) <= 1e-3 * check["tol"], (name, check["value"], value)
    assert d.checks["sweep_candidates"]["ok"] is True and d.failed_check is None


# --- the avoidance QP -----------------------------------------------------------------------------------
def test_avoid_diagnostics_are_the_kkt_residuals_of_its_final_qp() -> None:
    prob = lane_change(c0=-12.0, dv=1.0)
    plan = AvoidQPPlanner(steps=40, hold="foh", solver="clarabel", safety="nodes").plan(prob)
    d = plan.diagnostics
    assert isinstance(d, AvoidDiagnostics) and d.constraint == "avoid"
    assert d.kkt is not None and d.kkt_tol is not None and d.qp_solution is not None and d.avoidance is not None
    s: Any = d.qp_solution
    P = s.data.P.toarray()
    P = P + np.triu(P, 1).T
    A, z, y, l, u = s.data.A.toarray(), s.z, s.y, s.l, s.u
    n_eq = s.data.n_eq
    Pz, Az, Aty = P @ z, A @ z, A.T @ y
    stat = np.max(np.abs(Pz + s.data.q + Aty)) / max(1.0, np.max(np.abs(Pz)), np.max(np.abs(Aty)))
    viol = np.maximum(np.maximum(l - Az, Az - u), 0.0)
    finite = np.r_[np.abs(l[np.isfinite(l)]), np.abs(u[np.isfinite(u)])]
    primal = np.max(viol) / max(1.0, np.max(np.abs(Az)), np.max(finite))
    yi = y[n_eq:]
    sign = np.max(np.maximum(-yi, 0.0), initial=0.0) / max(1.0, np.max(np.abs(y)))
    compl = np.max(np.abs(yi) * np.maximum(u[n_eq:] - Az[n_eq:], 0.0), initial=0.0) / max(1.0, abs(z @ Pz))
    recomputed = {"kkt_stationarity_rel": stat, "kkt_primal_rel": primal, "kkt_dual_sign_rel": sign,
                  "kkt_complementarity_rel": compl}
    for name, value in recomputed.items():
        assert abs(d.kkt[name] - value) <= 1e-3 * d.kkt_tol, (name, d.kkt[name], value)
    failed = [k for k, v in recomputed.items() if v > d.kkt_tol]
    assert [k for k in (d.failed_checks or []) if k.startswith("kkt")] == failed
    assert (plan.status in (OPTIMAL, LOCAL)) == (not d.failed_checks)
    assert d.avoidance["kkt"] == d.kkt and d.avoidance["n_solves"] == d.n_solves


# --- the active set -------------------------------------------------------------------------------------
def test_active_set_diagnostics_name_the_imposed_vehicles() -> None:
    prob = lane_change(second=True)
    plan = ActiveSetPlanner(PMPPlanner()).plan(prob)
    d = plan.diagnostics
    assert isinstance(d, ActiveSetDiagnostics) and d.constraint == "active" and d.active_set is not None
    imposed = {v["name"] for v in d.active_set["imposed"]}
    with_contact = {v.name for v, t in zip(prob.vehicles, plan.contact_times) if np.isfinite(t)}
    assert imposed == with_contact
    assert {v["name"] for v in d.active_set["dropped"]} | imposed <= {v.name for v in prob.vehicles}
    if imposed:
        base = d.find(PMPDiagnostics)
        assert base is not None and base is d.base and base.checks == d.checks
    assert plan.to_json()["active_set"] == d.active_set


# --- the deprecated info view ---------------------------------------------------------------------------
def _assert_view(plan: Plan) -> None:
    d = plan.diagnostics
    info = plan.info
    with pytest.raises(TypeError):
        info["reason"] = "x"  # type: ignore[index]
    names = set(d.field_names())
    for key, value in info.items():
        assert (getattr(d, key) is value) if key in names else (d.extra[key] is value)
    for key in names - {"base"}:
        if getattr(d, key) is not None:
            assert info[key] is getattr(d, key)
    assert type(d).from_info(info).as_info() == dict(info)
    old = Plan(problem=plan.problem, planner=plan.planner, status=plan.status, cost=plan.cost,
               contact_times=plan.contact_times, jumps=plan.jumps, trajectory=plan.trajectory,
               solve_time_s=plan.solve_time_s, residuals=plan.residuals, solver=plan.solver, hold=plan.hold,
               steps=plan.steps, info=dict(info))
    assert isinstance(old.diagnostics, Diagnostics) and dict(old.info) == dict(info)
    assert old.to_json(steps=20) == plan.to_json(steps=20)


@SETTINGS
@given(problems(), st.sampled_from(["pmp", "qp", "avoid", "active"]))
def test_info_view_is_the_diagnostics(prob: Problem, which: str) -> None:
    planner: Any = {"pmp": PMPPlanner(), "qp": QPPlanner(steps=16, hold="foh", solver="clarabel"),
               "avoid": AvoidQPPlanner(steps=16, hold="foh", solver="clarabel"),
               "active": ActiveSetPlanner(PMPPlanner())}[which]
    plan = planner.plan(prob)
    expected = {"pmp": PMPDiagnostics, "qp": QPDiagnostics, "avoid": AvoidDiagnostics,
                "active": ActiveSetDiagnostics}[which]
    assert isinstance(plan.diagnostics, expected)
    _assert_view(plan)


def test_annotate_keeps_the_diagnostics_frozen_and_typed() -> None:
    plan = PMPPlanner().plan(lane_change())
    before = plan.diagnostics
    plan.annotate(reason="why", constrained=["sv1"])
    assert isinstance(plan.diagnostics, PMPDiagnostics) and plan.diagnostics is not before
    assert before.reason is None and plan.diagnostics.reason == "why"
    assert plan.diagnostics.extra["constrained"] == ["sv1"] and list(plan.info)[-2:] == ["reason", "constrained"]
    with pytest.raises(AttributeError):
        plan.diagnostics.reason = "x"  # type: ignore[misc]
    with pytest.raises(ValueError, match="either diagnostics or info"):
        Plan(problem=plan.problem, planner="pmp", status=OPTIMAL, cost=1.0, contact_times=plan.contact_times,
             jumps=plan.jumps, trajectory=None, diagnostics=before, info={"reason": "x"})
