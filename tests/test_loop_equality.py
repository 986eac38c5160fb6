"""The closed loop poses the equality planners (``pmp``, ``qp``) only the corners in the way.

The paper's equality makes the ego pass *through* each corner (SPEC §1). The decision layer used
to pose it on the gap's follower (``front-lower``), the gap's leader (``rear-lower``) and the
current lane's leader: with the car's limits the bounded PMP found no contact times on 307 of
311 problems of the seed-1 dense merge and the ego stopped at the lane's end.  Two corners on one
line need two crossings of it; a corner the unconstrained plan clears drags the ego back
(SPEC §2 identity 4).  :func:`~iamp.simulation.decision.corners_in_the_way` keeps a vehicle only
if the minimum-energy cubic enters its region, one per side, the deepest.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from iamp.core.free import FreeTrajectory
from iamp.core.physical import PASSENGER_CAR
from iamp.core.problem import EgoBoundary, Problem, SurroundingVehicle
from iamp.core.safety import SAFETY_TOLERANCE_M
from iamp.core.status import SUCCESS
from iamp.simulation.decision import (
    BODY_REGION,
    DecisionConfig,
    EgoNow,
    Gap,
    Neighbour,
    corners_in_the_way,
    lane_change_problem,
    limit_violations,
)
from iamp.simulation.planning import EQUALITY_PLANNERS, make_planner

# the first problem the loop's pmp was given on merge/dense/seed 1 (the ego in the merge lane at
# y = -9.375, the target lane at -5.625): gap follower v66 behind, gap leader v65 ahead
EGO = EgoNow(731.0846833039553, 8.877106573438839, -9.375001814294114, 2.1958012846751507e-06)
V66 = Neighbour("v66", (727.0722094261515, 5.093446456436561, -0.048277611916384015, 0.0012800323652421579),
                -5.62, 4.4, 1.8, 1)
V65 = Neighbour("v65", (741.5857944600715, 7.1935250765701175, -0.02670711520908308, -0.0004886852183769874),
                -5.62, 4.6, 1.8, 1)
END = (758.7684014012505, 4.993812587415903)
REGIONS = {"v66": 9.312925868639287, "v65": 8.332903667780101}


def _problem(equality: bool) -> Problem | EgoBoundary:
    cfg = DecisionConfig(safety_x=BODY_REGION[0], safety_y=BODY_REGION[1], equality=equality)
    return lane_change_problem(EGO, -5.625, Gap(V66, V65), None, cfg, 4.0, END,
                               lambda n, role, b: REGIONS[n.name])


def test_the_loop_poses_the_registry_equality_planners():
    assert EQUALITY_PLANNERS == ("pmp", "qp")


def test_two_corners_on_one_line_have_no_bounded_plan_and_the_corner_in_the_way_has_one():
    full = _problem(equality=False)
    assert isinstance(full, Problem) and [v.corner for v in full.vehicles] == ["front-lower", "rear-lower"]
    assert full.vehicles[0].corner_y == full.vehicles[1].corner_y  # one line, crossed once by a lane change
    plan = make_planner("pmp")(full)
    assert plan.status == "infeasible"  # what the loop got on 292 of 311 calls
    posed = _problem(equality=True)
    # the cubic enters both regions (the gap is short at the crossing), the leader's deeper: only it is posed
    assert isinstance(posed, Problem) and [v.name for v in posed.vehicles] == ["v65"]
    for name in EQUALITY_PLANNERS:
        plan = make_planner(name)(posed)
        assert plan.status in SUCCESS, (name, plan.status)
        assert limit_violations(plan.require_trajectory(), 4.0, PASSENGER_CAR) == []
        # the plan passes through the leader's corner: at its contact time the ego is at the corner
        if name == "pmp":
            t1 = float(plan.contact_times[0])
            X = np.asarray(plan.require_trajectory().states(np.array([t1])))[0]
            v = posed.vehicles[0]
            corner_x = float(np.polynomial.polynomial.polyval(t1, v.x_poly)) - v.length / 2 - v.safety_x
            assert X[0] == pytest.approx(corner_x, abs=1e-6) and X[2] == pytest.approx(v.corner_y, abs=1e-6)


def test_a_corner_the_cubic_clears_drags_the_equality_and_is_left_out():
    """Merge/dense/1, 4 s later: the follower 25 m behind the ego. The equality at its corner has no
    plan within the limits (certified), the cubic never enters its region: not posed."""
    ego = EgoBoundary(tf=5.0, x0=766.5657774199307, y0=-9.375, vx0=3.7214734429469924, vy0=0.0,
                      xf=791.4829971611385, yf=-5.625, vxf=5.247640038003976, vyf=0.0)
    f = SurroundingVehicle((744.4458000240558, 2.6623972805458442, 0.0, 0.0), "front-lower", -5.62, 4.4, 1.8,
                           4.8908121083244644, 1.2, name="f")
    prob = Problem(ego, (f,), "lane-change", PASSENGER_CAR)
    assert make_planner("pmp")(prob).status == "infeasible"
    assert corners_in_the_way(prob) == ego


def _depth(traj: FreeTrajectory, v: SurroundingVehicle, tf: float) -> float:
    """The deepest entry of the ego's point into ``v``'s region on a 0.1 ms grid (independent of §9's roots)."""
    t = np.linspace(0.0, tf, int(tf * 1e4) + 1)
    X = traj.states(t)
    dx = X[:, 0] - np.polynomial.polynomial.polyval(t, v.x_poly)
    dy = X[:, 2] - v.y
    return float(np.max(np.minimum(v.length / 2 + v.safety_x - np.abs(dx), v.width / 2 + v.safety_y - np.abs(dy))))


@settings(max_examples=60, deadline=None)
@given(x_f=st.floats(-40, 10), x_l=st.floats(0, 50), x_c=st.floats(5, 50), v=st.floats(5, 30),
       dv=st.tuples(st.floats(-5, 5), st.floats(-5, 5), st.floats(-5, 5)), xf=st.floats(60, 160),
       sx=st.tuples(st.floats(3, 20), st.floats(3, 20), st.floats(3, 20)), w=st.sampled_from([1.8, 2.5]))
def test_corners_in_the_way_are_the_entered_regions_one_per_side_the_deepest(x_f, x_l, x_c, v, dv, xf, sx, w):
    ego = EgoBoundary(tf=5.0, x0=0.0, y0=-9.375, vx0=v, vy0=0.0, xf=xf, yf=-5.625, vxf=v, vyf=0.0)
    vs = (SurroundingVehicle((x_f, v + dv[0]), "front-lower", -5.625, 4.6, w, sx[0], 1.2, name="f"),
          SurroundingVehicle((x_l + x_f + 10, v + dv[1]), "rear-lower", -5.625, 4.6, 1.8, sx[1], 1.2, name="l"),
          SurroundingVehicle((x_c, v + dv[2]), "rear-upper", -9.375, 4.6, 1.8, sx[2], 1.2, name="c"))
    prob = Problem(ego, vs, "lane-change", PASSENGER_CAR)
    traj = FreeTrajectory.of(ego)
    depth = {u.name: _depth(traj, u, 5.0) for u in vs}
    assume(all(abs(d - SAFETY_TOLERANCE_M) > 1e-3 for d in depth.values()))  # the grid decides the same
    posed = corners_in_the_way(prob)
    kept = [] if isinstance(posed, EgoBoundary) else [u.name for u in posed.vehicles]
    entered = [u.name for u in vs if depth[u.name] > SAFETY_TOLERANCE_M]
    lower = [n for n in entered if n in ("f", "l")]
    expect = ([max(lower, key=lambda n: depth[n])] if lower else []) + (["c"] if "c" in entered else [])
    assert kept == [n for n in ("f", "l", "c") if n in expect]
    if not kept:
        assert posed == ego
