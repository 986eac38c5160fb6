"""CommonRoad (SPEC §16): the road frame (exact back-transform), the conversion of a scenario,
solutions judged valid by CommonRoad's checker, and the check's per-check output.

The frame tests need numpy only.  The rest needs the ``[commonroad]`` extra and the shared
US-101 scenarios (``$IAMP_DATA/commonroad/US101``, default ``<repo>/../shared/data``: conftest's
``data_path``); they skip with the reason where either is absent.
"""

from __future__ import annotations

import importlib.util
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import data_path
from hypothesis import given, settings
from hypothesis import strategies as st

from iamp.commonroad.frame import RoadFrame

ROOT = Path(__file__).resolve().parents[1]
DATA = data_path("commonroad", "US101")
HAVE_EXTRA = all(importlib.util.find_spec(m) is not None for m in ("commonroad", "commonroad_dc", "triangle"))
needs_data = pytest.mark.skipif(not HAVE_EXTRA or not DATA.is_dir(),
                                reason=("the [commonroad] extra is not installed (pip install 'iamp[commonroad]')"
                                        if not HAVE_EXTRA else f"the shared CommonRoad data is absent ({DATA})"))


def _frame(angle: float, bend: float, wiggle: float) -> RoadFrame:
    u = np.linspace(0.0, 250.0, 80)
    w = bend * 1e-4 * u**2 + wiggle * 1e-7 * u**3
    c, s = math.cos(angle), math.sin(angle)
    pts = np.c_[10.0 + u * c - w * s, -5.0 + u * s + w * c]
    return RoadFrame.fit(pts)


@settings(max_examples=60, deadline=None)
@given(angle=st.floats(-math.pi, math.pi), bend=st.floats(-3.0, 3.0), wiggle=st.floats(-5.0, 5.0),
       s=st.lists(st.floats(-20.0, 270.0), min_size=1, max_size=20),
       d=st.floats(-15.0, 15.0))
def test_frame_back_transform_is_exact(angle: float, bend: float, wiggle: float, s: list[float], d: float) -> None:
    """(s, d) -> world -> (s, d) to 1e-6 m (the SPEC asks 1 cm); the world point is at distance |d|
    from the path point at s, along the normal (an independent check of the offset)."""
    f = _frame(angle, bend, wiggle)
    S = np.array(s)
    D = np.full_like(S, d)
    xy = f.to_world(S, D)
    back = f.to_road(xy)
    assert np.max(np.abs(back[:, 0] - S)) < 1e-6
    assert np.max(np.abs(back[:, 1] - D)) < 1e-6
    on_path = f.to_world(S, np.zeros_like(S))
    assert np.allclose(np.linalg.norm(xy - on_path, axis=1), abs(d), atol=1e-9)
    h = f.heading(S)
    tangent = np.c_[np.cos(h), np.sin(h)]
    assert np.max(np.abs(np.sum((xy - on_path) * tangent, axis=1))) < 1e-9


@settings(max_examples=30, deadline=None)
@given(angle=st.floats(-math.pi, math.pi), bend=st.floats(-3.0, 3.0), a=st.floats(0.0, 200.0), b=st.floats(1.0, 60.0))
def test_frame_arc_length_matches_a_dense_polyline(angle: float, bend: float, a: float, b: float) -> None:
    """s is arc length: the distance between s = a and a + b equals a 20 000-segment polyline's length."""
    f = _frame(angle, bend, 0.0)
    pts = f.to_world(np.linspace(a, a + b, 20001), 0.0)
    assert abs(np.sum(np.linalg.norm(np.diff(pts, axis=0), axis=1)) - b) < 1e-6


@settings(max_examples=30, deadline=None)
@given(bend=st.floats(-3.0, 3.0), s0=st.floats(0.0, 200.0), d0=st.floats(-10.0, 10.0),
       vs=st.floats(0.0, 35.0), vd=st.floats(-3.0, 3.0))
def test_frame_velocity_is_the_derivative_of_the_position(bend: float, s0: float, d0: float, vs: float,
                                                           vd: float) -> None:
    """The Frenet velocity equals the central difference of the world position of (s0 + vs t, d0 + vd t),
    and velocity_to_road inverts it."""
    f = _frame(0.3, bend, 0.0)
    h = 1e-4
    p1 = f.to_world(s0 + vs * h, d0 + vd * h)[0]
    p0 = f.to_world(s0 - vs * h, d0 - vd * h)[0]
    fd = (p1 - p0) / (2 * h)
    v = f.velocity_to_world(s0, d0, vs, vd)[0]
    assert np.allclose(v, fd, atol=1e-5)
    assert np.allclose(f.velocity_to_road(s0, d0, v[None, :])[0], [vs, vd], atol=1e-9)


def test_missing_extra_names_the_pip_line(monkeypatch: pytest.MonkeyPatch) -> None:
    import iamp
    from iamp import commonroad

    real = importlib.import_module

    def fake(name: str, *args: object) -> object:
        if name == "commonroad_dc":
            raise ImportError("no")
        return real(name)

    monkeypatch.setattr(commonroad.importlib, "import_module", fake)
    with pytest.raises(iamp.MissingDependencyError, match=r"\[commonroad\].*pip install 'iamp\[commonroad\]'"):
        commonroad.require()


# --- with the extra and the data ---------------------------------------------------------------


@needs_data
def test_conversion_of_a_scenario() -> None:
    """The ego's initial state and the goal map back to the world exactly; the recorded vehicles'
    cubic boxes cover every recorded corner; lanes are 3-4 m apart; the road edges contain them."""
    from iamp.commonroad.convert import load

    cr = load(DATA / "USA_US101-11_1_T-1.xml")
    init = cr.planning_problem.initial_state
    s0, vs0, d0, vd0 = cr.x0
    assert np.allclose(cr.frame.to_world(s0, d0)[0], init.position, atol=1e-6)
    v = cr.frame.velocity_to_world(s0, d0, vs0, vd0)[0]
    assert abs(math.hypot(*v) - init.velocity) < 1e-6
    assert abs(math.atan2(v[1], v[0]) - init.orientation) < 1e-6
    rect = cr.planning_problem.goal.state_list[0].position
    for c in cr.candidates:
        assert rect.contains_point(cr.frame.to_world(c.s, c.d)[0])
        speed = cr.goal.elements[c.element].speed
        assert speed is not None and speed[0] <= math.hypot(c.vs, c.vd) <= speed[1]
    spacing = np.diff(cr.lanes)
    assert np.all((spacing > 3.0) & (spacing < 4.2)), cr.lanes
    assert cr.road_y[0] < cr.lanes[0] and cr.lanes[-1] < cr.road_y[1]
    assert cr.frame_fit_residual_m < 0.5
    for ob in cr.obstacles:
        centre = np.polynomial.polynomial.polyval(ob.t, ob.cubic)
        assert np.all(ob.s_lo >= centre - ob.half_length - 1e-9)
        assert np.all(ob.s_hi <= centre + ob.half_length + 1e-9)
        assert ob.lane_change == (np.ptp(0.5 * (ob.d_lo + ob.d_hi)) > 1.0)


@needs_data
@pytest.mark.parametrize("name", ["USA_US101-2_1_T-1", "USA_US101-20_1_T-1", "USA_US101-21_1_T-1"])
def test_default_planner_solution_is_valid_by_commonroad(name: str) -> None:
    """The default planner's solution passes every CommonRoad check (the goal with the PM
    orientation defect worked around), and the raw goal test fails for exactly that defect:
    atan2(v_y, |v|) lies outside the goal's orientation interval while atan2(v_y, v_x) lies inside."""
    from iamp.commonroad.check import check
    from iamp.commonroad.convert import load
    from iamp.commonroad.planning import plan
    from iamp.commonroad.solution import build_solution

    cr = load(DATA / f"{name}.xml")
    rp = plan(cr)
    assert rp.safe and rp.candidate is not None
    sol, drift = build_solution(cr, rp.trajectory, rp.candidate.steps)
    assert drift < 0.02
    v = check(cr.scenario, cr.planning_problem_set, sol)
    assert v.valid, v.lines()
    assert v.colliding_obstacles == []
    last = sol.planning_problem_solutions[0].trajectory.state_list[-1]
    goal = cr.planning_problem.goal.state_list[0].orientation
    correct = math.atan2(last.velocity_y, last.velocity)
    defect = math.atan2(last.velocity_y, math.hypot(last.velocity, last.velocity_y))
    assert goal.start <= correct <= goal.end
    if not goal.start <= defect <= goal.end:
        assert not v.checks["goal_reached"]["ok"] and not v.valid_commonroad_raw


@needs_data
def test_road_edges_follow_commonroads_road_boundary() -> None:
    """USA_US101-21 has an on-ramp behind a gore area that joins the road at s = 85.7 m: the
    corridor reachable by adjacency is narrower before it, and that part becomes a road-edge box.
    Every box is on the narrow side of the §14 ``y`` limits, and a 0.2 m square 0.25 m inside its
    inner edge (on the corridor's side) is on the road by CommonRoad's own boundary (the checker's
    triangulation), so the boxes never forbid road CommonRoad accepts by more than that."""
    import commonroad_dc.feasibility.solution_checker as sc
    from commonroad_dc import pycrcc

    from iamp.commonroad.convert import EDGE_TOL_M, load

    cr = load(DATA / "USA_US101-21_1_T-1.xml")
    assert cr.road_edges, "the gore area before the merge must be a road-edge box"
    lo, hi = cr.road_y
    before_merge = [b for b in cr.road_edges if b.d_lo[0] < lo and b.s_hi[0] < 86.0]
    assert before_merge and max(b.d_hi[0] for b in before_merge) < lo + 4.5  # lane 20's right edge
    boundary = sc._construct_boundary_checker(cr.scenario)
    for b in cr.road_edges:
        below = b.d_lo[0] < lo
        inner = b.d_hi[0] if below else b.d_lo[0]
        assert (inner > lo + EDGE_TOL_M) if below else (inner < hi - EDGE_TOL_M)
        s_mid = 0.5 * (b.s_lo[0] + b.s_hi[0])
        p = cr.frame.to_world(s_mid, inner + (0.25 if below else -0.25))[0]
        heading = float(np.atleast_1d(cr.frame.heading(s_mid))[0])
        assert not boundary.collide(pycrcc.RectOBB(0.1, 0.1, heading, float(p[0]), float(p[1]))), b.obstacle_id


@needs_data
def test_check_names_the_obstacle_it_collides_with(tmp_path: Path) -> None:
    """A solution that drives exactly along a recorded obstacle collides with that obstacle (named),
    and `iamp commonroad check` prints every check's verdict with exit status 3."""
    from commonroad.common.solution import (
        CommonRoadSolutionWriter,
        CostFunction,
        PlanningProblemSolution,
        Solution,
        VehicleModel,
        VehicleType,
    )
    from commonroad.scenario.state import PMState
    from commonroad.scenario.trajectory import Trajectory

    from iamp.commonroad.convert import load

    path = DATA / "USA_US101-11_1_T-1.xml"
    cr = load(path)
    ob = max(cr.scenario.dynamic_obstacles, key=lambda o: len(o.prediction.trajectory.state_list))
    states = [ob.initial_state] + list(ob.prediction.trajectory.state_list)
    pm = [PMState(time_step=s.time_step, position=np.asarray(s.position), velocity=s.velocity * math.cos(s.orientation),
                  velocity_y=s.velocity * math.sin(s.orientation)) for s in states[:40]]
    sol = Solution(cr.scenario.scenario_id, [PlanningProblemSolution(
        planning_problem_id=cr.planning_problem.planning_problem_id, vehicle_type=VehicleType.BMW_320i,
        vehicle_model=VehicleModel.PM, cost_function=CostFunction.WX1,
        trajectory=Trajectory(initial_time_step=states[0].time_step, state_list=pm))])
    out = tmp_path / "bad.xml"
    out.write_text(CommonRoadSolutionWriter(sol).dump())
    proc = subprocess.run([sys.executable, "-W", "ignore", "-m", "iamp", "commonroad", "check", str(path), str(out)],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 3, proc.stderr
    lines = proc.stdout.splitlines()
    for name in ("starts_at_initial_state", "kinematically_feasible", "collision", "road_boundary", "goal_reached",
                 "goal_reached_corrected"):
        assert any(line.startswith(name) for line in lines), proc.stdout
    coll = next(line for line in lines if line.startswith("collision"))
    assert "FAIL" in coll and str(ob.obstacle_id) in coll


@needs_data
def test_plan_cli_writes_and_refuses_to_overwrite(tmp_path: Path) -> None:
    out = tmp_path / "sol.xml"
    cmd = [sys.executable, "-W", "ignore", "-m", "iamp", "commonroad", "plan", str(DATA / "USA_US101-9_1_T-1.xml"),
           "--out", str(out)]
    first = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert first.returncode == 0, first.stdout + first.stderr
    assert out.is_file() and "valid (corrected goal)     yes" in first.stdout
    again = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert again.returncode == 2 and "exists" in again.stderr and "Traceback" not in again.stderr


@needs_data
def test_predicted_mode_is_the_predictors_pipeline() -> None:
    """``--predict``: each vehicle's predicted centre equals what the §7 predictor itself predicts
    from a noise-free history consistent with the recorded state at t = 0 (position, road speed,
    acceleration a0: a quadratic, on which the smoother is exact and every chain state is the bin of
    a0) — an independent path through ``Predictor.predict`` — at every model node; the box keeps
    the recorded t = 0 extents (lane kept), and the fitted cubic covers the predicted centre."""
    from iamp.commonroad.convert import load
    from iamp.commonroad.predicted import _road_speed, predict_obstacles
    from iamp.core.scenario import History
    from iamp.prediction.predictor import Predictor

    cr = load(DATA / "USA_US101-11_1_T-1.xml")
    pc = predict_obstacles(cr)
    pred = Predictor.default()
    assert [o.obstacle_id for o in pc.obstacles] == [o.obstacle_id for o in cr.obstacles if o.t[0] == 0.0]
    moved = 0
    for ob, pr in zip(cr.obstacles, pc.obstacles, strict=True):
        a0 = float(cr.scenario.obstacle_by_id(ob.obstacle_id).initial_state.acceleration)
        s0 = 0.5 * (ob.s_lo[0] + ob.s_hi[0])
        v0 = _road_speed(cr, ob.obstacle_id, s0, 0.5 * (ob.d_lo[0] + ob.d_hi[0]))
        th = np.linspace(-1.0, 0.0, 11)
        ref = pred.predict(History(th, s0 + v0 * th + 0.5 * a0 * th**2), float(ob.t[-1]))
        centre = 0.5 * (pr.s_lo + pr.s_hi)
        nodes = [k for k, t in enumerate(ob.t) if abs(t / pred.dt - round(t / pred.dt)) < 1e-9]
        np.testing.assert_allclose(centre[nodes], np.interp(ob.t[nodes], ref.t, ref.x), atol=1e-8)
        np.testing.assert_allclose(pr.s_hi - pr.s_lo, ob.s_hi[0] - ob.s_lo[0], atol=1e-12)
        assert np.all(pr.d_lo == ob.d_lo[0]) and np.all(pr.d_hi == ob.d_hi[0])
        fit = np.polynomial.polynomial.polyval(ob.t, pr.cubic)
        assert np.all(np.abs(fit - centre) <= pr.fit_residual_m + 1e-12)
        moved += bool(np.max(np.abs(centre - 0.5 * (ob.s_lo + ob.s_hi))) > 0.5)
    assert moved > 0  # the prediction is not the recording


HAVE_SUMO = importlib.util.find_spec("libsumo") is not None or importlib.util.find_spec("traci") is not None
INTERACTIVE = data_path("commonroad", "interactive-US101")


@pytest.mark.skipif(not HAVE_EXTRA or not HAVE_SUMO or not INTERACTIVE.is_dir(),
                    reason="needs the [commonroad] and [sim] extras and the shared interactive scenarios "
                           f"({INTERACTIVE})")
def test_interactive_closed_loop_reaches_the_goal_without_contact() -> None:
    """``iamp simulate --commonroad``: the executed run ends inside CommonRoad's goal region (the
    goal test of commonroad-io, orientation corrected) within its time window, without body
    overlap or SUMO collision, within the vehicle's acceleration limit; SUMO's traffic is compared
    with the recording of the same vehicles."""
    from iamp.commonroad.interactive import simulate

    r = simulate(INTERACTIVE / "USA_US101-11_1_I-1-1", recording=DATA / "USA_US101-11_1_T-1.xml")
    assert r["goal_reached"] and r["status"] == "goal reached"
    lo, hi = r["goal_window_s"]
    assert lo - 1e-9 <= r["time_to_goal_s"] <= hi + 1e-9
    assert r["collisions"] == 0 and r["limit_violations"] == 0 and r["ego_peak_accel"] <= r["a_max"]
    assert r["sumo_vs_recording"]["vehicles_compared"] > 0


@needs_data
def test_interactive_folder_without_a_planning_problem_is_refused() -> None:
    cmd = [sys.executable, "-W", "ignore", "-m", "iamp", "simulate", "--commonroad",
           str(INTERACTIVE / "USA_US101-11_10_I-1-1")]
    if not (INTERACTIVE / "USA_US101-11_10_I-1-1").is_dir():
        pytest.skip(f"the shared interactive scenarios are absent ({INTERACTIVE})")
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "no planning problem" in r.stderr and "Traceback" not in r.stderr


@needs_data
def test_bench_cli_table_and_refusals(tmp_path: Path) -> None:
    """``iamp commonroad bench``: an unknown planner is refused (exit 2, one line); on a folder of
    one scenario every planner has exactly one row, the counts of every planner sum to the
    scenarios, the report names its command, and the default planner's row is valid there."""
    import json

    folder = tmp_path / "one"
    folder.mkdir()
    (folder / "USA_US101-20_1_T-1.xml").symlink_to(DATA / "USA_US101-20_1_T-1.xml")
    base = [sys.executable, "-W", "ignore", "-m", "iamp", "commonroad", "bench", str(folder)]
    bad = subprocess.run([*base, "--planners", "avoid,nope"], capture_output=True, text=True, timeout=120)
    assert bad.returncode == 2 and "nope" in bad.stderr and "Traceback" not in bad.stderr
    out = tmp_path / "out"
    r = subprocess.run([*base, "--planners", "avoid,free,avoid+predict", "--out", str(out), "--json"],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    data = json.loads((out / "bench.json").read_text())
    assert "iamp commonroad bench" in data["command"] and data["command"] in (out / "bench.md").read_text()
    for e in data["summary"]:
        assert e["scenarios"] == 1
        assert sum(e[c] for c in ("valid", "collision", "infeasible", "goal missed", "off road", "no plan",
                                  "timeout")) == 1
    rows = {row["planner"]: row for row in data["rows"]}
    assert rows["avoid"]["category"] == "valid"
    assert (out / "solutions" / "avoid" / "USA_US101-20_1_T-1.solution.xml").is_file()
