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
* no vehicle of the lane it enters is beside the ego when it starts (:func:`beside`), and RSS's
  stopping distance to the vehicles ahead holds every :data:`CHECK_EVERY_S` along it, where the
  ego is and in the lane it enters (:func:`stops_behind_along`), and
* its final state is one from which RSS holds in the new lane (:func:`rss_clear_at`): braking
  at ``STOP_DECEL_FRACTION a_max`` stops the ego behind the vehicle ahead whatever that one does
  within RSS's ``brake_max``, and the vehicle behind has room to slow to the ego's speed with a
  comfortable braking after its response time (:func:`follower_gap`, MOBIL's safety criterion;
  RSS's full safe distance behind, 35 m at 17 m/s, is longer than most gaps of dense US-101
  traffic, so a cut-in accepted here can leave RSS's distance to the new follower unmet for a
  while, which the loop's judge measures).

A goal two or more lanes over is first tried as **lane changes planned together**
(:func:`sequence`): the final state in a gap of the goal's lane is chosen first, then one lane
change per lane toward it along the minimum-energy motion along the road, each ending RSS-clear in
the lane it enters and each planned and accepted as a single lane change is (:class:`Stages`; the
predictions advanced to each lane change's start by :func:`advanced`).  One lane at a time can
end level with a column of cars in the goal's lane, from where its gap is out of reach.

The loop (:func:`iamp.commonroad.interactive.simulate_with_log`) uses it twice:

* **early**: a goal two or more lanes over (:class:`LaneMap`) whose cheapest final state is at
  least :data:`EARLY_MIN_S` ahead is approached one lane at a time (with the loop's
  ``sequences``: by a :func:`sequence` first; off by default, see
  :func:`~iamp.commonroad.interactive.simulate_with_log`) before its plan is tried
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

    def path(self, s: float, d: float, goal_s: float, goal_d: float) -> list[int]:
        """The lanelets side by side at ``s`` from the one next to the ego's (at ``(s, d)``) to the
        goal's lane, in order (empty when the ego is in the goal's lane or the lanes are not found)."""
        n, cur = self.toward(s, d, goal_s, goal_d)
        ego = self.at(s, d)
        if cur is None or ego is None:
            return []
        attr = "adj_left" if self.net.find_lanelet_by_id(ego).adj_left == cur else "adj_right"
        out: list[int] = []
        while cur is not None and len(out) < n:
            out.append(cur)
            nb = getattr(self.net.find_lanelet_by_id(cur), attr)
            cur = None if nb is None else int(nb)
        return out if len(out) == n else []


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
    s0, v0, d0, vd0 = cr.x0
    lanes = LaneMap(cr) if lanes is None else lanes
    _, nxt = lanes.toward(s0, d0, s0 if goal_s is None else goal_s, goal_d)
    if nxt is None:
        return []
    neighbours = lane_vehicles(cr, lanes, nxt, NEIGHBOUR_RANGE_M)
    if neighbours is None:
        return []
    speeds = [v0]
    want = v0
    if goal_s is not None and goal_t is not None and goal_t > now + 1e-6:
        want = (goal_s - s0) / (goal_t - now)
        speeds.append(want)
    lo, hi = cr.speed_range
    out = []
    for T in HORIZONS_S:
        steps = int(round(T / cr.dt))
        tf = steps * cr.dt
        finals = [(s0 + 0.5 * (v0 + v) * tf, v) for v in (min(max(v, lo), hi) for v in speeds)]
        finals += gap_states(cr, neighbours, tf)
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


def lane_vehicles(cr: CommonRoadProblem, lanes: LaneMap, lid: int, reach: float) -> list[Obstacle] | None:
    """The predicted vehicles in lanelet ``lid``'s lane now (their box now spans the lane's centre
    at the ego's position) within ``reach`` along the road of the ego (None: the lane does not
    reach the ego's position)."""
    s0 = cr.x0[0]
    d_now = lanes.centre(lid, s0)
    if d_now is None:
        return None
    return [ob for ob in cr.obstacles if not ob.road_edge and ob.d_lo[0] < d_now < ob.d_hi[0]
            and abs(0.5 * (ob.s_lo[0] + ob.s_hi[0]) - s0) < reach]


def gap_states(cr: CommonRoadProblem, vehicles: list[Obstacle], tf: float) -> list[tuple[float, float]]:
    """The positions along the road and speeds of the final states in the gaps next to
    ``vehicles`` at ``tf`` (:func:`waypoints`): behind each at RSS's stopping distance and ahead of
    each at :func:`follower_gap`, at its predicted speed then (clipped to the type's speed range),
    plus :data:`GAP_MARGIN_M`."""
    from iamp.simulation.rss import DEFAULT, rss_distance

    lo, hi = cr.speed_range
    half_l = 0.5 * cr.ego_length
    out = []
    for ob in vehicles:
        i = int(np.argmin(np.abs(ob.t - tf)))
        v_o = min(max(_speed(ob, float(ob.t[i])), lo), hi)
        behind = float(rss_distance(v_o, v_o, 0.0, 0.0, STOP_DECEL_FRACTION * cr.a_max, DEFAULT.brake_max))
        ahead = follower_gap(v_o, v_o)
        out.append((float(ob.s_lo[i]) - half_l - behind - GAP_MARGIN_M, v_o))
        out.append((float(ob.s_hi[i]) + half_l + ahead + GAP_MARGIN_M, v_o))
    return out


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
    if rp.safe and rp.candidate in cands and rp.within_limits(cr) \
            and stops_behind_along(cr, rp.trajectory, rp.candidate.tf):
        return rp
    return None


def beside(cr: CommonRoadProblem, s: float, d: float, T: float) -> bool:
    """Is a predicted vehicle beside the ego's body at ``(s, d)`` at time ``T``: its box (the
    nearest time step) overlapping the body along the road and across it grown by RSS's lateral
    margin ``μ``?

    Parameters
    ----------
    cr : CommonRoadProblem
        The live problem (``obstacles`` over time from now).
    s, d : float
        The body's centre in the road frame [m].
    T : float
        The time from now [s].

    Returns
    -------
    bool
        True when some vehicle is.
    """
    from iamp.simulation.rss import DEFAULT

    half_w = 0.5 * cr.ego_width + DEFAULT.lat_margin_m
    half_l = 0.5 * cr.ego_length
    for ob in cr.obstacles:
        if ob.road_edge:
            continue
        i = int(np.argmin(np.abs(ob.t - T)))
        if (ob.d_lo[i] < d + half_w and ob.d_hi[i] > d - half_w
                and ob.s_lo[i] < s + half_l and ob.s_hi[i] > s - half_l):
            return True
    return False


def stops_behind_along(cr: CommonRoadProblem, trajectory: Any, T: float, ends: Any = ()) -> bool:
    """Does the ego, along a plan, keep RSS's stopping distance to every vehicle ahead in its path
    (:func:`rss_clear_at` with ``behind=False``) every :data:`CHECK_EVERY_S` up to ``T``, both
    where it is then and in the lane it is entering (the body at the lateral offset of the next
    of ``ends`` and ``T``), with no vehicle of that lane beside it now (:func:`beside`)?  A lane
    change toward a car that brakes harder than predicted must be given up before it closes in,
    and one may not start beside a car of the lane it enters, counting on that car to pull ahead
    in time (USA_US101-23_1, seed 2, lane-change sequences: at 9.3 s the ego moved toward lane 4
    with vehicle 96 there 1.8 m ahead centre to centre, faster; 96 braked briefly and the ego's
    front corner touched its rear at 9.8 s, the ego at fault by RSS's lateral rule).

    Parameters
    ----------
    cr : CommonRoadProblem
        The live problem.
    trajectory : Trajectory
        The plan (``states(t)`` rows ``(s, v_s, d, v_d)`` from now).
    T : float
        Its horizon [s].
    ends : sequence of float
        Earlier times [s, from now] at which it reaches a lane's centre (the ends of the lane
        changes of a :class:`Stages` sequence before its last).

    Returns
    -------
    bool
        True when it does at every tested time.
    """
    marks = sorted({*(float(e) for e in ends if 0.0 < e < T), float(T)})
    lane_d = [float(x) for x in trajectory.states(np.array(marks))[:, 2]]
    s0, d0 = (float(x) for x in trajectory.states(np.array([0.0]))[0][[0, 2]])
    if abs(lane_d[0] - d0) > 0.5 * cr.ego_width and beside(cr, s0, lane_d[0], 0.0):
        return False
    for tau in np.arange(0.0, T + 1e-9, CHECK_EVERY_S):
        s, v, d, _ = (float(x) for x in trajectory.states(np.array([tau]))[0])
        entering = lane_d[min(int(np.searchsorted(marks, tau - 1e-9)), len(marks) - 1)]
        if tau > 0 and not rss_clear_at(cr, s, v, d, float(tau), behind=False):
            return False
        if not rss_clear_at(cr, s, v, entering, float(tau), behind=False):
            return False
    return True


def still_holds(cr: CommonRoadProblem, trajectory: Any, T: float, checkpoints: Any = ()) -> bool:
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
    checkpoints : sequence of float
        Earlier times [s, from now] at which it must also be RSS-clear (the ends of the lane
        changes still ahead in a :class:`Stages` sequence).

    Returns
    -------
    bool
        True when the loop may finish it without replanning.
    """
    if any(not h.obstacle.road_edge for h in intrusions(cr, trajectory, T)):
        return False
    for tau in (*checkpoints, T):
        s, v, d, _ = (float(x) for x in trajectory.states(np.array([tau]))[0])
        if not rss_clear_at(cr, s, v, d, float(tau)):
            return False
    return stops_behind_along(cr, trajectory, T, checkpoints)


#: Lane changes one :func:`sequence` plans at most (the goal's lane at most this many lanes over).
MAX_STAGES = 3
#: Road-planner calls one :func:`sequence` search may make (a count: the same answer on any machine).
SEQUENCE_PLANS = 12
#: Vehicles of the goal's lane this far along the road from the ego lend their gaps to a sequence [m].
GOAL_LANE_RANGE_M = 60.0


def advanced(cr: CommonRoadProblem, x: tuple[float, float, float, float], T: float) -> CommonRoadProblem:
    """The live problem seen ``T`` later with the ego at ``x``: every predicted vehicle's samples
    from the step nearest ``T`` on, timed from then, with its cubic re-expanded about ``T`` (road
    edges do not move); no final states.

    Parameters
    ----------
    cr : CommonRoadProblem
        The live problem (predictions from now).
    x : tuple of float
        The ego's state ``(s, v_s, d, v_d)`` at ``T``.
    T : float
        The time from now [s].

    Returns
    -------
    CommonRoadProblem
        The problem from ``T`` on.
    """
    shift = np.polynomial.Polynomial([T, 1.0])
    obs = []
    for ob in cr.obstacles:
        i = int(np.argmin(np.abs(ob.t - T)))
        coef = np.polynomial.Polynomial(ob.cubic)(shift).coef
        cubic = tuple(float(c) for c in np.pad(coef, (0, max(0, len(ob.cubic) - len(coef))))[:len(ob.cubic)])
        obs.append(dataclasses.replace(ob, t=ob.t[i:] - ob.t[i], s_lo=ob.s_lo[i:], s_hi=ob.s_hi[i:],
                                       d_lo=ob.d_lo[i:], d_hi=ob.d_hi[i:], cubic=cubic))
    return dataclasses.replace(cr, x0=x, obstacles=obs, candidates=[])


class Stages:
    """Plans one after another: ``parts`` rows ``(start, trajectory, horizon)`` (start from now,
    each trajectory timed from its start), the same interface as a plan (``states(t)`` rows
    ``(s, v_s, d, v_d)``, ``inputs(t)``); the last part runs on past its horizon.

    Parameters
    ----------
    parts : list of tuple
        ``(start [s], trajectory, horizon [s])`` in time order, each starting where the one before ends.
    """

    def __init__(self, parts: list[tuple[float, Any, float]]) -> None:
        self.parts = parts
        self.starts = np.array([p[0] for p in parts])

    @property
    def horizon(self) -> float:
        """The end of the last part [s]."""
        return float(self.parts[-1][0] + self.parts[-1][2])

    @property
    def ends(self) -> list[float]:
        """The times the parts end [s]."""
        return [float(p[0] + p[2]) for p in self.parts]

    def _eval(self, t: Any, what: str, width: int) -> np.ndarray:
        tt = np.atleast_1d(np.asarray(t, dtype=float))
        k = np.clip(np.searchsorted(self.starts, tt, side="right") - 1, 0, len(self.parts) - 1)
        out = np.empty((tt.size, width))
        for j in np.unique(k):
            m = k == j
            start, trajectory, _ = self.parts[int(j)]
            out[m] = getattr(trajectory, what)(tt[m] - start)
        return out

    def states(self, t: Any) -> np.ndarray:
        return self._eval(t, "states", 4)

    def inputs(self, t: Any) -> np.ndarray:
        return self._eval(t, "inputs", 2)


def sequence(cr: CommonRoadProblem, planner: str, goal_d: float, now: float = 0.0, goal_s: float | None = None,
             goal_t: float | None = None, lanes: LaneMap | None = None) -> Stages | None:
    r"""Lane changes into the goal's lane two or more lanes over, planned together: the gap in the
    goal's lane first, then the lane changes that reach it in time.

    The final state is in the goal's lane (:meth:`LaneMap.path`) after one horizon of
    :data:`HORIZONS_S` per lane (every combination whose end the predictions reach): at the ego's
    speed or the speed that reaches ``goal_s`` at ``goal_t`` (constant acceleration), or in a gap
    behind or ahead of one of the goal lane's vehicles within :data:`GOAL_LANE_RANGE_M`
    (:func:`gap_states`).  The motion along the road to it is the minimum-energy cubic over the
    whole sequence; each lane change ends where that cubic is at the end of its horizon, at the
    centre of its lane, parallel to the road.  A sequence is tried (cheapest first, as
    :func:`waypoints` orders) only when its speeds lie in the type's range, each lane change's
    free plan lies inside the friction circle and the ego is RSS-clear at every lane change's end
    in the lane it enters (:func:`rss_clear_at`, the vehicles ahead and behind).  Each lane change
    is then planned from the previous one's end with the road planner (predictions advanced by
    :func:`advanced`; one final state, no two-stage plan) and accepted as :func:`lane_change`
    accepts one: safe, within ``a_max``, RSS's stopping distance ahead kept along it
    (:func:`stops_behind_along`).  At most :data:`SEQUENCE_PLANS` planner calls in all.

    Parameters
    ----------
    cr : CommonRoadProblem
        The live problem (``x0`` now, ``obstacles`` the predicted vehicles over time from now).
    planner : str
        The road planner (a key of :data:`iamp.commonroad.planning.PLANNERS`).
    goal_d, now, goal_s, goal_t : float
        As for :func:`waypoints`.
    lanes : LaneMap, optional
        The scene's lanes (built from ``cr`` when not given).

    Returns
    -------
    Stages or None
        The accepted lane changes from now, or None when the goal's lane is fewer than two or more
        than :data:`MAX_STAGES` lanes over or no sequence is accepted.
    """
    import itertools

    s0, v0, d0, _ = cr.x0
    lanes = LaneMap(cr) if lanes is None else lanes
    path = lanes.path(s0, d0, s0 if goal_s is None else goal_s, goal_d)
    if not 2 <= len(path) <= MAX_STAGES:
        return None
    vehicles = lane_vehicles(cr, lanes, path[-1], GOAL_LANE_RANGE_M)
    if vehicles is None:
        return None
    reach = min((float(ob.t[-1]) for ob in cr.obstacles), default=math.inf)
    want = v0
    speeds = [v0]
    if goal_s is not None and goal_t is not None and goal_t > now + 1e-6:
        want = (goal_s - s0) / (goal_t - now)
        speeds.append(want)
    lo, hi = cr.speed_range
    trials = []
    for Ts in itertools.product(HORIZONS_S, repeat=len(path)):
        steps = np.cumsum([int(round(T / cr.dt)) for T in Ts])
        ends = steps * cr.dt
        tf = float(ends[-1])
        if tf > reach + 1e-9:
            continue
        finals = [(s0 + 0.5 * (v0 + v) * tf, v) for v in (min(max(v, lo), hi) for v in speeds)]
        for s_f, v_f in finals + gap_states(cr, vehicles, tf):
            X = FreeTrajectory(tf, cr.x0, (s_f, v_f, d0, 0.0)).states(ends)
            if float(X[:, 1].min()) < lo - 1e-9 or float(X[:, 1].max()) > hi + 1e-9:
                continue
            stages, prev, t_prev, cost = [], cr.x0, 0.0, 0.0
            for lid, k, te, (s, v) in zip(path, steps, ends, X[:, :2]):
                d = lanes.centre(lid, float(s))
                if d is None or not rss_clear_at(cr, float(s), float(v), d, float(te)):
                    break
                end = (float(s), float(v), d, 0.0)
                free = FreeTrajectory(float(te) - t_prev, prev, end)
                U = free.inputs(np.linspace(0.0, float(te) - t_prev, 13))
                if float(np.max(np.hypot(U[:, 0], U[:, 1]))) > cr.a_max:
                    break
                c0 = free.cost()
                stages.append((int(k), float(te), end, c0))
                prev, t_prev, cost = end, float(te), cost + c0
            else:
                trials.append((round(abs(v_f - want), 1), cost, tf, round(s_f, 6), stages))
    trials.sort(key=lambda tr: tr[:4])
    calls = 0
    for *_, stages in trials:
        parts: list[tuple[float, Any, float]] = []
        live, k_prev, t_prev = cr, 0, 0.0
        for k, te, (s, v, d, vd), c0 in stages:
            if calls >= SEQUENCE_PLANS:
                return None
            cand = Candidate(k - k_prev, te - t_prev, s, v, d, c0)
            rp = plan(dataclasses.replace(live, candidates=[cand]), planner, max_candidates=1, via=False)
            calls += 1
            if not (rp.safe and rp.candidate == cand and rp.trajectory is not None
                    and rp.within_limits(live) and stops_behind_along(live, rp.trajectory, cand.tf)):
                break
            parts.append((t_prev, rp.trajectory, cand.tf))
            live, k_prev, t_prev = advanced(cr, (s, v, d, vd), te), k, te
        else:
            return Stages(parts)
    return None
