r"""A CommonRoad scenario and its planning problem as an iamp problem in the road frame.

Every quantity is expressed in the :class:`~iamp.commonroad.frame.RoadFrame` of the ego's
lane (its lanelet with every predecessor and successor, centre line fitted by a polynomial):
``x`` of iamp is the arc length ``s``, ``y`` the lateral offset ``d`` (left positive).

* **Ego.** The initial state (position, speed, heading) maps to
  :math:`(s_0, \dot s_0, d_0, \dot d_0)` by the Frenet relations.  Its body is the vehicle
  type's (BMW 320i, CommonRoad type 2: 4.508 x 1.61 m) and its limits the type's
  (:math:`|a| \le 11.5` m/s² as a friction circle, speed range), stored as §14
  :class:`~iamp.core.physical.PhysicalLimits` with the road edges as ``y``.
* **Goal -> final state and t_f.** The goal's position (rectangle, or lanelet) gives
  :math:`(s_f, d_f)` (its centre; for a lanelet goal the lanelet's centre line at the
  unconstrained optimum's ``s``), :math:`\dot d_f = 0` (heading along the road, inside every
  US-101 orientation interval) and a candidate :math:`t_f` for every time step of the goal's
  interval with the speed :math:`\dot s_f` that minimises the unconstrained cost

  .. math::  J_0 = \sum_{axes} \frac{6\Delta^2}{T^3} - \frac{6\Delta\,\delta v}{T^2} + \frac{2\,\delta v^2}{T},
             \quad \Delta = p_f - p_0 - v_0 T,\ \delta v = v_f - v_0,

  (:math:`\delta v = 1.5\Delta/T`) clipped to the goal's speed interval less a margin.
  Candidates are sorted by :math:`J_0`; the planner takes the first it can plan safely
  (:mod:`iamp.commonroad.planning`), so the search reaches into the window only where the
  cheapest time fails.
* **Recorded vehicles -> cubics.** For each dynamic obstacle, its rectangle's four corners
  at each recorded time step of the horizon, in the road frame, give the box
  :math:`[s^-_k, s^+_k] \times [d^-_k, d^+_k]`; the centre :math:`(s^-_k + s^+_k)/2` is
  fitted by a least-squares cubic in ``t``, the half length is the largest half extent plus
  the fit's largest residual (so the box of the cubic covers every recorded corner), and the
  lateral box is the union of :math:`[d^-_k, d^+_k]` over the horizon.  A vehicle that
  changes lanes (its centre moves more than :data:`LANE_CHANGE_M`) is therefore handled
  **conservatively**: its box spans both lanes for the whole horizon (flagged
  ``lane_change``).  Its lane is the lane whose centre is nearest its mean offset.
* **Road edges** (:func:`_road_edges`): the corridor of lanelets reachable from the ego's lane
  by same-direction adjacency, at every arc length; its widest range is the §14 ``y`` limit
  (less the ego's lateral half extent), and where it is narrower (an on-ramp behind a gore
  area that joins the road only further on, a lane that ends) the missing part is a static box
  the planner avoids with the same corners as a vehicle (pieces of at most
  :data:`EDGE_CHUNK_M` over which the bound varies by at most :data:`EDGE_VARY_M`, so that the
  boxes follow a narrowing edge).  The lanelets' bounds are densified in the world
  (:func:`densify`) before they are projected: a straight bound between vertices far apart is
  curved in the road frame.  CommonRoad's road-boundary check uses the same lanelet geometry.
* **Margins** (:func:`ego_margins`): the ego's body turned by its heading relative to the
  road :math:`\varphi` has half extents
  :math:`L/2\cos\varphi + W/2\sin\varphi` along and :math:`L/2\sin\varphi + W/2\cos\varphi`
  across the road; these plus :data:`BUFFER_M` are the safety distances ``S_x, S_y``, so a
  point outside the safety region means the bodies do not overlap.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from iamp.commonroad import require
from iamp.commonroad.frame import RoadFrame
from iamp.commonroad.goal import Candidate, GoalRegion, read_goal
from iamp.core.errors import ScenarioError
from iamp.core.physical import PhysicalLimits
from iamp.core.problem import EgoBoundary, Problem, SurroundingVehicle

FloatArray = npt.NDArray[np.float64]

#: A vehicle whose centre's lateral offset spans more than this changes lanes [m].
LANE_CHANGE_M = 1.0
#: Extra clearance added to the body margins [m].
BUFFER_M = 0.15
#: Heading of the ego relative to the road assumed for the first plan's margins [rad].
HEADING_GUESS_RAD = 0.06
#: The road corridor is measured this far before the start and beyond the goal [m].
EDGE_REACH_M = 15.0
#: Spacing of the corridor's samples along the road [m].
EDGE_STEP_M = 0.5
#: Spacing of the lanelet bounds' points projected into the road frame [m] (:func:`densify`).
EDGE_DENSE_M = 0.5
#: Longest road-edge box along the road [m].
EDGE_CHUNK_M = 4.0
#: Largest change of the road's bound within one road-edge box [m].
EDGE_VARY_M = 0.01
#: Clearance added to the body's half extents at a road edge (vehicles: BUFFER_M) [m].
EDGE_BUFFER_M = 0.02
#: Two lanelets of the corridor whose bounds are this close at an ``s`` lie side by side there [m].
EDGE_JOIN_M = 0.1
#: A corridor narrower than the widest by more than this becomes a road-edge box [m]; a gap
#: wider than this between the lanelets of the corridor at one ``s`` is a hole in the road.
EDGE_TOL_M = 0.05
#: Largest change of a hole's bounds within one of its boxes [m] (each box covers the hole's
#: extreme bounds over its length, so it takes up to this much of the lanes beside it).
HOLE_VARY_M = 0.03
#: Half the width of the box along a bound two lanelets of the corridor share without being
#: adjacent in the map (CommonRoad's road boundary runs along it) [m].
BARRIER_HALF_M = 0.05
#: Vehicles considered relevant: lateral distance of their box to the ego's corridor [m].
CORRIDOR_M = 2.5


@dataclass(frozen=True)
class Obstacle:
    """One recorded vehicle in the road frame (times ``t`` [s], boxes per time step)."""

    obstacle_id: int
    t: FloatArray
    s_lo: FloatArray
    s_hi: FloatArray
    d_lo: FloatArray
    d_hi: FloatArray
    length: float
    width: float
    cubic: tuple[float, ...]
    half_length: float
    fit_residual_m: float
    lane: int
    lane_change: bool
    #: A road-edge box between two parts of the road (a gore area between lanes that part):
    #: passed on either side, not only the road's.
    hole: bool = False

    @property
    def road_edge(self) -> bool:
        """A static road-edge box of :func:`_road_edges` (negative id), not a vehicle."""
        return self.obstacle_id < 0

    @property
    def y(self) -> float:
        """Centre of the lateral box (union over the horizon)."""
        return 0.5 * (float(self.d_lo.min()) + float(self.d_hi.max()))

    @property
    def box_width(self) -> float:
        """Width of the lateral box (union over the horizon)."""
        return float(self.d_hi.max()) - float(self.d_lo.min())

    def vehicle(self, corner: str, safety_x: float, safety_y: float) -> SurroundingVehicle:
        """The iamp vehicle of this obstacle with the given corner and safety distances."""
        return SurroundingVehicle(x_poly=self.cubic, corner=corner, y=self.y, length=2 * self.half_length,
                                  width=self.box_width, safety_x=safety_x, safety_y=safety_y,
                                  name=f"obs{self.obstacle_id}")


@dataclass
class CommonRoadProblem:
    """A CommonRoad planning problem read into iamp's road frame (module docstring)."""

    path: Path
    scenario: Any
    planning_problem_set: Any
    planning_problem: Any
    frame: RoadFrame
    frame_fit_residual_m: float
    dt: float
    x0: tuple[float, float, float, float]
    goal: GoalRegion
    candidates: list[Candidate]
    obstacles: list[Obstacle]
    road_edges: list[Obstacle]
    lanes: list[float]
    road_y: tuple[float, float]
    ego_length: float
    ego_width: float
    a_max: float
    speed_range: tuple[float, float]
    notes: list[str] = field(default_factory=list)
    #: The road corridor ``(s, d^-(s), d^+(s))`` sampled every :data:`EDGE_STEP_M` (``nan`` off
    #: the lanelets), whose narrower parts are the ``road_edges`` boxes.
    corridor: tuple[FloatArray, FloatArray, FloatArray] | None = None
    #: CommonRoad's own road-boundary collision checker of the scenario (built on first use by
    #: :func:`iamp.commonroad.planning.off_road_steps`).
    road_checker: Any = field(default=None, repr=False, compare=False)

    @property
    def all_obstacles(self) -> list[Obstacle]:
        """The vehicles and the road-edge boxes (:func:`_road_edges`): everything the plan must avoid."""
        return [*self.obstacles, *self.road_edges]

    @property
    def name(self) -> str:
        return str(self.scenario.scenario_id)

    def limits(self, margin_y: float, final_d: float | None = None) -> PhysicalLimits:
        """§14 limits: the type's friction circle and speed range, the road edges less the ego's
        lateral half extent ``margin_y`` (widened to contain the start and the final offset)."""
        fd = self.x0[2] if final_d is None else final_d
        lo = min(self.road_y[0] + margin_y, self.x0[2], fd)
        hi = max(self.road_y[1] - margin_y, self.x0[2], fd)
        return PhysicalLimits(a_total=self.a_max, vx=self.speed_range, y=(lo, hi))

    def problem(self, candidate: Candidate, vehicles: list[SurroundingVehicle], margin_y: float) -> Problem:
        """The iamp problem of ``candidate`` with ``vehicles`` (at least one)."""
        s0, vs0, d0, vd0 = self.x0
        ego = EgoBoundary(tf=candidate.tf, x0=s0, y0=d0, vx0=vs0, vy0=vd0, xf=candidate.s, yf=candidate.d,
                          vxf=candidate.vs, vyf=candidate.vd, source=str(self.path), ego_length=self.ego_length,
                          ego_width=self.ego_width)
        return Problem(ego, tuple(vehicles), name=self.name, limits=self.limits(margin_y, candidate.d))


def fit_motion(t: FloatArray, s_lo: FloatArray, s_hi: FloatArray) -> tuple[tuple[float, ...], float, float]:
    """A recorded vehicle's motion along the road as iamp imposes it (module docstring): the
    least-squares cubic in ``t`` of its box's centre, the fit's largest residual, and the half
    length that covers every recorded box (the largest half extent plus that residual).

    Parameters
    ----------
    t : ndarray
        Times of the samples [s] (a cubic needs four; fewer give a lower degree).
    s_lo, s_hi : ndarray
        The box's rear and front along the road at those times [m].

    Returns
    -------
    (tuple of float, float, float)
        The coefficients in ascending powers of ``t``, the residual [m], the half length [m].
    """
    centre = 0.5 * (s_lo + s_hi)
    deg = int(min(3, len(t) - 1))
    coeffs = np.polynomial.polynomial.polyfit(t, centre, deg) if deg > 0 else np.array([centre[0]])
    resid = float(np.max(np.abs(np.polynomial.polynomial.polyval(t, coeffs) - centre)))
    return tuple(float(c) for c in coeffs), resid, float(np.max(0.5 * (s_hi - s_lo))) + resid


def ego_margins(length: float, width: float, heading: float, buffer: float = BUFFER_M) -> tuple[float, float]:
    r"""Safety distances ``(S_x, S_y)`` covering the ego's body turned by ``heading`` [rad]
    relative to the road: :math:`L/2\cos\varphi + W/2\sin\varphi` and
    :math:`L/2\sin\varphi + W/2\cos\varphi`, plus ``buffer``."""
    c, s = abs(math.cos(heading)), abs(math.sin(heading))
    return length / 2 * c + width / 2 * s + buffer, length / 2 * s + width / 2 * c + buffer


def unconstrained_cost(T: float, p0: float, v0: float, pf: float, vf: float) -> float:
    r"""½∫u² of the minimum-energy double integrator from ``(p0, v0)`` to ``(pf, vf)`` in ``T``."""
    D = pf - p0 - v0 * T
    dv = vf - v0
    return 6 * D * D / T**3 - 6 * D * dv / T**2 + 2 * dv * dv / T


def final_candidates(x0: tuple[float, float, float, float], goal: GoalRegion, dt: float,
                     elapsed_steps: int = 0) -> list[Candidate]:
    """Final states inside every element of a goal state, for every time step of the goal's
    windows still ahead, cheapest unconstrained cost first (:meth:`GoalRegion.final_states`);
    ``elapsed_steps`` steps have already passed (the closed loop replans from a later state)."""
    return goal.final_states(x0, dt, elapsed_steps)


def densify(polyline: FloatArray, spacing: float) -> FloatArray:
    """``polyline`` (``(n, 2)``) with points inserted on each segment so that consecutive points
    are at most ``spacing`` apart (every original vertex kept).

    Parameters
    ----------
    polyline : ndarray
        Vertices, shape ``(n, 2)``.
    spacing : float
        Largest distance between consecutive points [m] (> 0).

    Returns
    -------
    ndarray
        The densified polyline, shape ``(m, 2)``, ``m >= n``.
    """
    pts = np.asarray(polyline, dtype=float)
    if pts.shape[0] < 2:
        return pts
    out = [pts[:1]]
    for a, b in zip(pts[:-1], pts[1:]):
        n = max(1, int(np.ceil(float(np.linalg.norm(b - a)) / spacing)))
        f = np.arange(1, n + 1)[:, None] / n
        out.append(a + f * (b - a))
    return np.concatenate(out)


def _road_edges(frame: RoadFrame, network: Any, chain: list[Any], s_a: float, s_b: float,
                t: FloatArray, via: tuple[tuple[float, float], tuple[float, float]] = ((0.0, 0.0), (1.0, 0.0)),
                ) -> tuple[tuple[float, float], list[Obstacle], tuple[FloatArray, FloatArray, FloatArray]]:
    r"""The road corridor of the ego's lane: its widest lateral range as §14 ``y`` limits and the
    parts where it is narrower as static boxes to avoid (module docstring, "Road edges").

    At every arc length ``s`` (step :data:`EDGE_STEP_M`) the corridor grows from two seeds, the
    ego's lane (the lanelet of ``chain`` covering ``s``) and the lanelet under the straight line
    from the start ``via[0]`` to the goal ``via[1]`` (where the road splits, the goal's branch),
    each by every lanelet reachable from it by same-direction adjacency (``adj_left``/``adj_right``);
    :math:`[d^-(s), d^+(s)]` = the extreme bounds of those lanelets at ``s``.  A lanelet beside them
    that shares a bound (within :data:`EDGE_JOIN_M`) but is not adjacent in the map is not part of
    it, unless the two bounds are the same points: CommonRoad's solution checker draws its road
    boundary along such a bound (probed on DEU_A9-1_2, DEU_Muc-2_1 and the shared US-101 maps: a
    small body on it collides with the boundary at 7-20 of 20 points; on a bound between adjacent
    lanelets, or one given by the same vertices, at none); where two lanelets of the corridor
    share one (the goal's branch beside the ego's section), a box :data:`BARRIER_HALF_M` either
    side of it is a hole in the corridor (a line not to cross).
    A lanelet that touches the road only at its end (an on-ramp behind a gore area) is not
    part of it.  The limits are
    :math:`(\min_s d^-(s), \max_s d^+(s))`; every run of ``s`` where :math:`d^-(s)` is above
    its minimum (or :math:`d^+(s)` below its maximum) by more than :data:`EDGE_TOL_M` becomes a
    box :math:`[s_1, s_2] \times [\min_s d^- - 3, \max_{run} d^-]` (resp. above), which the planner
    avoids like a standing vehicle (obstacle ids -1, -2, ...).  The third value is the corridor
    itself, ``(s, d^-(s), d^+(s))`` at every sample (``nan`` where no lanelet covers ``s``).
    Where the mapped road ends before ``s_b`` (no lanelet of the corridor beyond it), the end is
    one more box, across the road from there on; where it begins after ``s_a`` (the ego starts
    near its beginning), its start likewise, across the road up to there.
    """
    cache: dict[int, tuple[FloatArray, FloatArray, FloatArray, FloatArray]] = {}

    def bounds(ll: Any) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        if ll.lanelet_id not in cache:
            # densified in the world first: a straight bound between two vertices is curved in the
            # road frame (the reference turns), so interpolating its projected vertices would
            # misplace it by up to centimetres where the vertices are far apart
            r = mapped(densify(np.asarray(ll.right_vertices, dtype=float), EDGE_DENSE_M))
            lf = mapped(densify(np.asarray(ll.left_vertices, dtype=float), EDGE_DENSE_M))
            ro, lo_ = np.argsort(r[:, 0]), np.argsort(lf[:, 0])
            cache[ll.lanelet_id] = (r[ro, 0], r[ro, 1], lf[lo_, 0], lf[lo_, 1])
        return cache[ll.lanelet_id]

    def mapped(points: FloatArray) -> FloatArray:
        """``points`` in the road frame, less those whose projection does not map back to them
        (to :data:`FRAME_ROUND_TRIP_M`): far beyond a frame fitted near the ego
        (:func:`road_frame`) its path is extrapolated and the projection of a point kilometres
        away is not unique (DEU_A9-1_2: a lanelet's end 2 km ahead at s = 50 km, d = 50 km)."""
        sd = frame.to_road(points)
        return np.asarray(sd[_maps_back(frame, points, sd)], dtype=float)

    def at(ll: Any, s: float) -> tuple[float, float] | None:
        rs, rd, ls, ld = bounds(ll)
        if rs.size < 2 or ls.size < 2:
            return None
        if not (rs[0] - 1e-6 <= s <= rs[-1] + 1e-6 and ls[0] - 1e-6 <= s <= ls[-1] + 1e-6):
            return None
        return float(np.interp(s, rs, rd)), float(np.interp(s, ls, ld))

    def adjacent(a: Any, b: Any) -> bool:
        """Does the map make ``a`` and ``b`` neighbours (same direction)?"""
        return bool((a.adj_left == b.lanelet_id and a.adj_left_same_direction)
                    or (a.adj_right == b.lanelet_id and a.adj_right_same_direction)
                    or (b.adj_left == a.lanelet_id and b.adj_left_same_direction)
                    or (b.adj_right == a.lanelet_id and b.adj_right_same_direction))

    def same_bound(a: Any, b: Any) -> bool:
        """Do ``a`` and ``b`` share a bound vertex for vertex (the same points)?  The checker's road
        has no line there; two bounds within EDGE_JOIN_M through other points leave slivers between
        the lanelets' polygons, which it draws as boundary where the map gives no adjacency."""
        return bool(np.array_equal(a.left_vertices, b.right_vertices) or np.array_equal(a.right_vertices,
                                                                                         b.left_vertices))

    grid = np.arange(s_a, s_b + EDGE_STEP_M, EDGE_STEP_M)
    lo = np.full(grid.size, np.nan)
    hi = np.full(grid.size, np.nan)
    gaps: list[list[tuple[float, float]]] = [[] for _ in grid]
    forward = []
    for ll in network.lanelets:
        c = mapped(np.asarray(ll.center_vertices, dtype=float))[:, 0]
        if c.size >= 2 and c[-1] > c[0]:
            forward.append(ll)

    def containing(s: float, d: float) -> Any:
        for ll in forward:
            b = at(ll, s)
            if b is not None and min(b) <= d <= max(b):
                return ll
        return None

    def seeds(s: float) -> tuple[Any, Any]:
        """The corridor's seeds at ``s``: the ego's own lane (else the line's lanelet) and the
        lanelet under the straight line from the start to the goal (where the road splits, the
        goal's branch is part of the corridor too); ``own`` None where neither covers ``s``."""
        d_line = float(np.interp(s, [via[0][0], via[1][0]], [via[0][1], via[1][1]]))
        line = containing(s, d_line)
        return next((ll for ll in chain if at(ll, s) is not None), None) or line, line

    def section(seed: Any, s: float) -> dict[int, Any]:
        """``seed`` and every lanelet at ``s`` reachable from it by same-direction adjacency: one
        section of CommonRoad's road (its solution checker draws a boundary along a bound shared
        by two lanelets the map does not make adjacent)."""
        group, todo = {seed.lanelet_id: seed}, [seed]
        while todo:
            cur = todo.pop()
            for nid, same in ((cur.adj_left, cur.adj_left_same_direction),
                              (cur.adj_right, cur.adj_right_same_direction)):
                if nid is not None and same and nid not in group:
                    nb = network.find_lanelet_by_id(nid)
                    if at(nb, s) is not None:
                        group[nid] = nb
                        todo.append(nb)
            for nb in network.lanelets:  # the same bound, vertex for vertex: no line on the road
                if nb.lanelet_id not in group and at(nb, s) is not None and same_bound(cur, nb):
                    group[nb.lanelet_id] = nb
                    todo.append(nb)
        return group

    for i, s in enumerate(grid):
        own, line = seeds(float(s))
        if own is None:
            continue
        group = section(own, float(s))
        if line is not None and line.lanelet_id not in group:
            group.update(section(line, float(s)))
        # two lanelets of the corridor sharing a bound without adjacency (the goal's branch beside
        # the ego's section, or two lanelets each adjacent to others): the checker's boundary runs
        # along it, a line the body may not cross
        here = {lid: b for lid, b in ((lid, at(ll, float(s))) for lid, ll in sorted(group.items())) if b is not None}
        barriers: list[float] = []
        for ia, (a_id, ba) in enumerate(here.items()):
            for b_id, bb in list(here.items())[ia + 1:]:
                if adjacent(group[a_id], group[b_id]) or same_bound(group[a_id], group[b_id]):
                    continue
                gap, mid = min((abs(x - y), 0.5 * (x + y)) for x in ba for y in bb)
                if gap < EDGE_JOIN_M:  # side by side here (a gore where they part: up to its tip)
                    barriers.append(mid)
        spans = sorted((min(b), max(b)) for b in here.values())
        lo[i], hi[i] = spans[0][0], max(b for _, b in spans)
        top = spans[0][1]
        for a, b in spans[1:]:  # a gap between the group's lanelets: outside CommonRoad's road too
            if a > top + EDGE_TOL_M:
                gaps[i].append((top, a))
            top = max(top, b)
        gaps[i] += [(d - BARRIER_HALF_M, d + BARRIER_HALF_M) for d in barriers]
        gaps[i].sort()
    ok = np.isfinite(lo)
    if not ok.any():
        return (-1e3, 1e3), [], (grid, lo, hi)
    y_lo, y_hi = float(np.min(lo[ok])), float(np.max(hi[ok]))
    boxes: list[Obstacle] = []
    n = t.size

    def add_box(s1: float, s2: float, d1: float, d2: float, hole: bool = False) -> None:
        """A static road-edge box ``[s1, s2] x [d1, d2]`` at every step (ids -1, -2, ...)."""
        half = 0.5 * (s2 - s1)
        boxes.append(Obstacle(-(len(boxes) + 1), t, np.full(n, s1), np.full(n, s2), np.full(n, d1), np.full(n, d2),
                              2 * half, d2 - d1, (0.5 * (s1 + s2), 0.0, 0.0, 0.0), half, 0.0, -1, False, hole))

    def on_road_end(on: float, off: float) -> float:
        """Where the mapped road begins or ends between a sample ``on`` it and one ``off`` it: the
        last point found on it, by bisection to 1e-6 m."""
        while abs(off - on) > 1e-6:
            mid = 0.5 * (on + off)
            if seeds(mid)[0] is not None:
                on = mid
            else:
                off = mid
        return on

    for side, narrow in (("lo", ok & (lo > y_lo + EDGE_TOL_M)), ("hi", ok & (hi < y_hi - EDGE_TOL_M))):
        idx = np.flatnonzero(narrow)
        if idx.size == 0:
            continue
        runs = []
        for run in np.split(idx, np.flatnonzero(np.diff(idx) > 1) + 1):
            # pieces of at most EDGE_CHUNK_M over which the bound varies by at most EDGE_VARY_M, so
            # the boxes follow a narrowing edge (the narrowest value of a long piece would shut
            # out a body that fits beside its wide end)
            bound = lo if side == "lo" else hi
            first = 0
            for j in range(1, run.size + 1):
                if (j == run.size or (j - first + 1) * EDGE_STEP_M > EDGE_CHUNK_M
                        or float(np.ptp(bound[run[first:j + 1]])) > EDGE_VARY_M):
                    runs.append(run[first:j])
                    first = j
        for run in runs:
            s1, s2 = float(grid[run[0]]) - EDGE_STEP_M, float(grid[run[-1]]) + EDGE_STEP_M
            if side == "lo":
                d1, d2 = y_lo - 3.0, float(np.max(lo[run]))
            else:
                d1, d2 = float(np.min(hi[run])), y_hi + 3.0
            add_box(s1, s2, d1, d2)
    first, last = (int(i) for i in np.flatnonzero(ok)[[0, -1]])
    if first > 0:
        # the mapped road begins within the corridor (the ego starts near its beginning): the
        # road's start is a box across it too, as its end (below)
        add_box(float(grid[0]) - EDGE_REACH_M, on_road_end(float(grid[first]), float(grid[first - 1])),
                y_lo - 3.0, y_hi + 3.0)
    if last < grid.size - 1:
        # the mapped road ends ahead (no lanelet of the corridor beyond): CommonRoad's road ends
        # there too, so the end is a box across the road from the last point on it
        add_box(on_road_end(float(grid[last]), float(grid[last + 1])), float(grid[-1]) + EDGE_REACH_M,
                y_lo - 3.0, y_hi + 3.0)
    for run_s, run_lo, run_hi in _hole_runs(grid, gaps):
        add_box(float(run_s[0]) - EDGE_STEP_M, float(run_s[-1]) + EDGE_STEP_M, float(np.min(run_lo)),
                float(np.max(run_hi)), hole=True)
    return (y_lo, y_hi), boxes, (grid, lo, hi)


def _hole_runs(grid: FloatArray, gaps: list[list[tuple[float, float]]]) -> list[tuple[FloatArray, FloatArray,
                                                                                        FloatArray]]:
    """The holes of the corridor (gaps between its lanelets at each sample of ``grid``) as pieces:
    a gap continues the piece of the last sample's gap it overlaps; a piece ends after
    :data:`EDGE_CHUNK_M` or where either bound has changed by more than :data:`HOLE_VARY_M`.
    Each piece is ``(s, lower bounds, upper bounds)`` at its samples."""
    done: list[tuple[list[float], list[float], list[float]]] = []
    open_: list[tuple[list[float], list[float], list[float]]] = []
    for i, here in enumerate(gaps):
        nxt: list[tuple[list[float], list[float], list[float]]] = []
        for a, b in here:
            run = next((r for r in open_ if r[1][-1] <= b and a <= r[2][-1] and r not in nxt), None)
            if run is not None and ((len(run[0]) + 1) * EDGE_STEP_M > EDGE_CHUNK_M
                                    or max(run[2] + [b]) - min(run[2] + [b]) > HOLE_VARY_M
                                    or max(run[1] + [a]) - min(run[1] + [a]) > HOLE_VARY_M):
                open_.remove(run)
                done.append(run)
                # the next piece starts where this one ended, so that together they cover the hole
                run = ([run[0][-1]], [run[1][-1]], [run[2][-1]])
            if run is None:
                run = ([], [], [])
            elif run in open_:
                open_.remove(run)
            run[0].append(float(grid[i]))
            run[1].append(a)
            run[2].append(b)
            nxt.append(run)
        done += open_
        open_ = nxt
    done += open_
    return [(np.array(r[0]), np.array(r[1]), np.array(r[2])) for r in done]


def _obstacle_boxes(frame: RoadFrame, obs: Any, dt: float, k_max: int, src: str) -> tuple[FloatArray, FloatArray]:
    """A dynamic obstacle's box in the road frame at each of its time steps ``0..k_max``: times
    ``(n,)`` and boxes ``(n, 4)`` = ``(s_lo, s_hi, d_lo, d_hi)``, the extremes of its body's
    corners (a recorded trajectory: its rectangle at each state) or of its occupancy's vertices,
    every edge densified to :data:`EDGE_DENSE_M` first (a set-based prediction, as the ``S``
    benchmark problems give: CommonRoad's checker tests the ego against each step's set, so the
    box covers the whole set).

    Raises
    ------
    iamp.ScenarioError
        A prediction of another kind, or an occupancy of a shape without vertices.
    """
    from commonroad.prediction.prediction import SetBasedPrediction, TrajectoryPrediction

    shape = obs.obstacle_shape
    pred = obs.prediction
    init = obs.initial_state
    rects: list[tuple[int, FloatArray]] = []
    if 0 <= init.time_step <= k_max:
        rects.append((int(init.time_step), _corners(np.asarray(init.position, dtype=float), float(shape.length),
                                                      float(shape.width), float(init.orientation))))
    if isinstance(pred, TrajectoryPrediction):
        rects += [(int(st.time_step), _corners(np.asarray(st.position, dtype=float), float(shape.length),
                                               float(shape.width), float(st.orientation)))
                  for st in pred.trajectory.state_list if 0 <= st.time_step <= k_max]
    elif isinstance(pred, SetBasedPrediction):
        for occ in pred.occupancy_set:
            k = int(occ.time_step)
            if not 0 <= k <= k_max:
                continue
            parts = occ.shape.shapes if hasattr(occ.shape, "shapes") else [occ.shape]
            if not all(hasattr(part, "vertices") for part in parts):
                raise ScenarioError(f"obstacle {obs.obstacle_id}: an occupancy at time step {k} is a "
                                    f"{type(occ.shape).__name__} without vertices", "prediction", src)
            rects.append((k, np.concatenate([densify(_closed(np.asarray(part.vertices, dtype=float)), EDGE_DENSE_M)
                                             for part in parts])))
    elif pred is not None:
        raise ScenarioError(f"obstacle {obs.obstacle_id}: a {type(pred).__name__} is not supported "
                            "(a trajectory or a set-based prediction is)", "prediction", src)
    if not rects:
        return np.zeros(0), np.zeros((0, 4))
    rects.sort(key=lambda r: r[0])
    sizes = [len(r[1]) for r in rects]
    sd = frame.to_road(np.concatenate([r[1] for r in rects]))  # one projection of every point
    cuts = np.cumsum(sizes)[:-1]
    B = np.array([[p[:, 0].min(), p[:, 0].max(), p[:, 1].min(), p[:, 1].max()] for p in np.split(sd, cuts)])
    return np.array([k * dt for k, _ in rects]), B


#: Vertices of the polygon circumscribing a circular body (its occupancy's box in the road frame).
CIRCLE_VERTICES = 24


def _shape_points(shape: Any, what: str, src: str) -> FloatArray:
    """The world points whose road-frame extremes bound ``shape`` (an occupancy's, already placed):
    a polygon's or rectangle's edges densified to :data:`EDGE_DENSE_M`, a circle's circumscribed
    polygon (:data:`CIRCLE_VERTICES`), a shape group's parts together.

    Raises
    ------
    iamp.ScenarioError
        A shape of another kind.
    """
    parts = shape.shapes if hasattr(shape, "shapes") else [shape]
    out = []
    for part in parts:
        if hasattr(part, "vertices"):
            out.append(densify(_closed(np.asarray(part.vertices, dtype=float)), EDGE_DENSE_M))
        elif hasattr(part, "radius") and hasattr(part, "center"):
            a = np.linspace(0.0, 2 * math.pi, CIRCLE_VERTICES + 1)
            r = float(part.radius) / math.cos(math.pi / CIRCLE_VERTICES)  # the polygon contains the circle
            ring = np.asarray(part.center, dtype=float) + r * np.column_stack([np.cos(a), np.sin(a)])
            out.append(densify(ring, EDGE_DENSE_M))
        else:
            raise ScenarioError(f"{what}: a {type(part).__name__} shape is not supported (a rectangle, polygon, "
                                "circle or a group of them is)", "obstacleShape", src)
    return np.concatenate(out)


def _occupancy_boxes(frame: RoadFrame, obs: Any, dt: float, k_max: int, src: str) -> tuple[FloatArray, FloatArray]:
    """A static obstacle's box, or that of a dynamic obstacle whose body is not a rectangle, in
    the road frame at each time step ``0..k_max`` it occupies (CommonRoad's own
    ``occupancy_at_time``): times ``(n,)`` and boxes ``(n, 4)`` = ``(s_lo, s_hi, d_lo, d_hi)``, the
    extremes of the occupancy's points (:func:`_shape_points`); a static obstacle's box is the
    same at every step."""
    what = f"obstacle {obs.obstacle_id}"
    steps: list[int] = []
    boxes: list[list[float]] = []
    static = not hasattr(obs, "prediction")
    for k in range(k_max + 1):
        if static and boxes:
            steps.append(k)
            boxes.append(boxes[0])
            continue
        occ = obs.occupancy_at_time(k)
        if occ is None:
            continue
        sd = frame.to_road(_shape_points(occ.shape, what, src))
        steps.append(k)
        boxes.append([float(sd[:, 0].min()), float(sd[:, 0].max()), float(sd[:, 1].min()), float(sd[:, 1].max())])
    if not boxes:
        return np.zeros(0), np.zeros((0, 4))
    return np.array(steps, dtype=float) * dt, np.array(boxes)


def _closed(vertices: FloatArray) -> FloatArray:
    """A polygon's vertices with the first repeated at the end (unless it already is)."""
    return vertices if np.array_equal(vertices[0], vertices[-1]) else np.vstack([vertices, vertices[:1]])


def _corners(center: FloatArray, length: float, width: float, orientation: float) -> FloatArray:
    c, s = math.cos(orientation), math.sin(orientation)
    half = np.array([[length / 2, width / 2], [length / 2, -width / 2], [-length / 2, width / 2],
                     [-length / 2, -width / 2]])
    return np.asarray(center + half @ np.array([[c, s], [-s, c]]), dtype=float)


#: The road frame's path is fitted to the whole chain of the ego's lanelets where it stays within
#: this of the chain's centre line (every shared US-101 scene: at most 0.44 m, the NGSIM centre
#: lines' own wobble) [m]; else it is fitted again near the ego (:func:`road_frame`).
FRAME_TOL_M = 1.0
#: The centre line fitted near the ego: from this far behind it ... [m]
FRAME_BEHIND_M = 50.0
#: ... to this far beyond what it can reach by the goal's last step at the vehicle's top speed [m].
FRAME_AHEAD_M = 50.0
#: Spacing of the centre line's points fitted near the ego [m].
FRAME_DENSE_M = 1.0
#: A point whose road-frame coordinates map back to within this of it is in the frame's reach [m].
FRAME_ROUND_TRIP_M = 0.01
#: Degree of the road frame's path (:meth:`~iamp.commonroad.frame.RoadFrame.fit`).
FRAME_DEGREE = 5


def road_frame(centre: FloatArray, start: FloatArray, reach: float) -> tuple[RoadFrame, float, str | None]:
    """The road frame of the ego's lane: its path fitted to the centre line ``centre`` of the
    chain of lanelets (:func:`_chain`), and where that fit leaves the centre line by more than
    :data:`FRAME_TOL_M` (a chain kilometres long, or a ramp's curve followed by a straight road:
    DEU_A9-1_2 left 44 m), fitted again to the stretch that matters -- from
    :data:`FRAME_BEHIND_M` behind the ego's ``start`` to ``reach`` (how far the ego can drive by the
    goal's last step) plus :data:`FRAME_AHEAD_M` ahead, the centre line densified to
    :data:`FRAME_DENSE_M` -- when that fits it better.

    Parameters
    ----------
    centre : ndarray, shape (n, 2)
        The chain's centre line (world, in driving order).
    start : ndarray, shape (2,)
        The ego's initial position (world).
    reach : float
        The farthest the ego can drive within the planning problem [m].

    Returns
    -------
    frame : RoadFrame
    residual : float
        The largest distance of the fitted centre-line points from the frame's path [m].
    note : str or None
        What was fitted, when it is not the whole chain or leaves more than :data:`FRAME_TOL_M`.
    """
    frame = RoadFrame.fit(centre, degree=FRAME_DEGREE)
    res = float(np.max(np.abs(frame.to_road(centre)[:, 1])))
    if res <= FRAME_TOL_M:
        return frame, res, None
    dense = densify(np.asarray(centre, dtype=float), FRAME_DENSE_M)
    arc = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(dense, axis=0), axis=1))]
    a0 = float(arc[int(np.argmin(np.linalg.norm(dense - np.asarray(start, dtype=float), axis=1)))])
    ahead = max(reach, 0.0) + FRAME_AHEAD_M
    window = (arc >= a0 - FRAME_BEHIND_M) & (arc <= a0 + ahead)
    near = dense[window]
    if len(near) > FRAME_DEGREE:
        whole_near = float(np.max(np.abs(frame.to_road(near)[:, 1])))
        local = RoadFrame.fit(near, degree=FRAME_DEGREE)
        local_res = float(np.max(np.abs(local.to_road(near)[:, 1])))
        if local_res < whole_near:
            note = (f"road frame fitted to the ego's lane from {FRAME_BEHIND_M:.0f} m behind it to "
                    f"{ahead:.0f} m ahead (the fit to its whole chain of "
                    f"lanelets left {res:.2f} m); it leaves the lane's centre line by up to {local_res:.2f} m")
            if local_res > FRAME_TOL_M:
                note += f", more than {FRAME_TOL_M:g} m: the lanes are not straight in it, the plan approximate"
            return local, local_res, note
    return frame, res, (f"the road frame leaves the lane's centre line by up to {res:.2f} m, more than "
                        f"{FRAME_TOL_M:g} m: the lanes are not straight in it, the plan approximate")


def _maps_back(frame: RoadFrame, points: FloatArray, sd: FloatArray) -> npt.NDArray[np.bool_]:
    """Which ``points`` (world) map back to themselves, to :data:`FRAME_ROUND_TRIP_M`, from their
    road-frame coordinates ``sd`` (``frame.to_road(points)``): in the frame's reach (far beyond a
    frame fitted near the ego the projection is not unique)."""
    back = frame.to_world(sd[:, 0], sd[:, 1])
    return np.asarray(np.linalg.norm(back - points, axis=1) <= FRAME_ROUND_TRIP_M, dtype=bool)


def _lane_end(frame: RoadFrame, chain: list[Any]) -> float:
    """Where the chain of lanelets ``chain`` (:func:`_chain`) ends along the road: the nearer of
    its last lanelet's bounds' ends in ``frame`` [m]; ``inf`` where an end lies beyond the frame's
    path (projected past the end of the centre line it was fitted to, where the path is
    extrapolated, or not mapping back to itself, :data:`FRAME_ROUND_TRIP_M`: a frame fitted near the
    ego, the chain going on kilometres beyond it)."""
    last = chain[-1]
    ends = []
    for v in (last.right_vertices, last.left_vertices):
        P = np.asarray(v, dtype=float)
        sd = frame.to_road(P)
        k = int(np.argmax(sd[:, 0]))
        if (float(frame.u_of_s(sd[k, 0])) > frame.u_range[1] + 1.0
                or not _maps_back(frame, P[k:k + 1], sd[k:k + 1])[0]):
            return math.inf
        ends.append(float(sd[k, 0]))
    return min(ends)


def _chain(network: Any, start_id: int) -> list[Any]:
    """The lanelet ``start_id`` with its predecessors before and successors after (first of each)."""
    lanelet = network.find_lanelet_by_id(start_id)
    chain = [lanelet]
    seen = {start_id}
    cur = lanelet
    while cur.predecessor and cur.predecessor[0] not in seen:
        cur = network.find_lanelet_by_id(cur.predecessor[0])
        seen.add(cur.lanelet_id)
        chain.insert(0, cur)
    cur = lanelet
    while cur.successor and cur.successor[0] not in seen:
        cur = network.find_lanelet_by_id(cur.successor[0])
        seen.add(cur.lanelet_id)
        chain.append(cur)
    return chain


def load(path: str | Path, vehicle_type: int = 2) -> CommonRoadProblem:
    """Read ``path`` (a CommonRoad XML scenario with one planning problem) into the road frame.

    Raises
    ------
    iamp.ScenarioError
        A folder or an unreadable file, an element that cannot be read or whose value no plan can
        use (:mod:`iamp.commonroad.inputs`, the element named), no planning problem, or an ego
        outside every lanelet.
    """
    require()
    from commonroad.common.solution import VehicleType
    from commonroad_dc.feasibility.vehicle_dynamics import VehicleDynamics

    from iamp.commonroad.inputs import read_scenario

    src = str(path)
    p = Path(path)
    params = VehicleDynamics.PM(VehicleType(vehicle_type)).parameters
    # the file, its elements and values (each refused naming it: iamp.commonroad.inputs); an initial
    # speed must lie in the speed range of the vehicle type that is planned
    scenario, pps = read_scenario(p, (float(params.longitudinal.v_min), float(params.longitudinal.v_max)),
                                  f"CommonRoad vehicle type {vehicle_type}")
    problems = list(pps.planning_problem_dict.values())
    if not problems:
        raise ScenarioError("has no planning problem", "planningProblem", src)
    pp = problems[0]
    notes: list[str] = []
    if len(problems) > 1:
        notes.append(f"{len(problems)} planning problems; the first ({pp.planning_problem_id}) is planned")
    dt = float(scenario.dt)
    network = scenario.lanelet_network

    init = pp.initial_state
    pos0 = np.asarray(init.position, dtype=float)
    hits = network.find_lanelet_by_position([pos0])[0]
    if not hits:
        raise ScenarioError("the ego's initial position lies on no lanelet", "planningProblem.initialState", src)
    chain = _chain(network, hits[0])
    centre = np.concatenate([ll.center_vertices for ll in chain])
    keep = np.r_[True, np.linalg.norm(np.diff(centre, axis=0), axis=1) > 1e-6]
    centre = centre[keep]
    last_step = max((int(getattr(g.time_step, "end", g.time_step)) for g in pp.goal.state_list), default=0)
    frame, fit_res, frame_note = road_frame(centre, pos0, float(params.longitudinal.v_max) * last_step * dt)
    if frame_note is not None:
        notes.append(frame_note)

    # --- ego initial state --------------------------------------------------------------------
    s0, d0 = (float(v) for v in frame.to_road(pos0)[0])
    speed0 = float(init.velocity)
    heading0 = float(init.orientation)
    vel0 = np.array([[speed0 * math.cos(heading0), speed0 * math.sin(heading0)]])
    vs0, vd0 = (float(v) for v in frame.velocity_to_road(s0, d0, vel0)[0])

    # --- goal ---------------------------------------------------------------------------------
    own = network.find_lanelet_by_id(hits[0])
    lane_r = frame.to_road(np.asarray(own.right_vertices, dtype=float))
    lane_l = frame.to_road(np.asarray(own.left_vertices, dtype=float))
    ego_lane = tuple(sorted((float(np.interp(s0, *lane_r[np.argsort(lane_r[:, 0])].T)),
                             float(np.interp(s0, *lane_l[np.argsort(lane_l[:, 0])].T)))))
    v_range = (max(0.0, float(params.longitudinal.v_min)), float(params.longitudinal.v_max))
    try:
        goal = read_goal(pp, network, frame, (ego_lane[0], ego_lane[1]), v_range,
                         float(params.longitudinal.a_max))
    except (AttributeError, TypeError, ValueError) as exc:
        raise ScenarioError(f"unreadable goal region ({exc.__class__.__name__}: {exc})", "goalState", src) from None
    steps = goal.steps
    if any(e.pieces is None for e in goal.elements):
        # a goal state without a position ends in the ego's lane on the mapped road: the body's
        # centre half a body and its buffer before the end of the lane's chain of lanelets
        goal.s_max = _lane_end(frame, chain) - float(params.l) / 2 - BUFFER_M

    # --- final-state candidates --------------------------------------------------------------
    candidates = final_candidates((s0, vs0, d0, vd0), goal, dt)
    k_max = steps[1]

    # --- lanes and road edges -----------------------------------------------------------------
    lanes = sorted(float(np.median(frame.to_road(ll.center_vertices)[:, 1])) for ll in network.lanelets)
    merged: list[float] = []
    for y in lanes:
        if not merged or y - merged[-1] > 1.5:
            merged.append(y)
    s_end = max((c.s for c in candidates), default=s0 + vs0 * steps[1] * dt)
    via = min(candidates, key=lambda c: c.cost0) if candidates else None
    road_y, road_edges, corridor = _road_edges(frame, network, chain, min(s0, s_end) - EDGE_REACH_M,
                                               max(s0, s_end) + EDGE_REACH_M,
                                               np.asarray(dt * np.arange(steps[1] + 1), dtype=np.float64),
                                               ((s0, d0), (via.s, via.d) if via is not None else (s0 + 1.0, d0)))

    # --- recorded vehicles --------------------------------------------------------------------
    obstacles: list[Obstacle] = []
    for obs in [*scenario.dynamic_obstacles, *scenario.static_obstacles]:
        shape = obs.obstacle_shape
        if hasattr(shape, "length") and hasattr(obs, "prediction"):  # a rectangle that moves
            t, B = _obstacle_boxes(frame, obs, dt, k_max, src)
            length, width = float(shape.length), float(shape.width)
        else:  # a static obstacle, or a body of another shape: its occupancy at every step
            t, B = _occupancy_boxes(frame, obs, dt, k_max, src)
            length = float(np.max(B[:, 1] - B[:, 0])) if t.size else 0.0
            width = float(np.max(B[:, 3] - B[:, 2])) if t.size else 0.0
        if t.size == 0:
            continue
        coeffs, resid, half = fit_motion(t, B[:, 0], B[:, 1])
        centre_d = 0.5 * (B[:, 2] + B[:, 3])
        lane = int(np.argmin([abs(float(np.mean(centre_d)) - y) for y in merged])) if merged else 0
        obstacles.append(Obstacle(int(obs.obstacle_id), t, B[:, 0], B[:, 1], B[:, 2], B[:, 3],
                                  length, width, coeffs, half, resid, lane, bool(np.ptp(centre_d) > LANE_CHANGE_M)))
    return CommonRoadProblem(
        path=p, scenario=scenario, planning_problem_set=pps, planning_problem=pp, frame=frame,
        frame_fit_residual_m=fit_res, dt=dt, x0=(s0, vs0, d0, vd0), goal=goal, candidates=candidates,
        obstacles=obstacles, road_edges=road_edges, lanes=merged, road_y=road_y, ego_length=float(params.l),
        ego_width=float(params.w),
        a_max=float(params.longitudinal.a_max),
        speed_range=v_range, notes=notes, corridor=corridor)
