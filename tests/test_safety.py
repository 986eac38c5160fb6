"""SPEC §9: the safety report, exact (roots of piecewise polynomials) against an independent
dense evaluation (1e-5 s sampling) on random problems and on PMP, FOH and ZOH trajectories."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, assume, given, settings
from hypothesis import strategies as st

from iamp.core.polyroots import roots_in_unit_interval
from iamp.core.problem import EgoBoundary, Problem, SurroundingVehicle
from iamp.core.safety import INTRUSION_TOL_M, safety_report
from iamp.planners.examples import paper_problem
from iamp.planners.pmp.planner import PMPPlanner
from iamp.planners.qp.planner import HoldTrajectory

DT = 1e-5  # dense sampling step [s]
EDGE = 3 * DT  # samples this close to an exact interval end are not judged
#: no shrinking: a dense check per example is too slow to shrink
PHASES = (Phase.explicit, Phase.reuse, Phase.generate)


def dense(problem, traj, Le=4.8, We=1.8):
    """Independent evaluation on a 1e-5 s grid: masks and extremes per vehicle."""
    t = np.linspace(0.0, problem.tf, int(round(problem.tf / DT)) + 1)  # never beyond t_f
    X = traj.states(t)
    out = []
    for v in problem.vehicles:
        dx = X[:, 0] - np.polynomial.polynomial.polyval(t, v.x_poly)
        dy = X[:, 2] - v.y
        ax, ay = v.length / 2 + v.safety_x, v.width / 2 + v.safety_y
        depth = np.minimum(ax - np.abs(dx), ay - np.abs(dy))
        dist = np.hypot(np.maximum(np.abs(dx) - ax, 0), np.maximum(np.abs(dy) - ay, 0))
        overlap = (np.abs(dx) < (Le + v.length) / 2) & (np.abs(dy) < (We + v.width) / 2)
        out.append({"t": t, "intrusion": depth > INTRUSION_TOL_M, "overlap": overlap,
                    "max_depth": max(0.0, float(depth.max())), "min_dist": float(dist.min()),
                    "speed": float(np.max(np.abs(np.diff(np.c_[dx, dy], axis=0)))) / DT})
    return out


def member(t, intervals):
    m = np.zeros(t.size, dtype=bool)
    near = np.zeros(t.size, dtype=bool)
    for a, b in intervals:
        m |= (t > a) & (t < b)
        near |= (np.abs(t - a) < EDGE) | (np.abs(t - b) < EDGE)
    return m, near


def check_against_dense(problem, traj, Le=4.8, We=1.8):
    rep = safety_report(problem, traj, Le, We)
    assert rep.exact
    for vs, d in zip(rep.vehicles, dense(problem, traj, Le, We)):
        for key in ("intrusion", "overlap"):
            iv = getattr(vs, key)
            assert all(a < b for a, b in iv) and all(iv[k][1] < iv[k + 1][0] for k in range(len(iv) - 1))
            m, near = member(d["t"], iv)
            bad = (m != d[key]) & ~near
            assert not bad.any(), (key, iv, d["t"][bad][:5])
        # extremes: exact >= sampled, and not above it by more than one step of motion
        slack = d["speed"] * DT + 1e-9
        assert vs.max_intrusion_m >= d["max_depth"] - 1e-9
        assert vs.max_intrusion_m <= d["max_depth"] + slack
        assert vs.min_clearance_m <= d["min_dist"] + 1e-9
        assert vs.min_clearance_m >= d["min_dist"] - slack
        assert (vs.intrusion == ()) == (vs.max_intrusion_m <= INTRUSION_TOL_M + slack) or vs.intrusion
    return rep


def problem_from(draw_vals):
    tf, xf, yf, vx0, vxf, vy0, vyf, c0, c1, c2, c3, y, L, W, sx, sy, corner = draw_vals
    ego = EgoBoundary(tf=tf, x0=0.0, y0=-2.0, vx0=vx0, xf=xf, yf=yf, vxf=vxf, vy0=vy0, vyf=vyf)
    v = SurroundingVehicle(x_poly=(c0, c1, c2, c3), corner=corner, y=y, length=L, width=W,
                           safety_x=sx, safety_y=sy)
    return Problem(ego, (v,), "random")


problems = st.tuples(
    st.floats(3.0, 6.0), st.floats(50.0, 110.0), st.floats(1.0, 5.0), st.floats(15.0, 25.0), st.floats(15.0, 25.0),
    st.floats(-1.0, 1.0), st.floats(-1.0, 1.0), st.floats(-30.0, 20.0), st.floats(10.0, 25.0),
    st.floats(-1.5, 1.5), st.floats(-0.1, 0.1), st.floats(1.5, 5.0), st.floats(3.0, 6.0), st.floats(1.5, 2.2),
    st.floats(0.0, 8.0), st.floats(0.0, 1.0), st.sampled_from(["front-lower", "rear-lower"]),
).map(problem_from)


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow], phases=PHASES)
@given(problems, st.floats(0.1, 0.9), st.floats(0.0, 6.0), st.floats(0.0, 1.5))
def test_pmp_plan_report_matches_dense_evaluation(problem, frac, sx, sy):
    plan = PMPPlanner().plan(problem, [frac * problem.tf], diagnostics=False)
    assume(plan.trajectory is not None)
    # judge it against a vehicle of other safety distances: real intrusions, not corner touches
    v = problem.vehicles[0]
    other = problem.with_vehicles([SurroundingVehicle(v.x_poly, v.corner, v.y, v.length, v.width, sx, sy)])
    check_against_dense(other, plan.trajectory)
    check_against_dense(problem, plan.trajectory, Le=3.0, We=1.5)


def integrated_hold(problem, N, hold, seed):
    """A dynamically consistent hold trajectory with random inputs."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, problem.tf, N + 1)
    U = rng.normal(0, 2.0, size=(N if hold == "zoh" else N + 1, 2))
    X = np.zeros((N + 1, 4))
    X[0] = problem.ego.initial
    for k in range(N):
        X[k + 1] = _step(X[k], U, k, t, hold)
    return HoldTrajectory(t, X, U, hold)


def _step(x, U, k, t, hold):
    h = t[k + 1] - t[k]
    s, v = x[[0, 2]], x[[1, 3]]
    if hold == "zoh":
        u = U[k]
        sn, vn = s + h * v + h**2 / 2 * u, v + h * u
    else:
        sn = s + h * v + h**2 * (U[k] / 3 + U[k + 1] / 6)
        vn = v + h / 2 * (U[k] + U[k + 1])
    return np.array([sn[0], vn[0], sn[1], vn[1]])


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow], phases=PHASES)
@given(problems, st.integers(3, 40), st.sampled_from(["foh", "zoh"]), st.integers(0, 10_000))
def test_hold_trajectory_report_matches_dense_evaluation(problem, N, hold, seed):
    traj = integrated_hold(problem, N, hold, seed)
    check_against_dense(problem, traj)


def test_roots_in_unit_interval_finds_every_root():
    rng = np.random.default_rng(0)
    r = rng.uniform(0, 1, size=(200, 3))
    C = np.array([np.polynomial.polynomial.polyfromroots(x) for x in r])
    rows, sig = roots_in_unit_interval(C)
    for i in range(200):
        assert np.allclose(np.sort(sig[rows == i]), np.sort(r[i]), atol=1e-9)


def test_equality_plan_touches_its_corner_and_paper_2_poly_is_unsafe():
    p1 = PMPPlanner().plan(paper_problem(1))
    rep1 = p1.safety if hasattr(p1, "safety") else safety_report(p1.problem, p1.trajectory)
    assert rep1.vehicles[0].min_clearance_m == pytest.approx(0.0, abs=1e-9)  # the corner is touched
    assert rep1.collision_free
    p2 = PMPPlanner().plan(paper_problem(2))
    rep2 = safety_report(p2.problem, p2.trajectory)
    v = rep2.vehicles[0]
    assert not rep2.intrusion_free and not rep2.collision_free
    # the ego ends 73 m down the road inside vehicle 1's box: the intrusion lasts to t_f
    assert v.intrusion[-1][1] == pytest.approx(p2.problem.tf)
    assert v.intrusion[0][0] == pytest.approx(p2.contact_times[0], abs=2e-3)
    assert v.max_intrusion_m == pytest.approx(1.4, abs=1e-9)  # W/2 + S_y: the ego reaches y_s


# --- the CLI (SPEC §9 JSON, text lines, --require-safe) and the ego body ------------------


def test_cli_plan_json_carries_the_safety_report_and_require_safe_exits_4(cli):
    import json

    out = cli("plan", "paper-2-poly", "--json")
    assert out.returncode == 0, out.stderr
    saf = json.loads(out.stdout)["safety"]
    assert saf["collision_free"] is False and saf["intrusion_free"] is False
    v = saf["vehicles"][0]
    assert set(v) >= {"name", "intrusion", "max_intrusion_m", "overlap", "min_clearance_m"}
    assert v["intrusion"][-1][1] == pytest.approx(5.0)
    unsafe = cli("plan", "paper-2-poly", "--require-safe")
    assert unsafe.returncode == 4
    assert "UNSAFE" in unsafe.stdout and "sv1" in unsafe.stdout  # one line per unsafe vehicle
    safe = cli("plan", "paper-3-poly", "--require-safe")
    assert safe.returncode == 0 and "intrusion-free and collision-free" in safe.stdout


def test_cli_avoid_infeasible_exits_3_with_the_reason(cli):
    import json

    out = cli("plan", "paper-2-poly", "--planner", "qp", "--constraint", "avoid", "--steps", "20", "--json")
    assert out.returncode == 3
    d = json.loads(out.stdout)
    assert d["status"] == "infeasible" and d["cost"] is None and "inside" in d["reason"]


def test_ego_body_keys_change_the_overlap():
    from iamp.core.scenario import builtin_text, loads_scenario

    base = loads_scenario(builtin_text("paper-2-poly")).to_problem()[0]
    small = loads_scenario(builtin_text("paper-2-poly").replace("[ego]", "[ego]\nlength = 1.0\nwidth = 0.5"))
    problem = small.to_problem()[0]
    assert (problem.ego.ego_length, problem.ego.ego_width) == (1.0, 0.5)
    plan = PMPPlanner().plan(base)
    big_overlap = safety_report(base, plan.trajectory).vehicles[0].overlap
    small_overlap = safety_report(problem, plan.trajectory).vehicles[0].overlap
    # a smaller ego body overlaps later (the same trajectory, the same vehicle)
    assert small_overlap[0][0] > big_overlap[0][0]
    with pytest.raises(ValueError, match="ego.width"):
        loads_scenario(builtin_text("paper-2-poly").replace("[ego]", "[ego]\nwidth = 0"))
