"""The bounded equality QP (SPEC §14): the bounds hold, the answers agree with an independent
cvxpy formulation on another solver, infeasibility is certified and explained, the
between-node violation falls with N, and the self-check catches wrong multipliers."""

from __future__ import annotations

import json
import math

import cvxpy as cp
import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from iamp.core import status as sts
from iamp.core.errors import IampError
from iamp.core.physical import PASSENGER_CAR, PhysicalLimits
from iamp.core.problem import Problem
from iamp.planners.examples import random_problem
from iamp.planners.qp import QPPlanner
from iamp.planners.qp.backends.base import farkas_residuals
from iamp.planners.qp.bounded import BoundedQP, complementarity
from iamp.planners.qp.data import QPData
from iamp.prediction.resolve import load_problem

BACKENDS = ("clarabel", "osqp", "piqp")


# --- an independent formulation: the bounded QP written directly in cvxpy ------------------
def cvxpy_bounded(problem: Problem, N: int, hold: str, nodes: tuple[int, ...], solver: str,
                  between: str = "nodes") -> tuple[str, float | None]:
    """SPEC §3's QP with SPEC §14's bounds at every node, from the SPEC text alone: per axis
    s, v (N+1) and u (N ZOH, N+1 FOH), exact double-integrator steps, the corner at node k_i,
    the friction circle as the inscribed regular 16-gon with vertices at angles (2j+1)π/16."""
    lim = problem.limits
    assert lim is not None
    tf = problem.tf
    h = tf / N
    nu = N if hold == "zoh" else N + 1
    s = [cp.Variable(N + 1) for _ in range(2)]
    v = [cp.Variable(N + 1) for _ in range(2)]
    u = [cp.Variable(nu) for _ in range(2)]
    e = problem.ego
    cons = []
    ends = ((e.x0, e.vx0, e.xf, e.vxf), (e.y0, e.vy0, e.yf, e.vyf))
    cost = 0
    for a in range(2):
        if hold == "zoh":
            cons += [s[a][1:] == s[a][:-1] + h * v[a][:-1] + h**2 / 2 * u[a], v[a][1:] == v[a][:-1] + h * u[a]]
            cost += 0.5 * h * cp.sum_squares(u[a])
        else:
            cons += [s[a][1:] == s[a][:-1] + h * v[a][:-1] + h**2 * (u[a][:-1] / 3 + u[a][1:] / 6),
                     v[a][1:] == v[a][:-1] + h / 2 * (u[a][:-1] + u[a][1:])]
            # (a² + ab + b²)/6 = (a + b)²/8 + (a − b)²/24
            cost += h / 8 * cp.sum_squares(u[a][:-1] + u[a][1:]) + h / 24 * cp.sum_squares(u[a][:-1] - u[a][1:])
        s0, v0, sf, vf = ends[a]
        cons += [s[a][0] == s0, v[a][0] == v0, s[a][N] == sf, v[a][N] == vf]
    for veh, k in zip(problem.vehicles, nodes):
        cons += [s[0][k] == float(veh.corner_x(k * h)), s[1][k] == veh.corner_y]
    if lim.ax is not None:
        cons += [u[0] >= lim.ax[0], u[0] <= lim.ax[1]]
    if lim.ay is not None:
        cons += [u[1] >= lim.ay[0], u[1] <= lim.ay[1]]
    if lim.a_total is not None:
        M = 16
        verts = [(lim.a_total * math.cos((2 * j + 1) * math.pi / M), lim.a_total * math.sin((2 * j + 1) * math.pi / M))
                 for j in range(M)]
        for j in range(M):  # the edge from vertex j to j+1: the origin's side of the line
            (x1, y1), (x2, y2) = verts[j], verts[(j + 1) % M]
            nx, ny = y2 - y1, -(x2 - x1)  # outward normal (counter-clockwise polygon)
            cons.append(nx * u[0] + ny * u[1] <= nx * x1 + ny * y1)
    if lim.vx is not None:
        cons += [v[0] >= lim.vx[0], v[0] <= lim.vx[1]]
    if lim.y is not None:
        cons += [s[1] >= lim.y[0], s[1] <= lim.y[1]]
    if lim.jerk is not None:
        for a in range(2):
            cons += [cp.abs(cp.diff(u[a])) <= lim.jerk * h]
    prob = cp.Problem(cp.Minimize(cost), cons)
    try:
        prob.solve(solver=solver)
    except cp.error.SolverError:
        return "solver_error", None
    return str(prob.status), (float(prob.value) if prob.status == "optimal" else None)


def _box_from_peaks(problem: Problem, shrink: float, vx_lo: float | None = None) -> PhysicalLimits:
    """Bounds cut from the unbounded plan's own peaks (so that some bind and some candidates
    stay feasible)."""
    plan = QPPlanner(steps=20).plan(problem)
    pk = plan.peaks
    assert pk is not None
    U = plan.trajectory.U
    ax = (min(-0.1, shrink * float(U[:, 0].min())), max(0.1, shrink * float(U[:, 0].max())))
    ay = (min(-0.1, shrink * float(U[:, 1].min())), max(0.1, shrink * float(U[:, 1].max())))
    return PhysicalLimits(ax=ax, ay=ay, a_total=max(0.5, 1.2 * shrink * float(pk.peaks["a_total"].peak)),  # type: ignore[arg-type]
                          vx=(vx_lo if vx_lo is not None else 0.0, 50.0), jerk=None)


# --- agreement with the independent formulation over a grid of cases -----------------------
@pytest.mark.parametrize("seed", [0, 1, 2, 3])
@pytest.mark.parametrize("hold", ["foh", "zoh"])
def test_bounded_qp_equals_independent_cvxpy(seed: int, hold: str) -> None:
    problem = random_problem(seed)
    lim = _box_from_peaks(problem, 0.85)
    if hold == "foh":
        lim = PhysicalLimits(ax=lim.ax, ay=lim.ay, a_total=lim.a_total, vx=lim.vx, jerk=40.0)
    p = problem.with_limits(lim)
    N = 16
    for solver, ref in (("clarabel", "PIQP"), ("osqp", "CLARABEL"), ("piqp", "CLARABEL")):
        qp = BoundedQP(p, N, hold, solver)
        n_ok = n_inf = 0
        for k in range(1, N):
            r = qp.solve_nodes([k])
            status, cost = cvxpy_bounded(p, N, hold, (k,), ref)
            if r.ok:
                n_ok += 1
                assert status == "optimal", (solver, k, status)
                assert r.cost == pytest.approx(cost, rel=1e-6, abs=1e-7), (solver, k)
            elif r.infeasible_certified:
                n_inf += 1
                if status == "user_limit":  # PIQP does not detect infeasibility: ask SCS (homogeneous embedding)
                    status = cvxpy_bounded(p, N, hold, (k,), "SCS")[0]
                assert status.startswith("infeasible"), (solver, k, status)
            else:
                assert solver == "piqp" or status != "optimal", (solver, k, r.status, status)
        assert n_ok >= 1


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(0, 10**5), st.sampled_from(["foh", "zoh"]), st.floats(0.5, 1.0), st.sampled_from(BACKENDS))
def test_bounded_plan_holds_every_bound(seed: int, hold: str, shrink: float, solver: str) -> None:
    """An optimal bounded plan satisfies every bound at every node (the limit rows) and its
    exact peaks of the inputs everywhere; it costs no less than the unbounded plan."""
    problem = random_problem(seed)
    lim = _box_from_peaks(problem, shrink)
    p = problem.with_limits(lim)
    plan = QPPlanner(steps=16, hold=hold, solver=solver).plan(p)
    free = QPPlanner(steps=16, hold=hold, solver=solver).plan(problem)
    if plan.status != sts.OPTIMAL:
        assert plan.status in (sts.INFEASIBLE, sts.INACCURATE, sts.LIMITS_VIOLATED, sts.MAX_ITER)
        return
    pk = plan.peaks
    assert pk is not None and pk.within
    for name in ("ax", "ay", "a_total"):
        assert pk.peaks[name].ok
    assert plan.cost is not None and free.cost is not None
    assert plan.cost >= free.cost * (1 - 1e-7)
    # the polygon is inside the circle: |u| <= a_total everywhere, with room cos(π/16)
    assert pk.peaks["a_total"].peak <= lim.a_total * (1 + 1e-7)  # type: ignore[operator]


def test_backends_agree_on_a_binding_case() -> None:
    _, p, _ = load_problem("paper-1-poly")
    p = p.with_limits(PASSENGER_CAR)
    costs = {}
    for solver in BACKENDS:
        plan = QPPlanner(steps=40, solver=solver).plan(p)
        assert plan.status == sts.OPTIMAL, (solver, plan.info.get("reason"))
        costs[solver] = plan.cost
        pk = plan.peaks
        assert pk is not None and pk.within
        assert pk.peaks["ax"].peak[1] == pytest.approx(3.0, abs=1e-6)  # type: ignore[index]  # binds
    assert max(costs.values()) - min(costs.values()) <= 1e-6 * max(costs.values())
    unbounded = QPPlanner(steps=40).plan(p.with_limits(None)).cost
    assert unbounded is not None and costs["clarabel"] > unbounded


# --- infeasibility: certified and explained ---------------------------------------------------
def test_paper3_with_a_passenger_car_is_infeasible_with_the_reason() -> None:
    _, p, _ = load_problem("paper-3")
    plan = QPPlanner(steps=50).plan(p.with_limits(PASSENGER_CAR))
    assert plan.status == sts.INFEASIBLE and plan.cost is None
    reason = plan.info["reason"]
    assert "corner" in reason and "49 of 49" in reason and "certified" in reason
    js = plan.to_json()
    assert js["status"] == "infeasible" and js["reason"] == reason and js["cost"] is None
    # the independent formulation agrees at sampled candidate nodes (SCS: PIQP reports
    # 'user_limit' rather than detecting infeasibility)
    for k in (5, 25, 45):
        assert cvxpy_bounded(p.with_limits(PASSENGER_CAR), 50, "foh", (k,), "SCS")[0].startswith("infeasible")


def test_boundary_outside_a_bound_is_the_reason() -> None:
    _, p, _ = load_problem("paper-1-poly")  # v_x(0) = 20
    plan = QPPlanner(steps=20).plan(p.with_limits(PhysicalLimits(vx=(0.0, 19.0))))
    assert plan.status == sts.INFEASIBLE
    assert "v_x(0) = 20" in plan.info["reason"] and "limits.vx" in plan.info["reason"]


def test_farkas_residuals_certify_only_true_certificates() -> None:
    A = sp.csc_matrix(np.array([[1.0, 0.0], [1.0, 0.0]]))
    l, u = np.array([1.0, -np.inf]), np.array([np.inf, 0.0])  # x >= 1 and x <= 0
    stat, support = farkas_residuals(A, l, u, np.array([-1.0, 1.0]))
    assert stat == 0.0 and support < 0
    stat, support = farkas_residuals(A, l, u, np.array([1.0, -1.0]))  # pushes against infinite bounds
    assert support == math.inf
    stat, _ = farkas_residuals(A, l, u, np.array([-1.0, 0.5]))  # A'y != 0
    assert stat > 0.1


# --- the self-check covers the inequalities ---------------------------------------------------
def test_wrong_limit_multipliers_fail_the_check() -> None:
    _, p, _ = load_problem("paper-1-poly")
    qp = BoundedQP(p.with_limits(PASSENGER_CAR), 40, "foh", "clarabel")
    r = next(r for r in (qp.solve_nodes([k]) for k in range(20, 39)) if r.ok)
    assert r.checks["kkt_complementarity_rel"]["ok"]
    assert r.y is not None and r.z is not None
    y = qp.limit_multipliers(r.y)
    Az = qp.rows.A @ r.z
    active = np.flatnonzero(np.abs(y) > 1e-6)
    assert active.size > 0
    _, ok_rel = complementarity(Az, y, qp.rows.lo, qp.rows.hi)
    bad = y.copy()
    bad[active[0]] = -bad[active[0]]  # the multiplier pushes towards the other, inactive bound
    _, bad_rel = complementarity(Az, bad, qp.rows.lo, qp.rows.hi)
    assert ok_rel <= 1e-9 < bad_rel
    inactive = np.flatnonzero((Az - qp.rows.lo > 1e-3) & (qp.rows.hi - Az > 1e-3))
    bad = y.copy()
    bad[inactive[0]] = 1.0  # a multiplier on a row that does not bind
    assert complementarity(Az, bad, qp.rows.lo, qp.rows.hi)[1] > 1e-6


def test_direct_kkt_backend_is_refused_naming_the_others() -> None:
    _, p, _ = load_problem("paper-1-poly")
    with pytest.raises(IampError, match="osqp, clarabel, piqp"):
        QPPlanner(solver="kkt").plan(p.with_limits(PhysicalLimits(ax=(-6.0, 3.0))))


def test_no_limits_is_the_unbounded_qp() -> None:
    """Without a [limits] table (or with an empty one) the QP is the unbounded one, unchanged."""
    from iamp.planners.qp.core import DiscretisedQP

    _, p, _ = load_problem("paper-1-poly")
    assert type(QPPlanner().build(p)) is DiscretisedQP
    assert type(QPPlanner().build(p.with_limits(PhysicalLimits()))) is DiscretisedQP
    a = QPPlanner(steps=30).plan(p)
    b = QPPlanner(steps=30).plan(p.with_limits(PhysicalLimits()))
    assert a.cost == b.cost


def test_inactive_limits_change_nothing() -> None:
    _, p, _ = load_problem("paper-1-poly")
    free = QPPlanner(steps=30).plan(p)
    wide = QPPlanner(steps=30).plan(p.with_limits(PhysicalLimits(ax=(-50.0, 50.0), vx=(0.0, 100.0), a_total=60.0)))
    assert wide.status == sts.OPTIMAL and free.cost is not None
    assert wide.cost == pytest.approx(free.cost, rel=1e-9)
    np.testing.assert_allclose(wide.contact_times, free.contact_times)
    np.testing.assert_allclose(wide.jumps, free.jumps, rtol=1e-6, atol=1e-6)


# --- between the nodes ------------------------------------------------------------------------
def test_between_node_violation_falls_as_n_grows_and_certified_removes_it() -> None:
    """paper-1-poly with v_x >= 14.5 m/s (the unbounded plan dips to 14.2): at a fixed contact
    time the speed bound binds at nodes and the FOH speed (quadratic per piece) dips below it
    between them by O(h^2); certified Bernstein rows remove the dip at a cost that shrinks."""
    _, p, _ = load_problem("paper-1-poly")
    p = p.with_limits(PhysicalLimits(vx=(14.5, 40.0)))
    t_c = 3.45
    viol, gap = [], []
    for N in (25, 50, 100, 200):
        a = QPPlanner(steps=N).plan_at_times(p, [t_c])
        b = QPPlanner(steps=N, limits_between="certified").plan_at_times(p, [t_c])
        assert a.cost is not None and b.cost is not None
        pa, pb = a.peaks, b.peaks
        assert pa is not None and pb is not None
        viol.append(pa.peaks["vx"].violation)
        assert pb.peaks["vx"].violation <= 1e-9 and pb.peaks["vx"].ok
        assert b.cost >= a.cost * (1 - 1e-9)
        gap.append(b.cost - a.cost)
        nodes_v = a.trajectory.X[:, 1]
        assert nodes_v.min() >= 14.5 - 1e-7  # at the nodes the bound holds
    assert all(v > 0 for v in viol)
    assert all(v2 < v1 / 2.5 for v1, v2 in zip(viol, viol[1:])), viol  # O(h^2): about 4x per halving
    assert gap[-1] < gap[0] / 10, gap


def test_node_only_plan_beyond_a_bound_is_not_optimal() -> None:
    _, p, _ = load_problem("paper-1-poly")
    p = p.with_limits(PhysicalLimits(vx=(14.5, 40.0)))
    plan = QPPlanner(steps=50).plan(p)
    assert plan.status == sts.LIMITS_VIOLATED
    assert "between the grid nodes" in plan.info["reason"]
    assert plan.info["limits_between_nodes"]["vx"] > 1e-4
    js = plan.to_json()
    assert js["status"] == "limits_violated" and js["limits"]["vx"]["ok"] is False
    ok = QPPlanner(steps=50, limits_between="certified").plan(p)
    assert ok.status == sts.OPTIMAL and ok.peaks is not None and ok.peaks.within


def test_y_bound_certified_rows_hold_everywhere() -> None:
    """A lateral bound just above the target lane centre: the FOH s_y (cubic per piece) with
    certified Bernstein rows never exceeds it; the node-only plan may, and says by how much."""
    _, p, _ = load_problem("paper-2")
    free = QPPlanner(steps=40).plan(p)
    y_max = float(free.states(np.linspace(0, p.tf, 2001))[:, 2].max())
    assert y_max > p.ego.yf + 0.1  # the unbounded plan overshoots the target lane centre
    y_hi = 0.5 * (p.ego.yf + y_max)
    lim = PhysicalLimits(y=(-3.0, y_hi))
    for hold in ("foh", "zoh"):
        c = QPPlanner(steps=40, hold=hold, limits_between="certified").plan(p.with_limits(lim))
        assert c.status == sts.OPTIMAL, c.info.get("reason")
        assert c.peaks is not None and c.peaks.peaks["y"].ok
        dense = c.states(np.linspace(0, p.tf, 20001))[:, 2]
        assert dense.max() <= y_hi + 1e-9


def test_jerk_with_zoh_is_refused() -> None:
    from iamp.core.errors import ScenarioError

    _, p, _ = load_problem("paper-1-poly")
    with pytest.raises(ScenarioError, match="limits.jerk"):
        QPPlanner(hold="zoh").plan(p.with_limits(PhysicalLimits(jerk=5.0)))


# --- the command line -------------------------------------------------------------------------
def _with_template_limits(cli, name: str, tmp_path) -> str:  # type: ignore[no-untyped-def]
    shown = cli("scenarios", "--show", name)
    tpl = cli("template")
    table = tpl.stdout[tpl.stdout.index("[limits]"):]
    path = tmp_path / f"{name}-car.toml"
    path.write_text(shown.stdout + "\n" + table)
    return str(path)


def test_cli_paper3_with_the_template_limits_says_infeasible(cli, tmp_path) -> None:  # type: ignore[no-untyped-def]
    path = _with_template_limits(cli, "paper-3-poly", tmp_path)
    r = cli("plan", path, "--planner", "qp", "--steps", "40")
    assert r.returncode == 3, r.stdout + r.stderr
    assert "status    infeasible" in r.stdout and "reason" in r.stdout and "corner" in r.stdout
    r = cli("plan", path, "--planner", "qp", "--steps", "40", "--json")
    out = json.loads(r.stdout)
    assert out["status"] == "infeasible" and "corner" in out["reason"]


def _template_with_jerk(text: str) -> str:
    """The template with its commented comfort-jerk bound switched on (the QP imposes it)."""
    import re

    out = re.sub(r"^# jerk = 5\.0 ", "jerk = 5.0   ", text, flags=re.M)
    assert out != text
    return out


def test_cli_template_plans_within_its_limits(cli, tmp_path) -> None:  # type: ignore[no-untyped-def]
    path = tmp_path / "t.toml"
    path.write_text(_template_with_jerk(cli("template").stdout))
    r = cli("plan", str(path), "--planner", "qp", "--steps", "40", "--json")
    assert r.returncode == 0, r.stdout + r.stderr
    out = json.loads(r.stdout)
    assert set(out["limits"]) == {"ax", "ay", "a_total", "vx", "jerk"}
    assert all(v["ok"] for v in out["limits"].values())
    assert out["limits_polygon_sides"] == 16
    r = cli("plan", str(path), "--planner", "qp", "--steps", "40")
    assert "limits    ax [" in r.stdout and "16-gon" in r.stdout


def test_cli_jerk_with_zoh_exits_2(cli, tmp_path) -> None:  # type: ignore[no-untyped-def]
    path = tmp_path / "t.toml"
    path.write_text(_template_with_jerk(cli("template").stdout))
    r = cli("plan", str(path), "--planner", "qp", "--hold", "zoh", "--steps", "20")
    assert r.returncode == 2 and "limits.jerk" in r.stderr and "Traceback" not in r.stderr


def test_cli_limits_errors_name_file_and_field(cli, tmp_path) -> None:  # type: ignore[no-untyped-def]
    base = cli("template").stdout
    for bad, field in (("ax = [-6.0, 3.0]", "ax = [1.0, 3.0]"), ("a_total = 8.0", "a_total = -1.0"),
                       ("jerk = 5.0", "jerk = 5.0\nspeed = 3.0")):
        path = tmp_path / "bad.toml"
        path.write_text(base.replace(bad, field))
        r = cli("plan", str(path))
        assert r.returncode == 2, r.stderr
        assert str(path) in r.stderr and "limits." in r.stderr and "Traceback" not in r.stderr


def test_qpdata_layout_matches_the_rows() -> None:
    """The limit rows address the same z as QPData.unpack (one layout, StateIndex)."""
    from iamp.planners.qp.limits import limit_rows

    p = random_problem(7)
    d = QPData(p, 12, "foh")
    rows = limit_rows(d, d.t_nodes, "foh", PhysicalLimits(vx=(0.0, 40.0)), between="certified")
    z = np.random.default_rng(3).normal(size=d.n)
    X, U = d.unpack(z)
    sel = rows.kind == "vx_between"
    np.testing.assert_allclose(rows.A[sel] @ z, X[:-1, 1] + d.h / 2 * U[:-1, 0], rtol=1e-13)


def test_a_certificate_without_the_corners_makes_every_candidate_infeasible() -> None:
    """paper-2-poly under the passenger car's box: the x boundary (20 -> 20 m/s, 73 m in 5 s)
    needs a speed dip whose deficit at a_x in [-6, 3] is at most 9 t1^2 = 25 m (3 t1 = 5 s) < 27 m,
    so no plan exists even without the corner.  At N = 100 one candidate's solve ended in a
    numerical error (Clarabel); the certificate of the corner-free problem still makes the plan
    ``infeasible`` (it was ``inaccurate`` before), and an independent solver agrees."""
    _, p, _ = load_problem("paper-2-poly")
    box = p.with_limits(PhysicalLimits(ax=(-6.0, 3.0), ay=(-2.0, 2.0)))
    plan = QPPlanner(steps=100).plan(box)
    assert plan.status == sts.INFEASIBLE, plan.info.get("reason")
    assert "even without the corner constraints" in plan.info["reason"]
    assert cvxpy_bounded(box, 100, "foh", (), "SCS")[0].startswith("infeasible")
    assert cvxpy_bounded(box, 100, "foh", (), "CLARABEL")[0].startswith("infeasible")
