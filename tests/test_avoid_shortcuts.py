"""Issue 32 item 5: certified shortcuts of the continuous-time avoidance QP in the closed loop.

* The relaxed optimum certified at once (:meth:`ContinuousAvoidPlanner._free_certified`): when
  the candidate at the relaxation's best crossing times costs no more than the relaxation, the
  plan is returned without the box search, and it is the plan of the full search bit for bit
  (generated problems, the vehicles from in the way to far away); it is taken whenever the ego's
  unconstrained optimum clears every vehicle by far.
* The per-grid factorisation shared across one planner's plans
  (:class:`~iamp.planners.avoid.continuous.GridShare`): a planner that plans a sequence of
  problems gives, plan by plan, the plans of fresh planners bit for bit, and factors each grid's
  KKT matrix once.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st_h

from iamp.core.errors import ScenarioError
from iamp.core.physical import PASSENGER_CAR
from iamp.core.plan import Plan
from iamp.core.problem import Problem
from iamp.planners.avoid import continuous as cont
from iamp.planners.avoid.planner import AvoidQPPlanner
from iamp.planners.examples import random_problem

N = 12


def _loop_planner() -> AvoidQPPlanner:
    """The closed loop's ``qp-avoid`` (:data:`iamp.simulation.planning.SIM_OPTIONS`)."""
    return AvoidQPPlanner(steps=N, hold="foh", solver="clarabel", safety="continuous", max_solves=100)


def _moved(seed: int, m: int, shift: float, limits: bool) -> Problem:
    """``random_problem(seed, m)`` with every vehicle moved ``shift`` m along x (away from the ego
    when large: vehicle 1 behind, the others ahead)."""
    p = random_problem(seed, m=m)
    vs = tuple(replace(v, x_poly=(v.x_poly[0] + (-shift if i == 0 else shift),) + tuple(v.x_poly[1:]))
               for i, v in enumerate(p.vehicles))
    out = Problem(ego=p.ego, vehicles=vs, name=p.name)
    return out.with_limits(PASSENGER_CAR) if limits else out


def _same(a: Plan, b: Plan) -> None:
    assert a.status == b.status
    assert a.cost == b.cost  # bit for bit
    assert np.array_equal(a.contact_times, b.contact_times, equal_nan=True)
    if a.trajectory is not None:
        assert b.trajectory is not None
        t = np.linspace(0.0, a.problem.tf, 41)
        assert np.array_equal(np.asarray(a.trajectory.states(t)), np.asarray(b.trajectory.states(t)))


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st_h.integers(0, 10**6), st_h.integers(1, 2), st_h.sampled_from([-12.0, -8.0, -4.0, 0.0, 15.0, 300.0]),
       st_h.booleans())
def test_the_free_shortcut_gives_the_plan_of_the_full_search(seed: int, m: int, shift: float, limits: bool) -> None:
    # negative shifts move the vehicles into the ego's way (the plans bind); far ones leave it free
    problem = _moved(seed, m, shift, limits)
    try:
        plan = _loop_planner().plan(problem)
    except ScenarioError:  # moved so far that the corner no longer describes the manoeuvre
        assume(False)
        raise
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(cont.ContinuousAvoidPlanner, "_free_certified", lambda self, qp, box: None)
        full = _loop_planner().plan(problem)
    _same(plan, full)
    search = plan.info.get("search", {})
    if search.get("free_certified"):
        assert plan.status == "optimal" and search["closed"]
        assert full.info["search"]["closed"]
        assert search["n_solves"] == full.info["search"]["n_solves"]  # the same QPs, without the boxes' work


@pytest.mark.parametrize("m", [1, 2])
@pytest.mark.parametrize("limits", [False, True])
def test_the_free_shortcut_is_taken_when_every_vehicle_is_far(m: int, limits: bool) -> None:
    for seed in range(4):
        plan = _loop_planner().plan(_moved(seed, m, 400.0, limits))
        assert plan.status == "optimal"
        assert plan.info["search"]["free_certified"] is True
        assert plan.info["search"]["lower_bound"] == pytest.approx(plan.cost, rel=1e-12)


def test_one_planner_factors_each_grid_once_and_plans_as_fresh_planners(monkeypatch: pytest.MonkeyPatch) -> None:
    import iamp.planners.avoid.schur as schur

    calls = {"n": 0}
    splu = schur.spla.splu

    def counted(*args: object, **kwargs: object) -> object:
        calls["n"] += 1
        return splu(*args, **kwargs)

    problems = [_moved(seed, m, shift, True) for seed, m, shift in
                [(1, 2, 0.0), (2, 1, 15.0), (3, 2, 300.0), (4, 1, 0.0), (5, 2, 40.0)]]
    # the same horizon twice: the loop replans one grid (tf) every period
    problems += [Problem(ego=replace(p.ego, tf=problems[0].tf), vehicles=p.vehicles, name=p.name,
                         limits=p.limits) for p in problems[1:3]]
    fresh = [_loop_planner().plan(p) for p in problems]
    monkeypatch.setattr(schur.spla, "splu", counted)
    one = _loop_planner()
    shared = [one.plan(p) for p in problems]
    for a, b in zip(shared, fresh):
        _same(a, b)
    grids = len({p.tf for p in problems})
    assert grids < len(problems)
    assert calls["n"] == grids  # one factorisation per grid (was one per plan)


def _scan_leave_time(traj, plane, tf: float) -> float:  # type: ignore[no-untyped-def]
    """The former ``leave_time``: the whole 1 ms scan, then the root on its last bracket."""
    from scipy import optimize

    t = np.linspace(0.0, tf, max(2, int(np.ceil(tf / 1e-3)) + 1))
    axis = 0 if plane.axis == "x" else 2

    def margin(x: np.ndarray) -> np.ndarray:
        return np.asarray(plane.margin(x, traj.states(x)[:, axis]), dtype=float)

    inside = np.flatnonzero(margin(t) >= -1e-12)
    if inside.size == 0:
        return 0.0
    k = int(inside[-1])
    if k == t.size - 1:
        return float(tf)
    return float(optimize.brentq(lambda x: float(margin(np.array([x]))[0]) + 1e-12, float(t[k]), float(t[k + 1]),
                                 xtol=1e-13))


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st_h.integers(0, 10**6), st_h.sampled_from(["foh", "zoh"]), st_h.integers(4, 16),
       st_h.floats(-20.0, 20.0), st_h.sampled_from(["front-lower", "front-upper", "rear-lower", "rear-upper"]))
def test_leave_time_from_exact_roots_is_the_scans(seed: int, hold: str, n: int, dx: float, corner: str) -> None:
    """On held trajectories (random nodal states and inputs) against every half-plane of a
    vehicle moved along the ego's path: the exact root is the full 1 ms scan's root (Brent's
    method to 1e-13 s) to 1e-12 s, and the margin is within its tolerance there (so the two roots
    are the same root, not two crossings)."""
    from iamp.planners.avoid.check import leave_time
    from iamp.planners.avoid.data import HalfPlane
    from iamp.planners.qp.hold import HoldTrajectory

    rng = np.random.default_rng(seed)
    p = random_problem(seed, m=1)
    tf = p.tf
    t_nodes = np.linspace(0.0, tf, n + 1)
    U = rng.normal(0.0, 2.0, (n + 1 if hold == "foh" else n, 2))
    X = np.zeros((n + 1, 4))
    X[0] = [p.ego.x0, p.ego.vx0, p.ego.y0, p.ego.vy0]
    h = tf / n
    for k in range(n):  # the exact integration of the hold
        u0 = U[k]
        du = (U[k + 1] - U[k]) / h if hold == "foh" else np.zeros(2)
        s, v = X[k, [0, 2]], X[k, [1, 3]]
        X[k + 1, [0, 2]] = s + v * h + u0 * h**2 / 2 + du * h**3 / 6
        X[k + 1, [1, 3]] = v + u0 * h + du * h**2 / 2
    traj = HoldTrajectory(t_nodes, X, U, hold)
    v = p.vehicles[0]
    v = replace(v, corner=corner, x_poly=(v.x_poly[0] + dx,) + tuple(v.x_poly[1:]),
                y=float(X[n // 2, 2]) + rng.uniform(-3.0, 3.0))
    for axis in ("x", "y"):
        plane = HalfPlane(v, axis)
        exact, scan = leave_time(traj, plane, tf), _scan_leave_time(traj, plane, tf)
        assert abs(exact - scan) <= 1e-12, (exact, scan)
        if 0.0 < exact < tf:
            col = 0 if axis == "x" else 2
            assert abs(plane.margin(np.array([exact]), traj.states(np.array([exact]))[:, col])[0] + 1e-12) <= 1e-9


def test_leave_time_takes_the_exact_bracket_on_avoidance_plans() -> None:
    """On the avoidance plans of generated problems the leave time comes from the roots (no
    scan), the scan's root to 1e-12 s, on every half-plane."""
    from iamp.planners.avoid import check
    from iamp.planners.avoid.data import HalfPlane

    taken = total = roots = 0
    for seed in range(6):
        problem = _moved(seed, 2, -4.0 if seed % 2 else 0.0, bool(seed % 3))
        plan = _loop_planner().plan(problem)
        if plan.trajectory is None:
            continue
        for v in problem.vehicles:
            for axis in ("x", "y"):
                plane = HalfPlane(v, axis)
                t = check.ScanGrid(problem.tf)
                col = 0 if axis == "x" else 2
                traj = plan.trajectory
                k = check._scan_bracket(traj, plane, t,
                                        lambda x, pl=plane, tr=traj, c=col: pl.margin(x, tr.states(x)[:, c]))
                taken += k is not None
                total += 1
                roots += k is not None and k[1] is not None
                assert abs(check.leave_time(plan.trajectory, plane, problem.tf)
                           - _scan_leave_time(plan.trajectory, plane, problem.tf)) <= 1e-12
    # every half-plane of every plan takes the exact path (none falls back to the scan), and 7 of
    # the 24 through a root inside the horizon (the others end inside their half-plane)
    assert taken == total == 24
    assert roots >= 7


@settings(max_examples=300, deadline=None)
@given(st_h.one_of(st_h.floats(0.0, 60.0), st_h.sampled_from([0.0, 1e-3, 2e-3, 0.1, 5.0, 8.0, 12.3, 30.0])),
       st_h.lists(st_h.floats(-1.0, 61.0) | st_h.sampled_from([float("nan"), float("inf"), -float("inf"), -0.0]),
                  min_size=1, max_size=8))
def test_scan_grid_is_linspace_and_searchsorted(tf: float, xs: list[float]) -> None:
    """:class:`~iamp.planners.avoid.check.ScanGrid` gives ``numpy.linspace``'s points bit for bit
    and ``numpy.searchsorted(..., side="right") - 1`` at any number (grid points and their
    neighbours included), without building the ~10,000 points."""
    from iamp.planners.avoid.check import ScanGrid

    grid = ScanGrid(tf)
    t = np.linspace(0.0, tf, max(2, int(np.ceil(tf / 1e-3)) + 1))
    assert grid.size == t.size
    assert grid.full().tobytes() == t.tobytes()
    picks = sorted({0, 1, t.size // 2, t.size - 2, t.size - 1})
    assert np.array([grid.at(k) for k in range(t.size)]).tobytes() == t.tobytes() if t.size <= 2000 else \
        all(grid.at(k) == t[k] for k in picks)
    probes = list(xs) + [float(t[k]) for k in picks] + [float(np.nextafter(t[k], -1.0)) for k in picks] \
        + [float(np.nextafter(t[k], 2.0 * tf + 1.0)) for k in picks]
    for x in probes:
        assert grid.last_at_or_below(x) == int(np.searchsorted(t, x, side="right")) - 1, x


def _same_sparse(a: object, b: object) -> None:
    import scipy.sparse as sp

    a, b = sp.csr_matrix(a), sp.csr_matrix(b)
    assert a.shape == b.shape
    assert np.array_equal(a.indptr, b.indptr) and np.array_equal(a.indices, b.indices)
    assert np.array_equal(a.data, b.data)


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st_h.integers(0, 10**6), st_h.integers(1, 2), st_h.sampled_from([0.0, 15.0, 300.0]))
def test_what_a_grid_keeps_is_what_each_plan_would_build(seed: int, m: int, shift: float) -> None:
    # the QP's A and P, the KKT checks' triu(P, 1)^T and the stacked limit rows [A_lim; -A_lim],
    # [hi; -lo], kept per grid by the planner (GridShare), are those a plan builds from its own data
    import scipy.sparse as sp

    from iamp.planners.avoid.data import AvoidData
    from iamp.planners.qp.limits import limit_rows

    shared = cont.GridShare()
    first = _moved(seed, m, shift, True)
    again = _moved(seed + 1, m, shift, True)
    again = Problem(ego=replace(again.ego, tf=first.tf), vehicles=again.vehicles, name=again.name,
                    limits=again.limits)
    for p in (first, again, first):  # first again: its half-planes' bounds are then the kept ones
        try:
            qp = cont.ContinuousAvoidQP(p, N, "foh", "clarabel", shared=shared)
        except ScenarioError:
            assume(False)
            raise
        d = qp.data
        own = AvoidData(p, d.t_nodes, "foh")  # built by this plan alone
        _same_sparse(d.A, own.A)
        _same_sparse(d.P, own.P)
        assert np.array_equal(d.b_eq, own.b_eq) and np.array_equal(d.c_on, own.c_on) and d.relax == own.relax
        assert qp.schur is not None
        _same_sparse(qp.schur.P_lower, sp.triu(sp.csc_matrix(d.P), 1).T)
        lr = limit_rows(d, d.t_nodes, "foh", p.limits, between="certified")
        _same_sparse(qp.A_lim, sp.vstack([lr.A, -lr.A]))
        assert np.array_equal(qp.u_lim, np.r_[lr.hi, -lr.lo])
        # the layout (equality rows, node columns, full pieces' values, split polynomials) and the
        # half-planes' bounds (full pieces, the polynomials of split pieces) are a fresh QP's
        alone = cont.ContinuousAvoidQP(p, N, "foh", "clarabel")
        _same_sparse(qp.A_eq, sp.csr_matrix(d.A[:d.n_eq]))
        assert np.array_equal(qp._bern_cols, alone._bern_cols)
        for key, vals in alone._full_vals.items():
            assert np.array_equal(qp._full_vals[key], vals)
            assert np.array_equal(qp._full_rhs[key], alone._full_rhs[key])
            for k, pre in ((0, True), (N // 2, False), (N - 1, True)):
                assert np.array_equal(qp.rhs_polynomial(*key, k, pre), alone.rhs_polynomial(*key, k, pre))
            for ta, tb in ((0.0, 0.37 * p.tf), (0.37 * p.tf, p.tf), (0.2 * p.tf, 0.2 * p.tf), (0.0, 0.5 * p.tf)):
                for a, b in zip(qp._segment(*key, ta, tb), alone._segment(*key, ta, tb)):
                    assert np.array_equal(a, b)
        for a, b in zip(qp.split_polynomials(), alone.split_polynomials()):
            assert np.array_equal(a, b)


def test_a_half_planes_kept_rows_are_bounded() -> None:
    # _PlaneRows keeps at most LIMIT entries per kind: the next one empties the kind first (each
    # value is a function of its key, so a plan computes it again and gets the same)
    rows = cont._PlaneRows(np.zeros(4))
    for k in range(cont._PlaneRows.LIMIT):
        rows.keep(rows.segments, (0, float(k), 1.0), (np.zeros(1), np.zeros(1), np.zeros(1, dtype=np.int64)))
    assert len(rows.segments) == cont._PlaneRows.LIMIT
    rows.keep(rows.segments, (0, -1.0, 1.0), (np.ones(1), np.ones(1), np.ones(1, dtype=np.int64)))
    assert list(rows.segments) == [(0, -1.0, 1.0)] and not rows.splits


@pytest.mark.parametrize("tf", [0.0, 1e-3, 0.0071, 1.234, 4.6, 7.0])
def test_scan_grid_finds_every_point_of_its_grid(tf: float) -> None:
    """:meth:`~iamp.planners.avoid.check.ScanGrid.last_at_or_below` at every point of the grid and
    at the floats on either side of it: ``numpy.searchsorted``'s index (the first guess
    ``x / step`` rounds either way; both corrections are needed)."""
    from iamp.planners.avoid.check import ScanGrid

    grid = ScanGrid(tf)
    t = grid.full()
    xs = np.concatenate((t, np.nextafter(t, -np.inf), np.nextafter(t, np.inf)))
    got = np.array([grid.last_at_or_below(float(x)) for x in xs])
    assert np.array_equal(got, np.searchsorted(t, xs, side="right") - 1)
