"""Road edges of CommonRoad problems (issue 33): the corridor's geometry, the lateral repair of a
plan at a narrowing edge, and the equality QP's solve budget."""

from __future__ import annotations

import math
from types import SimpleNamespace
from typing import Any, cast

import numpy as np
import pytest
from conftest import data_path, needs_commonroad_data
from hypothesis import given, settings
from hypothesis import strategies as st

DATA = data_path("commonroad", "US101")
needs_data = needs_commonroad_data("commonroad", "US101")


@settings(max_examples=60, deadline=None, derandomize=True)
@given(pts=st.lists(st.tuples(st.integers(-5000, 5000), st.integers(-5000, 5000))
                    .map(lambda p: (p[0] / 100, p[1] / 100)), min_size=2, max_size=8),
       spacing=st.floats(0.05, 5.0))
def test_densify_keeps_vertices_and_spacing(pts: list[tuple[float, float]], spacing: float) -> None:
    """Every vertex is kept in order, consecutive points are at most ``spacing`` apart and every
    new point lies on its segment."""
    from iamp.commonroad.convert import densify

    P = np.array(pts)
    D = densify(P, spacing)
    assert np.all(np.linalg.norm(np.diff(D, axis=0), axis=1) <= spacing * (1 + 1e-9) + 1e-12)
    # the original vertices appear in order
    j = 0
    for p in P:
        while j < len(D) and not np.allclose(D[j], p, atol=1e-9):
            j += 1
        assert j < len(D)
    # every point lies on the polyline (distance to the nearest segment ~ 0)
    for q in D:
        best = math.inf
        for a, b in zip(P[:-1], P[1:]):
            ab = b - a
            f = 0.0 if not ab.any() else float(np.clip((q - a) @ ab / (ab @ ab), 0.0, 1.0))
            best = min(best, float(np.linalg.norm(a + f * ab - q)))
        assert best <= 1e-7 * (1 + float(np.abs(P).max()))


@pytest.mark.parametrize("m", [1, 2, 3, 4])
def test_qp_steps_is_the_finest_grid_within_the_budget(m: int) -> None:
    """The equality QP sweeps (N-1)!/(N-1-m)! node assignments: the grid is the finest whose sweep
    fits the solve budget, and one vehicle keeps the full grid."""
    from iamp.commonroad.planning import QP_MAX_SOLVES, STEPS, qp_steps

    n = qp_steps(m)
    assert math.perm(n - 1, m) <= QP_MAX_SOLVES or n == 2
    assert n == STEPS or math.perm(n, m) > QP_MAX_SOLVES
    assert qp_steps(1) == STEPS
    assert qp_steps(2, STEPS, 100) >= qp_steps(2, STEPS, 20)


def _straight_problem(narrow_at: float, drop: float, speed: float) -> Any:
    """A straight road along ``s`` whose upper bound ``1.0`` drops by ``drop`` from ``narrow_at`` on
    (over 4 m), the ego at ``d = 0.1`` heading along it: the shape the repair sees (no vehicle)."""
    from iamp.commonroad.goal import Candidate

    grid = np.arange(-20.0, 200.0, 0.5)
    hi = 1.0 - drop * np.clip((grid - narrow_at) / 4.0, 0.0, 1.0)
    lo = np.full(grid.size, -5.0)
    cr = SimpleNamespace(corridor=(grid, lo, hi), dt=0.1, ego_length=4.508, ego_width=1.61,
                         x0=(0.0, speed, 0.1, 0.0), a_max=11.5, obstacles=[], road_edges=[])
    T = 6.0
    cand = Candidate(s=speed * T, vs=speed, d=-0.5, vd=0.0, tf=T, steps=60, cost0=0.0, element=0, piece=0)
    return cr, cand


def _corners_inside(cr: Any, traj: Any, steps: int) -> float:
    """Largest excess of a body corner (or of the left side at a corridor sample) over the upper
    bound, the exact rectangle at its heading [m] (< 0: inside)."""
    grid, _, hi = cr.corridor
    L2, W2 = cr.ego_length / 2, cr.ego_width / 2
    X = traj.states(np.arange(1, steps + 1) * cr.dt)
    worst = -math.inf
    for s, vs, d, vd in X:
        phi = math.atan2(vd, vs)
        c, sn = math.cos(phi), math.sin(phi)
        for lam in np.linspace(-L2, L2, 41):  # the left side, corners included
            ps, pd = s + lam * c - W2 * sn, d + lam * sn + W2 * c
            worst = max(worst, pd - float(np.interp(ps, grid, hi)))
    return worst


@settings(max_examples=15, deadline=None, derandomize=True)
@given(narrow_at=st.floats(5.0, 20.0), drop=st.floats(0.2, 0.4), speed=st.floats(8.0, 25.0))
def test_repair_keeps_the_body_inside_a_narrowing_edge(narrow_at: float, drop: float, speed: float) -> None:
    """A plan that drives straight into a narrowing edge (the free cubic to the final state) is
    repaired laterally: the exact body at its heading stays below the bound at every step, the
    start and the final state are kept, and the inputs stay in the friction circle."""
    from iamp.commonroad.planning import FreeTrajectory, repair_at_edges

    cr, cand = _straight_problem(narrow_at, drop, speed)
    base = FreeTrajectory(cand.tf, cr.x0, (cand.s, cand.vs, 0.1, 0.0))  # keeps d = 0.1: into the edge
    assert _corners_inside(cr, base, cand.steps) > 0.05
    fixed = repair_at_edges(cast(Any, cr), base, cand)
    assert fixed is not None
    assert _corners_inside(cr, fixed, cand.steps) <= 1e-9
    end = fixed.states([cand.tf])[0]
    assert end[2] == pytest.approx(cand.d, abs=1e-6) and end[3] == pytest.approx(cand.vd, abs=1e-6)
    assert fixed.states([0.0])[0][2] == pytest.approx(0.1)
    U = fixed.inputs(np.arange(cand.steps) * cr.dt + 0.05)
    assert np.all(np.hypot(U[:, 0], U[:, 1]) <= cr.a_max + 1e-9)


def test_repair_refuses_a_corridor_the_body_cannot_fit() -> None:
    from iamp.commonroad.planning import FreeTrajectory, repair_at_edges

    cr, cand = _straight_problem(10.0, 0.4, 10.0)
    grid, lo, hi = cr.corridor
    cr.corridor = (grid, np.maximum(lo, hi - 1.0), hi)  # 1 m wide: narrower than the body (1.61 m)
    base = FreeTrajectory(cand.tf, cr.x0, (cand.s, cand.vs, cand.d, cand.vd))
    assert repair_at_edges(cast(Any, cr), base, cand) is None


@pytest.mark.slow
@needs_data
def test_us101_5_is_valid_beside_its_narrowing_edge() -> None:
    """US101-5: the ego starts 5 mm from a left edge that narrows by 20 cm ahead (bench.md: off road
    with every planner before).  The default planner's plan now passes CommonRoad's checker."""
    from iamp.commonroad.check import check
    from iamp.commonroad.convert import load
    from iamp.commonroad.planning import plan
    from iamp.commonroad.solution import build_solution

    cr = load(DATA / "USA_US101-5_1_T-1.xml")
    rp = plan(cr)
    assert rp.safe and rp.trajectory is not None and rp.candidate is not None
    sol, _ = build_solution(cr, rp.trajectory, rp.candidate.steps)
    v = check(cr.scenario, cr.planning_problem_set, sol, cost=False)
    assert v.checks["road_boundary"]["ok"], v.checks
    assert v.valid


@needs_data
def test_corridor_follows_the_lanelet_bounds_between_vertices() -> None:
    """The corridor is the lanelets' bounds densified in the world before projection: its upper
    bound at the US101-5 start lies within 5 mm of CommonRoad's own lanelet polygon (projecting
    only the vertices put it 1.1 cm inside, so the recorded start overlapped the edge)."""
    from iamp.commonroad.convert import load

    cr = load(DATA / "USA_US101-5_1_T-1.xml")
    grid, _, hi = cr.corridor
    network = cr.scenario.lanelet_network
    # the left bound of the leftmost lanelet at the ego's start, measured in the world: the point of
    # the lanelets' left polylines nearest to the frame's (s0 - L/2, d_hi) point
    s0 = cr.x0[0] - cr.ego_length / 2
    d_hi = float(np.interp(s0, grid, hi))
    p = cr.frame.to_world(np.array([s0]), np.array([d_hi]))[0]
    best = math.inf
    for V in [np.asarray(v, dtype=float) for ll in network.lanelets for v in (ll.left_vertices, ll.right_vertices)]:
        for a, b in zip(V[:-1], V[1:]):
            ab = b - a
            if not ab.any():
                continue
            f = float(np.clip((p - a) @ ab / (ab @ ab), 0.0, 1.0))
            best = min(best, float(np.linalg.norm(a + f * ab - p)))
    assert best < 0.005
