"""Goal variants not used while the planner was tuned (issue 33: seeds 7, 11, 13 of
``scripts/commonroad_variants.py``) and the general causes of their failures.

Each variant is rebuilt here from its source problem and the goal states the script wrote for it
(``variants.json``), so a test needs one shared file, not the script's run over the whole folder.
Every test needs the ``[commonroad]`` extra and the shared US-101 data; each skips with the
reason where either is absent.
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path
from typing import Any

import numpy as np
from conftest import data_path, needs_commonroad_data

DATA = data_path("commonroad", "US101")
needs_data = needs_commonroad_data("commonroad", "US101")


def with_goal(tmp_path: Path, source: str, name: str, goal_states: list[dict[str, Any]]) -> Path:
    """``source`` (a shared US-101 file) with its goal replaced by ``goal_states`` (each as
    ``variants.json`` describes one: ``time_step``, ``velocity``, ``orientation`` intervals, a
    rectangle ``position``), written as ``name`` with the benchmark ID ``name``."""
    from commonroad.common.file_reader import CommonRoadFileReader
    from commonroad.common.file_writer import CommonRoadFileWriter, OverwriteExistingFile
    from commonroad.common.util import AngleInterval, Interval
    from commonroad.geometry.shape import Rectangle
    from commonroad.planning.goal import GoalRegion
    from commonroad.scenario.scenario import ScenarioID
    from commonroad.scenario.state import CustomState

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scenario, pps = CommonRoadFileReader(str(DATA / source)).open()
    pp = next(iter(pps.planning_problem_dict.values()))
    states = []
    for g in goal_states:
        p = g["position"]
        st = CustomState(time_step=Interval(int(g["time_step"][0]), int(g["time_step"][1])),
                         position=Rectangle(p["length"], p["width"], np.array(p["center"]), p["orientation"]))
        if g.get("velocity") is not None:
            st.velocity = Interval(*g["velocity"])
        if g.get("orientation") is not None:
            st.orientation = AngleInterval(*g["orientation"])
        states.append(st)
    pp.goal = GoalRegion(states)
    scenario.scenario_id = ScenarioID.from_benchmark_id(name, "2020a")
    out = tmp_path / f"{name}.xml"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        CommonRoadFileWriter(scenario, pps, "iamp", "iamp", "tests", "").write_to_file(
            str(out), OverwriteExistingFile.ALWAYS)
    return out


def _valid(cr: Any, rp: Any) -> Any:
    from iamp.commonroad.check import check
    from iamp.commonroad.solution import build_solution

    solution, _ = build_solution(cr, rp.trajectory, rp.candidate.steps)
    return check(cr.scenario, cr.planning_problem_set, solution, cost=False)


#: USA_US101-23_802_T-1 (seed 7, ``lanes``): two lanes to the left of the exit lane the ego is in.
GOAL_23_802 = [{"time_step": [130, 140], "velocity": [13.5903, 19.5903], "orientation": [-0.7783, -0.6038],
                "position": {"center": [168.1576, -143.2472], "length": 2.1212, "width": 1.6317,
                             "orientation": -0.72225}}]


@needs_data
def test_a_gore_area_between_lanes_is_a_hole_in_the_road(tmp_path: Path) -> None:
    """US101-23's exit lane (lanelet 29) parts from the next lane (7) from s = 234 m on, with a gore
    area between them that no lanelet covers: CommonRoad's road boundary (the lanelets'
    triangulation) has a hole there.  The corridor took only the extreme bounds of its lanelets,
    so the body check saw one road from -1.9 to 19 m, and the free plan to the goal two lanes over
    drove through the gore (13-50 cm deep by the checker).  Now every gap between the corridor's
    lanelets is a road-edge box (``hole``); each box's centre is off CommonRoad's road (its own
    boundary collision checker), and the plan is valid by the checker."""
    from commonroad_dc import pycrcc
    from commonroad_dc.feasibility import solution_checker as sc

    from iamp.commonroad.convert import load
    from iamp.commonroad.planning import plan

    cr = load(with_goal(tmp_path, "USA_US101-23_1_T-1.xml", "USA_US101-23_802_T-1", GOAL_23_802))
    holes = [o for o in cr.road_edges if o.hole]
    assert len(holes) > 10
    boundary = sc._construct_boundary_checker(cr.scenario)
    for ob in holes:
        s, d = 0.5 * (ob.s_lo[0] + ob.s_hi[0]), 0.5 * (ob.d_lo[0] + ob.d_hi[0])
        x, y = np.asarray(cr.frame.to_world(np.array([s]), np.array([d])), dtype=float).reshape(-1)[:2]
        assert boundary.collide(pycrcc.Circle(0.01, float(x), float(y))), (s, d)
    rp = plan(cr)
    assert rp.safe, rp.reason
    verdict = _valid(cr, rp)
    assert verdict.valid, verdict.checks


def test_hole_runs_cover_every_gap_sample() -> None:
    """:func:`~iamp.commonroad.convert._hole_runs`: every sample's gap lies inside a piece's
    bounds at that ``s``, each piece's bounds vary by at most ``HOLE_VARY_M`` and two gaps that
    never overlap laterally are never in one piece."""
    from iamp.commonroad.convert import EDGE_CHUNK_M, EDGE_STEP_M, HOLE_VARY_M, _hole_runs

    grid = np.arange(0.0, 40.0, EDGE_STEP_M)
    gaps: list[list[tuple[float, float]]] = []
    for s in grid:
        here = []
        if s >= 5.0:  # a gore widening by 2.5 cm/m
            here.append((2.1, 2.1 + 0.025 * (s - 5.0) + 0.06))
        if 10.0 <= s < 20.0:  # a second, separate gap
            here.append((8.0, 8.2))
        gaps.append(here)
    runs = _hole_runs(grid, gaps)
    for s, here in zip(grid, gaps):
        for a, b in here:
            assert any(r[0][0] <= s <= r[0][-1] and r[1].min() <= a and r[2].max() >= b for r in runs), (s, a, b)
    for rs, rlo, rhi in runs:
        assert np.ptp(rlo) <= HOLE_VARY_M + 1e-12 and np.ptp(rhi) <= HOLE_VARY_M + 1e-12
        assert (len(rs) - 1) * EDGE_STEP_M <= EDGE_CHUNK_M
        assert not (rlo.min() < 5.0 < rhi.max()), "two separate gaps in one piece"
    assert math.isclose(min(r[0][0] for r in runs), 5.0)
