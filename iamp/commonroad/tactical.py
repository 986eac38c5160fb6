r"""A tactical layer for the closed loop: one lane at a time toward the goal's lane.

The road planner (:mod:`iamp.commonroad.planning`) plans to the goal region in one piece and
imposes the vehicles in its way one at a time (the active set).  A goal several lanes over,
with traffic in every lane in between, often has no such plan even where the lanes have gaps:
the plan that crosses three lanes of traffic at once needs several vehicles imposed together.
When the loop's replan toward the goal finds no safe plan, this layer proposes a shorter
manoeuvre instead: **a lane change into the next lane toward the goal's lane**, ending after
:data:`HORIZONS_S` at the lane's centre, parallel to the road, at a speed chosen to fit the
traffic there (:func:`waypoints`).  Each such final state is planned with the same road planner
(the same counted budgets), and a plan is accepted only when

* it keeps clear of every predicted vehicle over its horizon (the planner's own test, ``safe``),
  within the friction circle, and
* its final state is one from which RSS holds in the new lane (:func:`rss_clear_at`): braking
  at ``STOP_DECEL_FRACTION a_max`` stops the ego behind the vehicle ahead whatever that one does
  within RSS's ``brake_max``, and the vehicle behind has room to slow to the ego's speed with a
  comfortable braking after its response time (:func:`follower_gap`, MOBIL's safety criterion;
  RSS's full safe distance behind, 35 m at 17 m/s, is longer than most gaps of dense US-101
  traffic, so a cut-in accepted here can leave RSS's distance to the new follower unmet for a
  while, which the loop's judge measures).

The loop (:func:`iamp.commonroad.interactive.simulate_with_log`) uses it twice:

* **early**: a goal two or more lanes over (:class:`LaneMap`) whose cheapest final state is at
  least :data:`EARLY_MIN_S` ahead is approached one lane at a time before its plan is tried
  (the plan across several lanes of traffic is the one the active set fails at);
* **instead of braking**: when the replan toward the goal finds no safe plan and neither that plan
  nor the previous plan's remainder keeps clear, an accepted lane change comes before a new
  fail-safe brake.

A lane change under way is finished without replanning while it still holds under the newest
predictions (:func:`still_holds`: clear of the predicted boxes, RSS's stopping distance to the
car ahead along the way and at its end); when it no longer holds it is given up, not kept as a
fallback, and the loop replans (USA_US101-2_1: finishing one while the car ahead in the new
lane braked harder than predicted ran into it).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from iamp.commonroad.convert import CommonRoadProblem, Obstacle, unconstrained_cost
from iamp.commonroad.goal import Candidate
from iamp.commonroad.planning import FreeTrajectory, RoadPlan, intrusions, plan

#: Horizons of a lane change [s].
HORIZONS_S = (2.0, 3.0)
#: Vehicles of the target lane this far along the road from the ego lend their speeds [m].
NEIGHBOUR_RANGE_M = 40.0
#: The ego's braking in :func:`rss_clear_at`, as a fraction of ``a_max`` (the fail-safe's hardest).
STOP_DECEL_FRACTION = 0.9
#: Room added to RSS's distance of a final state in a gap [m].
GAP_MARGIN_M = 1.0
#: Shortest time gap a lane change leaves to the vehicle behind in the new lane [s].
MIN_TIME_GAP_S = 0.5
#: A goal two or more lanes over is approached lane by lane before its plan is tried only when
#: its cheapest final state is at least this far ahead (two of the longest lane changes) [s].
EARLY_MIN_S = 2 * max(HORIZONS_S)
#: Spacing of the RSS tests along a lane change [s].
CHECK_EVERY_S = 0.5
#: Final states planned per lane change (the road planner's ``max_candidates``).
MAX_WAYPOINTS = 4


class LaneMap:
    """The scene's lanelets in the road frame: which lane the ego is in, how many lanes lie
    between it and the goal, and where the next lane's centre is further along.

    The road frame follows one chain of lanelets; the other lanes' centres drift across it where
    the road forks or curves differently (US-101's exits), so lanes are followed along the
    lanelet network (successors, predecessors and same-direction neighbours), not by a fixed
    lateral offset.

    Parameters
    ----------
    cr : CommonRoadProblem
        The scene.
    """

    def __init__(self, cr: CommonRoadProblem) -> None:
        self.net = cr.scenario.lanelet_network
        self.sd = {int(ll.lanelet_id): cr.frame.to_road(ll.center_vertices) for ll in self.net.lanelets}

    def at(self, s: float, d: float) -> int | None:
        """The lanelet covering ``s`` whose centre is nearest ``d`` there (None: none covers ``s``)."""
        best, best_dist = None, math.inf
        for lid, sd in self.sd.items():
            if sd[0, 0] - 1e-6 <= s <= sd[-1, 0] + 1e-6:
                dist = abs(float(np.interp(s, sd[:, 0], sd[:, 1])) - d)
                if dist < best_dist:
                    best, best_dist = lid, dist
        return best

    def along(self, lid: int, s: float) -> int | None:
        """The lanelet of ``lid``'s lane (first successors or predecessors) that covers ``s``."""
        seen = set()
        while lid not in seen:
            seen.add(lid)
            sd = self.sd[lid]
            ll = self.net.find_lanelet_by_id(lid)
            if s < sd[0, 0] - 1e-6 and ll.predecessor:
                lid = int(ll.predecessor[0])
            elif s > sd[-1, 0] + 1e-6 and ll.successor:
                lid = int(ll.successor[0])
            else:
                return lid if sd[0, 0] - 1e-6 <= s <= sd[-1, 0] + 1e-6 else None
        return None

    def centre(self, lid: int, s: float) -> float | None:
        """The lateral offset of ``lid``'s lane's centre at ``s`` (None: the lane does not reach it)."""
        here = self.along(lid, s)
        if here is None:
            return None
        sd = self.sd[here]
        return float(np.interp(s, sd[:, 0], sd[:, 1]))

    def steps(self, lid: int, goal: int) -> int | None:
        """Signed lanes from ``lid`` to ``goal`` (positive: to the left) across same-direction
        neighbours, or None when they are not side by side."""
        for sign, attr in ((1, "adj_left"), (-1, "adj_right")):
            cur: int | None = lid
            n = 0
            while cur is not None and n <= 10:
                if cur == goal:
                    return sign * n
                ll = self.net.find_lanelet_by_id(cur)
                nxt = getattr(ll, attr)
                same = getattr(ll, attr + "_same_direction")
                cur, n = (int(nxt), n + 1) if nxt is not None and same else (None, n)
        return None

    def toward(self, s: float, d: float, goal_s: float, goal_d: float) -> tuple[int, int | None]:
        """How many lanes the goal's lane lies from the ego's lane at ``(s, d)``, and the lanelet
        next to the ego's toward it (None when the ego is in it, or the lanes are not found)."""
        ego, goal = self.at(s, d), self.at(goal_s, goal_d)
        if ego is None or goal is None:
            return 0, None
        goal_here = self.along(goal, s)
        n = None if goal_here is None else self.steps(ego, goal_here)
        if not n:
            return 0, None
        ll = self.net.find_lanelet_by_id(ego)
        nxt = ll.adj_left if n > 0 else ll.adj_right
        return abs(n), None if nxt is None else int(nxt)


def waypoints(cr: CommonRoadProblem, goal_d: float, now: float = 0.0, goal_s: float | None = None,
              goal_t: float | None = None, lanes: LaneMap | None = None) -> list[Candidate]:
    """The final states of a lane change one lane toward the goal's lane, cheapest first.

    The target lane is the lane next to the ego's toward the goal's lane (:class:`LaneMap`: the
    lanelet at ``(goal_s, goal_d)`` followed back to the ego's position); none when the ego is
    already in that lane.  For every horizon of :data:`HORIZONS_S`, the final states are at the
    target lane's centre there, parallel to the road, and

    * at the ego's speed and at the speed that reaches ``goal_s`` at ``goal_t`` (when given),
      reached at constant acceleration;
    * into a gap: behind and ahead of each of the target lane's vehicles within
      :data:`NEIGHBOUR_RANGE_M`, at its predicted speed then and RSS's distance from it (behind:
      the ego stops behind it braking at ``STOP_DECEL_FRACTION a_max``; ahead: :func:`follower_gap`
      at equal speeds), plus :data:`GAP_MARGIN_M`;

    each within the type's speed range and with its free (minimum-energy) plan inside the friction
    circle; the final speeds nearest the goal's (the speed that reaches ``goal_s`` at ``goal_t``,
    else the ego's) first, then by the unconstrained cost ``cost0``.

    Parameters
    ----------
    cr : CommonRoadProblem
        The live problem (``x0`` now, ``obstacles`` the predicted vehicles over time from now).
    goal_d : float
        A lateral offset of the goal region [m].
    now : float
        The time now [s] (``goal_t`` is on the same clock).
    goal_s, goal_t : float, optional
        A position of the goal region along the road [m] and a time of its window [s].
    lanes : LaneMap, optional
        The scene's lanes (built from ``cr`` when not given).

    Returns
    -------
    list of Candidate
        The final states (``steps``/``tf`` from now, ``cost0`` their unconstrained cost).
    """
    from iamp.simulation.rss import DEFAULT, rss_distance

    s0, v0, d0, vd0 = cr.x0
    lanes = LaneMap(cr) if lanes is None else lanes
    _, nxt = lanes.toward(s0, d0, s0 if goal_s is None else goal_s, goal_d)
    if nxt is None:
        return []
    d_now = lanes.centre(nxt, s0)
    if d_now is None:
        return []
    neighbours = [ob for ob in cr.obstacles if not ob.road_edge and ob.d_lo[0] < d_now < ob.d_hi[0]
                  and abs(0.5 * (ob.s_lo[0] + ob.s_hi[0]) - s0) < NEIGHBOUR_RANGE_M]
    speeds = [v0]
    want = v0
    if goal_s is not None and goal_t is not None and goal_t > now + 1e-6:
        want = (goal_s - s0) / (goal_t - now)
        speeds.append(want)
    lo, hi = cr.speed_range
    half_l = 0.5 * cr.ego_length
    out = []
    for T in HORIZONS_S:
        steps = int(round(T / cr.dt))
        tf = steps * cr.dt
        finals = [(s0 + 0.5 * (v0 + v) * tf, v) for v in (min(max(v, lo), hi) for v in speeds)]
        for ob in neighbours:
            i = int(np.argmin(np.abs(ob.t - tf)))
            v_o = min(max(_speed(ob, float(ob.t[i])), lo), hi)
            behind = float(rss_distance(v_o, v_o, 0.0, 0.0, STOP_DECEL_FRACTION * cr.a_max, DEFAULT.brake_max))
            ahead = follower_gap(v_o, v_o)
            finals.append((float(ob.s_lo[i]) - half_l - behind - GAP_MARGIN_M, v_o))
            finals.append((float(ob.s_hi[i]) + half_l + ahead + GAP_MARGIN_M, v_o))
        for s_f, v in finals:
            d_f = lanes.centre(nxt, s_f)
            if d_f is None:
                continue
            U = FreeTrajectory(tf, cr.x0, (s_f, v, d_f, 0.0)).inputs([0.0, tf])
            if float(np.max(np.hypot(U[:, 0], U[:, 1]))) > cr.a_max:
                continue  # the free plan leaves the friction circle: out of reach in a lane change
            cost = unconstrained_cost(tf, s0, v0, s_f, v) + unconstrained_cost(tf, d0, vd0, d_f, 0.0)
            out.append(Candidate(steps, tf, round(s_f, 6), round(v, 6), d_f, cost))
    out.sort(key=lambda c: (round(abs(c.vs - want), 1), c.cost0, c.tf, c.s))
    return list(dict.fromkeys(out))


def _speed(ob: Obstacle, t: float) -> float:
    """The slope of an obstacle's predicted cubic at ``t`` [m/s]."""
    return float(sum(j * c * t ** (j - 1) for j, c in enumerate(ob.cubic) if j > 0))


def follower_gap(v_rear: float, v_ego: float) -> float:
    """The gap [m] a vehicle behind the ego in its new lane needs: the ego keeps its speed, the
    rear car keeps its own for RSS's response time and then brakes at RSS's ``brake_min`` (a
    comfortable braking, MOBIL's safety criterion) down to the ego's speed, with
    :data:`GAP_MARGIN_M` to spare and at least :data:`MIN_TIME_GAP_S` of its speed.

    Parameters
    ----------
    v_rear, v_ego : float
        Speeds of the rear car and the ego [m/s].

    Returns
    -------
    float
        The gap, bumper to bumper [m].
    """
    from iamp.simulation.rss import DEFAULT

    closing = max(v_rear - v_ego, 0.0)
    brake = closing * DEFAULT.response_time_s + closing**2 / (2.0 * DEFAULT.brake_min)
    return max(brake, MIN_TIME_GAP_S * max(v_rear, 0.0)) + GAP_MARGIN_M


def rss_clear_at(cr: CommonRoadProblem, s: float, v: float, d: float, T: float, behind: bool = True) -> bool:
    """Does RSS hold for the ego at ``(s, v, d)`` at time ``T``, in the lane it is in then?

    Every predicted vehicle whose box at ``T`` (the nearest time step) overlaps the ego's body
    across the road grown by RSS's lateral margin ``μ`` counts: one ahead must be far enough
    that the ego, braking at :data:`STOP_DECEL_FRACTION` ``a_max`` without response time, stops
    behind it whatever it does within RSS's ``brake_max``
    (:func:`iamp.simulation.rss.rss_distance`); one behind must be at least :func:`follower_gap`
    behind.  Vehicle speeds are
    the slopes of their predicted cubics at ``T``.

    Parameters
    ----------
    cr : CommonRoadProblem
        The live problem (``obstacles`` over time from now).
    s, v, d : float
        The ego's position along the road [m], speed [m/s] and lateral offset [m] at ``T``.
    T : float
        The time from now [s].
    behind : bool
        Test the vehicles behind too (False: only those ahead).

    Returns
    -------
    bool
        True when every such vehicle is far enough.
    """
    from iamp.simulation.rss import DEFAULT, rss_distance

    half_w = 0.5 * cr.ego_width + DEFAULT.lat_margin_m
    half_l = 0.5 * cr.ego_length
    for ob in cr.obstacles:
        if ob.road_edge:
            continue
        i = int(np.argmin(np.abs(ob.t - T)))
        if ob.d_lo[i] >= d + half_w or ob.d_hi[i] <= d - half_w:
            continue
        v_o = _speed(ob, float(ob.t[i]))
        if 0.5 * (float(ob.s_lo[i]) + float(ob.s_hi[i])) > s:
            gap = float(ob.s_lo[i]) - (s + half_l)
            need = float(rss_distance(v, v_o, 0.0, 0.0, STOP_DECEL_FRACTION * cr.a_max, DEFAULT.brake_max))
        elif behind:
            gap = (s - half_l) - float(ob.s_hi[i])
            need = follower_gap(v_o, v)
        else:
            continue
        if gap < need:
            return False
    return True


def lane_change(cr: CommonRoadProblem, planner: str, goal_d: float, now: float = 0.0,
                goal_s: float | None = None, goal_t: float | None = None,
                lanes: LaneMap | None = None) -> RoadPlan | None:
    """A safe lane change one lane toward the goal's lane (module doc), or None.

    Parameters
    ----------
    cr : CommonRoadProblem
        The live problem.
    planner : str
        The road planner (a key of :data:`iamp.commonroad.planning.PLANNERS`).
    goal_d, now, goal_s, goal_t : float
        As for :func:`waypoints`.
    lanes : LaneMap, optional
        The scene's lanes (built from ``cr`` when not given).

    Returns
    -------
    RoadPlan or None
        The road planner's first safe plan within ``a_max`` (at most :data:`MAX_WAYPOINTS`
        final states tried) to a final state of :func:`waypoints` that is RSS-clear
        (:func:`rss_clear_at`: a final state is fixed, so this is tested before planning); None
        when there is none.
    """
    cands = [c for c in waypoints(cr, goal_d, now, goal_s, goal_t, lanes) if rss_clear_at(cr, c.s, c.vs, c.d, c.tf)]
    if not cands:
        return None
    cands = cands[:MAX_WAYPOINTS]
    # a lane change is one plan to the next lane, not a two-stage plan around a vehicle (via=False: a
    # waypoint plan taken as a lane change at 6.5 s made 23_1's ego end against the car in its goal)
    rp = plan(dataclasses.replace(cr, candidates=cands), planner, max_candidates=MAX_WAYPOINTS, via=False)
    if rp.safe and rp.candidate in cands and rp.trajectory is not None and rp.peak_accel_mps2 <= cr.a_max \
            and stops_behind_along(cr, rp.trajectory, rp.candidate.tf):
        return rp
    return None


def stops_behind_along(cr: CommonRoadProblem, trajectory: Any, T: float) -> bool:
    """Does the ego, along a plan, keep RSS's stopping distance to every vehicle ahead in its path
    (:func:`rss_clear_at` with ``behind=False``) every :data:`CHECK_EVERY_S` up to ``T``?  A lane
    change toward a car that brakes harder than predicted must be given up before it closes in.

    Parameters
    ----------
    cr : CommonRoadProblem
        The live problem.
    trajectory : Trajectory
        The plan (``states(t)`` rows ``(s, v_s, d, v_d)`` from now).
    T : float
        Its horizon [s].

    Returns
    -------
    bool
        True when it does at every tested time.
    """
    for tau in np.arange(CHECK_EVERY_S, T + 1e-9, CHECK_EVERY_S):
        s, v, d, _ = (float(x) for x in trajectory.states(np.array([tau]))[0])
        if not rss_clear_at(cr, s, v, d, float(tau), behind=False):
            return False
    return True


def still_holds(cr: CommonRoadProblem, trajectory: Any, T: float) -> bool:
    """Is a lane change under way still acceptable under the newest predictions?  Its remainder
    (``trajectory`` from now, horizon ``T``) keeps the body off every predicted vehicle
    (:func:`iamp.commonroad.planning.intrusions`, road edges aside), keeps RSS's stopping distance
    to the vehicles ahead along the way (:func:`stops_behind_along`) and ends RSS-clear
    (:func:`rss_clear_at`).

    Parameters
    ----------
    cr : CommonRoadProblem
        The live problem (predictions from now).
    trajectory : Trajectory
        The remainder of the lane change (``states(t)`` from now).
    T : float
        The time it has left [s].

    Returns
    -------
    bool
        True when the loop may finish it without replanning.
    """
    if any(not h.obstacle.road_edge for h in intrusions(cr, trajectory, T)):
        return False
    s, v, d, _ = (float(x) for x in trajectory.states(np.array([T]))[0])
    return stops_behind_along(cr, trajectory, T) and rss_clear_at(cr, s, v, d, T)
