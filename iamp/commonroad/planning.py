r"""Planning a CommonRoad problem with iamp's planners: the active set of vehicles in the way.

A recorded scene holds 25-60 vehicles; few are in the ego's way.  The active-set loop
(SPEC §14's ``--constraint active`` idea, applied to the recorded boxes):

1. start from the unconstrained plan (the minimum-energy cubic per axis, no vehicle);
2. measure, at every recorded time step, how deeply the ego's body (its bounding box at its
   heading, :func:`~iamp.commonroad.convert.ego_margins`) enters each recorded vehicle's box
   (the real recorded corners in the road frame, not the cubic);
3. impose the deepest intruded vehicle with the corner that describes the manoeuvre
   (:func:`corner_for`: ``front``/``rear`` by which side of it the ego ends, ``upper``/``lower``
   by the side it is beside at the start or the end) and plan again with the chosen planner
   (the paper's equality by the PMP or the QP, or the avoidance QP of §10);
4. repeat until no vehicle is intruded (the plan is ``safe``) or nothing more can be imposed;
5. a plan that is unsafe only at road edges is repaired laterally (:func:`repair_at_edges`: its
   longitudinal motion kept, its lateral motion one convex QP with the body's corners and sides
   at its own heading inside the road corridor, beside the vehicles it is beside).

A vehicle the ego neither starts nor ends beside (car following in its lane) has no corner
(§10's half-plane crossing does not exist); the loop cannot impose it and tries the next final
state.  Final states are the goal's final states that can be valid, in order of the
unconstrained cost: for every goal state, time step and piece, the cheapest pose inside every
goal element whose body is clear of every recorded vehicle at that step and on the road
(:func:`search_final_states`, :func:`final_state_clearance`); the first safe plan is taken
(``max_candidates`` bounds the search).

``planner="all-pmp"`` is the paper's method without the active set: every *relevant* vehicle
(its recorded box within the ego's lateral corridor and within :data:`RELEVANT_S_M` of the
unconstrained plan) imposed at once with the PMP.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field
from types import SimpleNamespace
from typing import TYPE_CHECKING, Any, NamedTuple, TypedDict

import numpy as np
import numpy.typing as npt

from iamp.commonroad.check import VerdictJSON
from iamp.commonroad.convert import (
    BUFFER_M,
    EDGE_BUFFER_M,
    EDGE_STEP_M,
    HEADING_GUESS_RAD,
    CommonRoadProblem,
    Obstacle,
    ego_margins,
)
from iamp.commonroad.goal import CLEAR_MAX_SOLVES, Blocked, Candidate, ClearanceTest, ClearSearch, clear_goal_states
from iamp.core.errors import IampError, ScenarioError
from iamp.core.plan import Plan, Trajectory
from iamp.core.problem import SurroundingVehicle

if TYPE_CHECKING:
    from iamp.commonroad.ks import KSTrajectory

FloatArray = npt.NDArray[np.float64]

#: The planners of ``iamp commonroad plan`` (label -> (iamp planner, constraint, active set)).
PLANNERS: dict[str, tuple[str, str, bool]] = {
    "avoid": ("qp", "avoid", True),
    "pmp": ("pmp", "equality", True),
    "qp": ("qp", "equality", True),
    "all-pmp": ("pmp", "equality", False),
    "free": ("", "", False),
}
DEFAULT_PLANNER = "avoid"
#: Points of a plan's horizon at which its heading, peak acceleration and lowest speed are read.
LIMIT_SAMPLES = 401
#: How far below the lowest speed of the vehicle type a plan's speed along the road may dip (the
#: round-off of a final state at rest, about 1e-16) [m/s].
SPEED_TOL_MPS = 1e-6
#: Buffer of the body check (the planners' margins carry the larger convert.BUFFER_M) [m].
CHECK_BUFFER_M = 0.05
#: Overlap with a road-edge box that the self-check tolerates: the boxes take the narrowest
#: edge over :data:`~iamp.commonroad.convert.EDGE_CHUNK_M` and the frame's fit error is a few cm,
#: so a start that CommonRoad's road check accepts can touch them [m].
EDGE_SLACK_M = 0.02
#: Clearance of a final state's body from the road corridor's edge (:func:`final_state_clearance`) [m].
FINAL_EDGE_BUFFER_M = 0.01
#: How far beyond the body's margin a way around an obstacle puts the final state
#: (:func:`final_state_clearance`): a pose exactly at the margin touches it, and the body check's
#: rounding may call that an overlap (the search then re-added the same row until its node
#: budget ran out) [m].
WAY_PUSH_M = 1e-6
#: Longitudinal reach of "relevant" for the all-vehicles equality [m].
RELEVANT_S_M = 10.0
#: Active-set iterations.
MAX_IMPOSED = 6
#: Final states tried per problem (:func:`_candidate_order`).
MAX_CANDIDATES = 8
#: Calls of the iamp planner per problem, over every final state (a count, never a time).
MAX_PLANS = 6
#: Grid intervals of the QP planners (24 and 40 give the same plans to 1e-4 in J on US-101, 1.5-4x faster).
STEPS = 24
#: Branch-and-bound boxes of the PMP per problem, over every call (each call's ``max_boxes`` is
#: what is left; beyond it the plan is ``local``).
PMP_MAX_BOXES = 2_000
#: Fewest boxes a PMP call is made with; a call that the boxes left cannot afford is not made.
PMP_MIN_BOXES = 64
#: QP solves per avoidance-QP call (its branch and bound's ``max_solves``).
AVOID_MAX_SOLVES = 8
#: QP solves of the equality QP per problem, over every call (the avoidance QP's most,
#: ``AVOID_MAX_SOLVES * MAX_PLANS``): its contact-time sweep solves one QP per assignment of
#: distinct interior grid nodes, ``(N-1)!/(N-1-m)!`` for ``m`` vehicles, so each call's grid is
#: the finest the solves left allow (:func:`qp_steps`).
QP_MAX_SOLVES = 48
#: Coarsest grid of an equality-QP call; a call that the solves left cannot afford is not made.
QP_MIN_STEPS = 4


class FreeTrajectory:
    """The unconstrained minimum-energy plan: a cubic per axis,
    :math:`p(t) = p_0 + v_0 t + a t^2 + b t^3`, :math:`a = (3\\Delta - \\delta v T)/T^2`,
    :math:`b = (\\delta v T - 2\\Delta)/T^3`."""

    def __init__(self, T: float, start: tuple[float, float, float, float], end: tuple[float, float, float, float]):
        self.T = T
        self.c = []
        for (p0, v0), (pf, vf) in (((start[0], start[1]), (end[0], end[1])), ((start[2], start[3]), (end[2], end[3]))):
            D, dv = pf - p0 - v0 * T, vf - v0
            self.c.append((p0, v0, (3 * D - dv * T) / T**2, (dv * T - 2 * D) / T**3))

    def states(self, t: npt.ArrayLike) -> FloatArray:
        tt = np.atleast_1d(np.asarray(t, dtype=float))
        cols = []
        for p0, v0, a, b in self.c:
            cols += [p0 + v0 * tt + a * tt**2 + b * tt**3, v0 + 2 * a * tt + 3 * b * tt**2]
        return np.stack(cols, axis=1)

    def inputs(self, t: npt.ArrayLike) -> FloatArray:
        tt = np.atleast_1d(np.asarray(t, dtype=float))
        return np.stack([2 * a + 6 * b * tt for _, _, a, b in self.c], axis=1)

    def cost(self) -> float:
        """½∫|u|² exactly (Gauss-Legendre on the linear inputs)."""
        x, w = np.polynomial.legendre.leggauss(4)
        t = 0.5 * self.T * (x + 1)
        return float(0.25 * self.T * np.sum(w * np.sum(self.inputs(t) ** 2, axis=1)))


@dataclass
class Intrusion:
    """The deepest entry of the ego's body box into one recorded vehicle's box."""

    obstacle: Obstacle
    depth_m: float
    time_s: float


class ImposedJSON(TypedDict):
    """A vehicle whose corner a plan imposed."""

    obstacle: int
    corner: str


class IntrusionJSON(TypedDict):
    """A recorded vehicle the ego's body box enters: how deep [m] and when [s]."""

    obstacle: int
    depth_m: float
    t: float


class FinalStateJSON(TypedDict):
    """A candidate's final state in the road frame and its number of steps."""

    s: float
    vs: float
    d: float
    vd: float
    steps: int


class RoadPlanJSON(TypedDict, total=False):
    """The JSON object of a road plan (:func:`describe`, every key; ``iamp commonroad plan`` and the
    bench add the scenario, the solution's drift and the checker's verdict)."""

    planner: str
    status: str
    iamp_status: str | None
    cost: float | None
    solve_time_s: float
    tf: float | None
    final_state: FinalStateJSON | None
    candidates_tried: int
    planner_calls: int
    imposed: list[ImposedJSON]
    intrusions: list[IntrusionJSON]
    off_road_s: list[float]
    max_heading_rad: float
    peak_accel_mps2: float
    reason: str | None
    scenario: str
    frame_fit_residual_m: float
    notes: list[str]
    predict: bool
    zoh_drift_m: float
    solution: str
    commonroad: VerdictJSON


@dataclass
class RoadPlan:
    """A plan in the road frame with how it was found."""

    planner: str
    status: str
    candidate: Candidate | None
    trajectory: Trajectory | None  # the iamp plan, or the free cubic
    cost: float | None
    solve_time_s: float
    imposed: list[tuple[int, str]] = field(default_factory=list)
    intrusions: list[Intrusion] = field(default_factory=list)
    iamp_status: str | None = None
    candidates_tried: int = 0
    reason: str | None = None
    max_heading_rad: float = 0.0
    peak_accel_mps2: float = 0.0
    plans_used: int = 0
    blocked: Obstacle | None = None  # an intruded vehicle without a corner for this final state
    #: For a steered solution (:func:`steer_at_edges`): does the tracked ``KS`` solution reach the
    #: goal by CommonRoad's test (``None``: not tracked)?
    steered_goal: bool | None = None
    #: The tracked ``KS`` solution :attr:`steered_goal` was judged on (``None``: not tracked).
    steered: Any = field(default=None, repr=False)
    #: The times [s] at which CommonRoad's own road-boundary checker finds the body of the
    #: solution written from this plan off the road (:func:`road_checked`; empty: not found, or
    #: not checked).
    off_road_s: list[float] = field(default_factory=list)

    @property
    def safe(self) -> bool:
        return self.trajectory is not None and not self.intrusions and not self.off_road_s

    def within_limits(self, cr: CommonRoadProblem) -> bool:
        """A plan within the vehicle's limits (:meth:`limit_breach` finds none)."""
        return self.trajectory is not None and self.candidate is not None and self.limit_breach(cr) is None

    def limit_breach(self, cr: CommonRoadProblem) -> str | None:
        """How the plan leaves the vehicle's limits, in words (None: it does not): the peak
        acceleration above ``a_max``, or the speed along the road below the type's lowest (0: no
        reversing; widened to the start's and the final state's own speeds, which the plan must
        meet) by more than :data:`SPEED_TOL_MPS`, on :data:`LIMIT_SAMPLES` points of its horizon.
        A cubic whose final state lies behind the start reaches it by reversing, which CommonRoad's
        ``PM`` model accepts with the body turned around (its heading is its velocity's); no car
        on a road does that."""
        if self.trajectory is None or self.candidate is None:
            return None
        if self.peak_accel_mps2 > cr.a_max:
            return f"its peak acceleration {self.peak_accel_mps2:.2f} m/s^2 exceeds a_max {cr.a_max:.2f} m/s^2"
        floor = min(cr.speed_range[0], cr.x0[1], self.candidate.vs)
        low = min_speed(self.trajectory, self.candidate.tf)
        if low < floor - SPEED_TOL_MPS:
            lowest = round(floor, 2) + 0.0  # no "-0.00" for a final state at rest read as -1e-16
            return (f"its speed along the road falls to {low:.2f} m/s, below the lowest {lowest:.2f} m/s "
                    "(it would reverse)")
        return None


def body_overlap(s: FloatArray, d: FloatArray, heading: FloatArray, s_lo: FloatArray, s_hi: FloatArray,
                 d_lo: FloatArray, d_hi: FloatArray, half_l: float, half_w: float, buffer: float) -> FloatArray:
    """How deep the ego's body (centre ``(s, d)``, half extents ``half_l, half_w`` turned by
    ``heading`` relative to the road) grown by ``buffer`` overlaps each box: the separating-axis
    overlap, the smallest over the road's two axes and the body's two (> 0: they overlap)."""
    c, sn = np.cos(heading), np.sin(heading)
    bs, bd = 0.5 * (s_hi - s_lo), 0.5 * (d_hi - d_lo)
    ds, dd = s - 0.5 * (s_lo + s_hi), d - 0.5 * (d_lo + d_hi)
    along_s = half_l * np.abs(c) + half_w * np.abs(sn) + bs + buffer - np.abs(ds)
    along_d = half_l * np.abs(sn) + half_w * np.abs(c) + bd + buffer - np.abs(dd)
    body_u = half_l + bs * np.abs(c) + bd * np.abs(sn) + buffer - np.abs(ds * c + dd * sn)
    body_n = half_w + bs * np.abs(sn) + bd * np.abs(c) + buffer - np.abs(-ds * sn + dd * c)
    return np.asarray(np.minimum(np.minimum(along_s, along_d), np.minimum(body_u, body_n)), dtype=float)


def off_road_steps(cr: CommonRoadProblem, trajectory: Trajectory, steps: int) -> npt.NDArray[np.bool_]:
    """At which time steps ``0..steps`` the body of the solution written from ``trajectory`` (its
    zero-order-hold world states, :func:`~iamp.commonroad.solution.world_states`, the body at the
    heading of its velocity) collides with the road boundary, by CommonRoad's own road-boundary
    checker (the lanelets' triangulation the solution checker builds; built once per problem).

    Parameters
    ----------
    cr : CommonRoadProblem
    trajectory : Trajectory
        A road-frame plan.
    steps : int
        The last time step.

    Returns
    -------
    ndarray of bool, shape (steps + 1,)
    """
    from iamp.commonroad.solution import world_states

    P, V, _ = world_states(cr, trajectory, steps)
    return off_road_poses(cr, P, np.arctan2(V[:, 1], V[:, 0]))


def off_road_poses(cr: CommonRoadProblem, centre: FloatArray, heading: FloatArray,
                   grow: float = 0.0) -> npt.NDArray[np.bool_]:
    """Which of the ego's bodies (centres ``(n, 2)`` in the world, world headings ``(n,)``, each
    half extent grown by ``grow``) collide with CommonRoad's road boundary (its own checker, the
    one the solution checker builds; built once per problem).

    Parameters
    ----------
    cr : CommonRoadProblem
    centre : ndarray, shape (n, 2)
    heading : ndarray, shape (n,)
    grow : float
        Added to both half extents [m] (0: the checker's body).

    Returns
    -------
    ndarray of bool, shape (n,)
    """
    import importlib

    from commonroad_dc.feasibility import solution_checker

    pycrcc = importlib.import_module("commonroad_dc.pycrcc")  # (its type stub does not parse)

    if cr.road_checker is None:
        cr.road_checker = solution_checker._construct_boundary_checker(cr.scenario)
    L2, W2 = cr.ego_length / 2 + grow, cr.ego_width / 2 + grow
    return np.array([bool(cr.road_checker.collide(pycrcc.RectOBB(L2, W2, float(h), float(p[0]), float(p[1]))))
                     for p, h in zip(np.asarray(centre, dtype=float), np.asarray(heading, dtype=float))], dtype=bool)


def intrusions(cr: CommonRoadProblem, trajectory: Trajectory, T: float,
               buffer: float = CHECK_BUFFER_M) -> list[Intrusion]:
    """Every recorded vehicle whose box the ego's body enters, deepest first (module doc, step 2).

    The body is the ego's rectangle at its heading in the road frame, the box each vehicle's
    recorded box at every recorded step; the depth is :func:`body_overlap`, so a body turned
    away from a road edge is not charged with its bounding box's corner.  A road-edge box
    (grown by :data:`EDGE_SLACK_M`: the corridor's bounds are within a centimetre or two of
    CommonRoad's) counts only at the steps where CommonRoad's own road-boundary check finds the
    body off the road (:func:`off_road_steps`): the boxes cover the narrowest bound over up to
    :data:`~iamp.commonroad.convert.EDGE_CHUNK_M` and overstate an edge that narrows steeply."""
    out = []
    off: npt.NDArray[np.bool_] | None = None
    for ob in cr.all_obstacles:
        keep = ob.t <= T + 1e-9
        if not keep.any():
            continue
        t = ob.t[keep]
        X = trajectory.states(t)
        heading = np.arctan2(X[:, 3], np.maximum(X[:, 1], 1e-6))
        depth = body_overlap(X[:, 0], X[:, 2], heading, ob.s_lo[keep], ob.s_hi[keep], ob.d_lo[keep], ob.d_hi[keep],
                             cr.ego_length / 2, cr.ego_width / 2, EDGE_SLACK_M if ob.road_edge else buffer)
        if ob.road_edge and np.any(depth > 0):
            if off is None:
                off = off_road_steps(cr, trajectory, int(round(T / cr.dt)))
            step = np.clip(np.rint(t / cr.dt).astype(int), 0, off.size - 1)
            depth = np.where(off[step], depth, -np.inf)
        k = int(np.argmax(depth))
        if depth[k] > 0:
            out.append(Intrusion(ob, float(depth[k]), float(t[k])))
    out.sort(key=lambda i: -i.depth_m)
    return out


def clear_final_states(cr: CommonRoadProblem, cands: list[Candidate], buffer: float = BUFFER_M) -> list[Candidate]:
    """The candidates whose final state keeps the ego's body (grown by ``buffer``) off every
    recorded vehicle at its final time step: one that ends inside a vehicle has no safe plan, so
    it costs no planner call."""
    if not cands:
        return []
    ok = np.ones(len(cands), dtype=bool)
    s = np.array([c.s for c in cands])
    d = np.array([c.d for c in cands])
    heading = np.arctan2(np.array([c.vd for c in cands]), np.maximum(np.array([c.vs for c in cands]), 1e-6))
    t_end = np.array([c.tf for c in cands])
    for ob in cr.obstacles:
        k = np.searchsorted(ob.t, t_end - 1e-6)
        there = (k < ob.t.size)
        there[there] &= np.abs(ob.t[np.minimum(k[there], ob.t.size - 1)] - t_end[there]) < 1e-6
        if not there.any():
            continue
        j = k[there]
        depth = body_overlap(s[there], d[there], heading[there], ob.s_lo[j], ob.s_hi[j], ob.d_lo[j], ob.d_hi[j],
                             cr.ego_length / 2, cr.ego_width / 2, buffer)
        ok[np.flatnonzero(there)[depth > 0]] = False
    return [c for c, keep in zip(cands, ok) if keep]


def final_state_clearance(cr: CommonRoadProblem, buffer: float = BUFFER_M,
                          edge_buffer: float = FINAL_EDGE_BUFFER_M) -> ClearanceTest:
    r"""The clearance test of the final-state search (:func:`~iamp.commonroad.goal.clear_final_states`):
    a final state ``z = (s, vs, d, vd)`` at horizon ``T`` is accepted when the ego's body at its
    heading :math:`\operatorname{atan2}(\dot d, \dot s)`, grown by ``buffer``, enters no recorded
    vehicle's box at that time step (:func:`body_overlap`, as :func:`clear_final_states`), enters
    the road-edge boxes and the road's widest bounds ``cr.road_y`` no deeper than the self-check
    tolerates (:func:`intrusions`, :data:`EDGE_SLACK_M`) and, grown by ``edge_buffer``, stays
    inside the road corridor (``cr.corridor``: every sample :math:`s_j` the body spans between
    :math:`d^-(s_j)` and :math:`d^+(s_j)`, a sample off every lanelet excluded).  Otherwise it
    names what the body enters and the ways around the deepest of them: ahead of it
    (:math:`s \ge s^+ + S_x`), behind it, above (:math:`d \ge d^+ + S_y`) or below it, with
    :math:`S_x, S_y` the body's margins at the band's heading (:func:`~iamp.commonroad.convert.ego_margins`);
    a corridor sample is a box of zero length below :math:`d^-(s_j)` (or above :math:`d^+(s_j)`).

    Parameters
    ----------
    cr : CommonRoadProblem
    buffer : float
        Clearance from the vehicles [m] (the planner's :data:`~iamp.commonroad.convert.BUFFER_M`).
    edge_buffer : float
        Clearance from the road's edge [m].

    Returns
    -------
    callable
        ``(T, z, band) -> None | Blocked``.
    """
    L2, W2 = cr.ego_length / 2, cr.ego_width / 2
    big = 1e3
    y_lo, y_hi = cr.road_y
    static = [(-1e5, 1e5, y_lo - big, y_lo), (-1e5, 1e5, y_hi, y_hi + big)]
    static += [(float(ob.s_lo[0]), float(ob.s_hi[0]), float(ob.d_lo[0]), float(ob.d_hi[0])) for ob in cr.road_edges]
    road = np.array(static, dtype=float)
    samples: list[tuple[float, float, float, float, int]] = []  # the corridor's samples, boxes of zero length
    if cr.corridor is not None:
        for s_j, lo_j, hi_j in zip(*cr.corridor):
            if np.isfinite(lo_j) and np.isfinite(hi_j):  # below the road (kind 0), above it (1)
                samples += [(float(s_j), float(s_j), float(lo_j) - big, float(lo_j), 0),
                            (float(s_j), float(s_j), float(hi_j), float(hi_j) + big, 1)]
            else:  # off every lanelet (2)
                samples.append((float(s_j), float(s_j), -big, big, 2))
    corridor = np.array(samples, dtype=float).reshape(-1, 5)

    def ways(box: tuple[float, float, float, float], buf: float, band: float) -> tuple[tuple[FloatArray, float], ...]:
        s_lo, s_hi, d_lo, d_hi = box
        sx, sy = ego_margins(cr.ego_length, cr.ego_width, band, buf + WAY_PUSH_M)
        out = [(np.array([-1.0, 0.0, 0.0, 0.0]), -(s_hi + sx)), (np.array([1.0, 0.0, 0.0, 0.0]), s_lo - sx)]
        if d_hi < big / 2:
            out.append((np.array([0.0, 0.0, -1.0, 0.0]), -(d_hi + sy)))
        if d_lo > -big / 2:
            out.append((np.array([0.0, 0.0, 1.0, 0.0]), d_lo - sy))
        return tuple(out)

    def depth_of(B: FloatArray, z: tuple[float, float, float, float], heading: float) -> FloatArray:
        n = len(B)
        return body_overlap(np.full(n, z[0]), np.full(n, z[2]), np.full(n, heading), B[:, 0], B[:, 1], B[:, 2],
                            B[:, 3], L2, W2, 0.0)

    at: dict[float, tuple[FloatArray, FloatArray, list[str]]] = {}

    def occupied(T: float) -> tuple[FloatArray, FloatArray, list[str]]:
        """Every box at time ``T`` with its buffer and name (the road-edge boxes as the self-check
        judges them, :func:`intrusions`: less :data:`EDGE_SLACK_M`)."""
        key = round(T, 6)
        if key not in at:
            boxes, buffers, names = [road], [np.full(len(road), -EDGE_SLACK_M)], ["the road's edge"] * len(road)
            for ob in cr.obstacles:
                k = _step_at(ob, T)
                if k is not None:
                    boxes.append(np.array([[ob.s_lo[k], ob.s_hi[k], ob.d_lo[k], ob.d_hi[k]]]))
                    buffers.append(np.array([buffer]))
                    names.append(f"vehicle {ob.obstacle_id}")
            at[key] = (np.concatenate(boxes), np.concatenate(buffers), names)
        return at[key]

    def test(T: float, z: tuple[float, float, float, float], band: float) -> Blocked | None:
        heading = math.atan2(z[3], max(z[1], 1e-6))
        B, buf, names = occupied(T)
        depth = depth_of(B, z, heading) + buf
        if np.any(depth > 0):
            i = int(np.argmax(depth))
            hit = sorted({names[j] for j in np.flatnonzero(depth > 0)})
            return Blocked(tuple(hit), ways((B[i, 0], B[i, 1], B[i, 2], B[i, 3]), float(buf[i]), band))
        near = corridor[np.abs(corridor[:, 0] - z[0]) <= L2 + W2 + 1.0]
        if near.size == 0:
            return None
        off = near[depth_of(near, z, heading) + edge_buffer > 0]
        if off.size == 0:
            return None
        # the samples the body leaves the road at, of the deepest one's kind, as one box
        d_off = depth_of(off, z, heading)
        kind = off[int(np.argmax(d_off)), 4]
        same = off[off[:, 4] == kind]
        s_a, s_b = float(same[:, 0].min()), float(same[:, 1].max())
        box = ((s_a, s_b, -big, float(same[:, 3].max())) if kind == 0 else
               (s_a, s_b, float(same[:, 2].min()), big) if kind == 1 else (s_a, s_b, -big, big))
        return Blocked(("the road's edge",), ways(box, edge_buffer, band))

    return test


def _step_at(ob: Obstacle, T: float) -> int | None:
    """The index of ``ob``'s recorded step at time ``T``, or None where it has none."""
    k = int(np.searchsorted(ob.t, T - 1e-6))
    return k if k < ob.t.size and abs(float(ob.t[k]) - T) < 1e-6 else None


def _elapsed(cr: CommonRoadProblem) -> int:
    """Steps already passed when ``cr``'s final states were made (0 unless replanned)."""
    c = cr.candidates[0]
    return c.goal_step - c.steps


def search_final_states(cr: CommonRoadProblem, max_solves: int = CLEAR_MAX_SOLVES) -> ClearSearch | None:
    """The final states of ``cr``'s goal that can be valid (:func:`~iamp.commonroad.goal.clear_goal_states`
    with :func:`final_state_clearance`), or None when ``cr.candidates`` are not the goal's final
    states (waypoints of the tactical layer: they are judged as given, by :func:`clear_final_states`).

    Parameters
    ----------
    cr : CommonRoadProblem
    max_solves : int
        QP solves of the search (a count, never a time).

    Returns
    -------
    ClearSearch or None
    """
    if not cr.candidates or any(c.goal_step < 0 for c in cr.candidates):
        return None
    test = final_state_clearance(cr)
    found = clear_goal_states(cr.goal, cr.x0, cr.dt, test, _elapsed(cr), max_solves, known=cr.candidates)
    follow, solves = follow_states(cr, test, max_solves - found.solves)
    if not follow:
        return found
    seen = {(c.element, c.goal_step, round(c.s, 3), round(c.d, 3)) for c in found.candidates}
    extra = [c for c in follow if (c.element, c.goal_step, round(c.s, 3), round(c.d, 3)) not in seen]
    return dataclasses.replace(found, candidates=sorted(found.candidates + extra,
                                                        key=lambda c: (c.cost0, c.steps, c.element, c.piece)),
                               solves=found.solves + solves)


#: Vehicles ahead in the ego's lane at the start, nearest first, behind each of which a goal state
#: without a position gets a final state of its own (:func:`follow_states`).
FOLLOW_VEHICLES = 3


def follow_states(cr: CommonRoadProblem, test: ClearanceTest, max_solves: int) -> tuple[list[Candidate], int]:
    """Final states that keep the ego's lane behind a vehicle ahead, for the goal states without
    a position (their final state is anywhere in the ego's lane).

    The cheapest clear final state of such a goal state (:func:`~iamp.commonroad.goal.clear_goal_states`)
    may lie beyond vehicles ahead in the lane that the ego cannot pass inside it (dense traffic: the
    ego's lane is the goal); a driver follows them.  For each of the :data:`FOLLOW_VEHICLES` nearest
    vehicles ahead in the ego's lane at the start (their box at ``t = 0`` across the lane's bounds
    ``cr.goal.ego_lane``, ahead of the ego's centre), at the last step of the goal state's window
    where that vehicle is recorded: the cheapest final state that ``test`` accepts with the body's
    centre half a body, :data:`~iamp.commonroad.convert.BUFFER_M` and :data:`WAY_PUSH_M` behind the
    vehicle's rear (the goal region's ``s_max`` lowered to there).  ``max_solves`` QP solves in all;
    returns the final states and the solves spent.
    """
    region = cr.goal
    lo, hi = region.ego_lane
    s0 = cr.x0[0]
    ahead = [ob for ob in cr.obstacles
             if ob.t.size and ob.t[0] <= 1e-9 and ob.s_lo[0] > s0 and ob.d_hi[0] > lo and ob.d_lo[0] < hi]
    ahead.sort(key=lambda ob: float(ob.s_lo[0]))
    elapsed = _elapsed(cr)
    out: list[Candidate] = []
    solves = 0
    for e in region.elements:
        if e.pieces is not None:
            continue
        for ob in ahead[:FOLLOW_VEHICLES]:
            ks = [k for k in range(max(e.steps[0], elapsed + 1), e.steps[1] + 1)
                  if _step_at(ob, (k - elapsed) * cr.dt) is not None]
            if not ks or solves >= max_solves:
                continue
            k = ks[-1]
            rear = float(ob.s_lo[_step_at(ob, (k - elapsed) * cr.dt)])
            sub = dataclasses.replace(region, elements=[dataclasses.replace(e, steps=(k, k))],
                                      s_max=min(region.s_max, rear - cr.ego_length / 2 - BUFFER_M - WAY_PUSH_M))
            got = clear_goal_states(sub, cr.x0, cr.dt, test, elapsed, max_solves - solves)
            solves += got.solves
            out += got.candidates
    return out, solves


def corner_for(ob: Obstacle, candidate: Candidate, x0: tuple[float, float, float, float],
               sy: float, sx: float = 0.0, edge: tuple[float, float] | None = None) -> str | None:
    """The corner describing the manoeuvre around ``ob`` (module docstring, step 3), or ``None``.

    A road-edge box (``ob.road_edge``) is passed on the side of the road (``upper`` for an edge
    below the corridor, ``lower`` above it): ``front-<side>`` when the ego starts beside it (in
    the lateral half-plane, with the edge margins of :func:`_avoided`) and ends ahead of it,
    ``rear-<side>`` when it starts behind it and ends beside it.  ``edge`` gives the body's
    margins at a road edge (:func:`edge_margins`); by default ``sx, sy`` less the vehicles' buffer.
    """
    if ob.road_edge:
        sx_e, sy_e = edge if edge is not None else (sx - BUFFER_M + EDGE_BUFFER_M, sy - BUFFER_M + EDGE_BUFFER_M)
        top, bottom = float(ob.d_hi.max()), float(ob.d_lo.min())
        s_lo, s_hi = float(ob.s_lo.min()), float(ob.s_hi.max())
        # the box is below the ego: pass above it; a hole in the road (ob.hole) on either side
        sides = (ob.y < x0[2],) + ((ob.y >= x0[2],) if ob.hole else ())
        for upper in sides:
            edge_side = "upper" if upper else "lower"

            def beside(d: float, above: bool) -> bool:
                return d >= top + sy_e if above else d <= bottom - sy_e

            if beside(x0[2], upper) and candidate.s >= s_hi + sx_e:
                return f"front-{edge_side}"
            if x0[0] <= s_lo - sx_e and beside(candidate.d, upper):
                return f"rear-{edge_side}"
        return None
    ax, ay = ob.half_length + sx, ob.box_width / 2 + sy

    def planes(t: float, x: float, y: float) -> set[str]:
        xs = float(np.polynomial.polynomial.polyval(t, ob.cubic))
        out = {name for name, inside in (("front", x >= xs + ax), ("rear", x <= xs - ax), ("upper", y >= ob.y + ay),
                                         ("lower", y <= ob.y - ay)) if inside}
        return out

    start, end = planes(0.0, x0[0], x0[2]), planes(candidate.tf, candidate.s, candidate.d)

    def valid(corner: str) -> bool:
        lon, lat = corner.split("-")
        return (lon in start and lat in end) or (lat in start and lon in end)

    # the manoeuvre's own corner first: the side it starts (or ends) beside, ahead or behind at the end
    end_ahead = candidate.s > float(np.polynomial.polynomial.polyval(candidate.tf, ob.cubic))
    lat = next((p for p in ("upper", "lower") if p in start), next((p for p in ("upper", "lower") if p in end), None))
    preferred = [f"{'front' if end_ahead else 'rear'}-{lat}"] if lat is not None else []
    for corner in preferred + ["front-upper", "front-lower", "rear-upper", "rear-lower"]:
        if valid(corner):
            return corner
    return None  # a start or end inside its safety region, or in the same half-plane at both ends


def road_checked(cr: CommonRoadProblem, rp: RoadPlan) -> bool:
    """Does CommonRoad's own road-boundary checker find the body of the solution written from
    ``rp`` on the road at every step (:func:`off_road_steps`)?  The road-edge boxes count only
    where it finds the body off the road, but it can find it off where no box is entered: the
    public hand-crafted DEU_Muc-2_1's corridor held its two lanelets (bounds shared, no adjacency
    given), whose plan was called ``optimal`` while the checker finds its body off the road at
    0.6-1.5 s (it draws a boundary along such a bound; the corridor now follows the map's
    adjacency, :func:`~iamp.commonroad.convert.load`, and this check stays as the last word).
    Where it does, the times go to :attr:`RoadPlan.off_road_s` and the plan is ``unsafe``."""
    if rp.trajectory is None or rp.candidate is None:
        return False
    off = off_road_steps(cr, rp.trajectory, rp.candidate.steps)
    if off.any():
        rp.off_road_s = [float(k * cr.dt) for k in np.flatnonzero(off)]
        rp.status = "unsafe"
        rp.reason = rp.reason or (f"CommonRoad's road boundary: the body is off the road at "
                                  f"{rp.off_road_s[0]:.1f}-{rp.off_road_s[-1]:.1f} s")
        return False
    return True


def min_speed(trajectory: Trajectory, T: float) -> float:
    """The lowest speed along the road of ``trajectory`` on ``[0, T]`` (:data:`LIMIT_SAMPLES` points) [m/s]."""
    return float(np.min(trajectory.states(np.linspace(0.0, T, LIMIT_SAMPLES))[:, 1]))


def _heading_and_peak(trajectory: Trajectory, T: float) -> tuple[float, float]:
    t = np.linspace(0.0, T, LIMIT_SAMPLES)
    X = trajectory.states(t)
    U = trajectory.inputs(t)
    return (float(np.max(np.abs(np.arctan2(X[:, 3], np.maximum(X[:, 1], 1e-6))))),
            float(np.max(np.hypot(U[:, 0], U[:, 1]))))


def qp_steps(m: int, steps: int = STEPS, max_solves: int = QP_MAX_SOLVES) -> int:
    """Grid intervals of the equality QP with ``m`` imposed vehicles: ``steps``, or fewer so that
    its sweep over every assignment of distinct interior nodes, ``(N-1)!/(N-1-m)!`` QP solves, stays within
    ``max_solves`` (a count of solves, never a time; at least 2 intervals).

    Parameters
    ----------
    m : int
        Vehicles (and road-edge boxes) imposed at once.
    steps : int
        The grid asked for.
    max_solves : int
        The most QP solves of one sweep.

    Returns
    -------
    int
        The largest ``N <= steps`` whose sweep is within ``max_solves`` (``N >= 2``).
    """
    n = steps
    while n > 2 and math.perm(n - 1, max(m, 1)) > max_solves:
        n -= 1
    return n


def _affords(budget: list[int], iamp_planner: str, constraint: str, m: int, steps: int) -> bool:
    """Can ``budget`` (calls, equality-QP solves, PMP boxes) pay one more call with ``m`` vehicles?"""
    if budget[0] <= 0:
        return False
    if iamp_planner == "pmp":
        return budget[2] >= PMP_MIN_BOXES
    if iamp_planner != "qp" or constraint != "equality":
        return True
    n = qp_steps(m, steps, budget[1])
    return n >= QP_MIN_STEPS and math.perm(n - 1, m) <= budget[1]


def _iamp_plan(cr: CommonRoadProblem, cand: Candidate, vehicles: list[SurroundingVehicle], margin_y: float,
               planner: str, constraint: str, steps: int, max_boxes: int = PMP_MAX_BOXES) -> Plan:
    import iamp

    problem = cr.problem(cand, vehicles, margin_y)
    if planner == "pmp":
        return iamp.plan(problem, "pmp", max_boxes=max_boxes)
    if constraint == "avoid":
        return iamp.plan(problem, "qp", constraint=constraint, steps=steps, hold="foh", max_solves=AVOID_MAX_SOLVES)
    return iamp.plan(problem, "qp", constraint=constraint, steps=steps, hold="foh")


def refine_checks() -> Any:
    """iamp's tests of a steered solution for :func:`iamp.commonroad.ks_refine.refine` (the vehicles'
    boxes per step, the body's overlap, clear of the vehicles, on the road, the goal reached)."""
    from iamp.commonroad.ks_refine import Checks

    return Checks(_step_boxes, body_overlap, steered_clear, steered_off_road, steered_reaches_goal)


def plan(cr: CommonRoadProblem, planner: str = DEFAULT_PLANNER, *, max_candidates: int = MAX_CANDIDATES,
         steps: int = STEPS, max_plans: int = MAX_PLANS, via: bool = True, search: bool = True,
         corridor: bool = True, engine: tuple[float, ...] | None = None) -> RoadPlan:
    """Plan ``cr`` with ``planner`` (a key of :data:`PLANNERS`; module docstring,
    :func:`_plan_road`).

    With a steered model (``engine`` a :class:`KSEngine`): where the steered solution tracked from
    the plan is not valid by iamp's own tests (the plan unsafe, or the tracked car missing the
    goal or entering a vehicle's box, :func:`steered_valid`), the ``KS`` inputs are optimised
    directly (:func:`iamp.commonroad.ks_refine.refine`), from the tracked solution of this plan
    and then of the point-mass pipeline's plan (``engine=None``), each cut or continued to its
    own final step and then to the steps :data:`~iamp.commonroad.ks_refine.STEP_OFFSETS` away
    inside the goal's window, within
    :data:`~iamp.commonroad.ks_refine.PROBLEM_EVALUATIONS` evaluations; the first accepted is returned
    (``iamp_status`` ``steered-refined``, its trajectory a
    :class:`~iamp.commonroad.ks_refine.SteeredTrajectory`).  When none is accepted, the vehicle
    the first plan's steered solution meets is passed behind it (:func:`plan_behind`, its own
    budgets of QP solves and evaluations; the same status).  Plans whose steered solution passes
    are returned unchanged.
    """
    kw: dict[str, Any] = {"max_candidates": max_candidates, "steps": steps, "max_plans": max_plans, "via": via,
                          "search": search, "corridor": corridor}
    rp = _plan_road(cr, planner, engine=engine, **kw)
    vehicle_type = getattr(engine, "vehicle_type", None)
    if vehicle_type is None or planner == "free" or steered_valid(cr, rp, int(vehicle_type)):
        return rp
    from iamp.commonroad.ks import track
    from iamp.commonroad.ks_refine import (
        MAX_EVALUATIONS,
        PROBLEM_EVALUATIONS,
        STEP_OFFSETS,
        SteeredTrajectory,
        refine,
        retimed,
    )

    start = time.perf_counter()
    starts = [rp] if rp.trajectory is not None and rp.candidate is not None else []
    pm = _plan_road(cr, planner, engine=None, **kw)
    if pm.safe and pm.candidate is not None:
        starts.append(pm)
    left = PROBLEM_EVALUATIONS
    for p in starts:
        assert p.trajectory is not None and p.candidate is not None
        cand = p.candidate
        tracked = track(cr, p.trajectory, cand.steps, int(vehicle_type))
        lo, hi = cr.goal.elements[cand.element].steps if cand.goal_step >= 0 else (cand.steps, cand.steps)
        for off in STEP_OFFSETS:  # the starting solution's own final step, then earlier and later ones
            if not (lo <= cand.goal_step + off <= hi and cand.steps + off >= 2 and left > 0):
                continue
            c = dataclasses.replace(cand, steps=cand.steps + off, tf=(cand.steps + off) * cr.dt,
                                    goal_step=cand.goal_step + off)
            ks, used = refine(cr, retimed(tracked, c.steps), c, refine_checks(), min(MAX_EVALUATIONS, left))
            left -= used
            if ks is None:
                continue
            assert engine is not None
            traj = SteeredTrajectory(cr, ks, float(engine[3]), float(engine[4]))
            h, peak = _heading_and_peak(traj, c.tf)
            return RoadPlan(rp.planner, "optimal", c, traj, traj.cost(),
                            rp.solve_time_s + time.perf_counter() - start, list(p.imposed), [], "steered-refined",
                            rp.candidates_tried, None, h, peak, rp.plans_used, steered_goal=True, steered=ks)
    if starts and isinstance(engine, KSEngine):  # the vehicle met passed in the other order: behind it
        p = starts[0]
        ks, end, _, _ = plan_behind(cr, p, engine)
        if ks is not None and end is not None:
            traj = SteeredTrajectory(cr, ks, float(engine[3]), float(engine[4]))
            h, peak = _heading_and_peak(traj, end.tf)
            return RoadPlan(rp.planner, "optimal", end, traj, traj.cost(),
                            rp.solve_time_s + time.perf_counter() - start, [], [], "steered-refined",
                            rp.candidates_tried, None, h, peak, rp.plans_used, steered_goal=True, steered=ks)
    rp.solve_time_s += time.perf_counter() - start
    return rp


def steered_valid(cr: CommonRoadProblem, rp: RoadPlan, vehicle_type: int) -> bool:
    """Is the steered (``KS``) solution tracked from ``rp`` valid by iamp's own tests: the plan
    safe, its tracked solution reaching the goal (:attr:`RoadPlan.steered_goal`) and the tracked
    body clear of every recorded vehicle's box (:func:`body_overlap`, :data:`CHECK_BUFFER_M`)?"""
    if not rp.safe or rp.candidate is None or rp.trajectory is None or rp.steered_goal is False:
        return False
    from iamp.commonroad.ks import KSTrajectory, track

    ks = rp.steered
    if not (isinstance(ks, KSTrajectory) and ks.vehicle_type == vehicle_type
            and len(ks.states) == rp.candidate.steps + 1):
        ks = track(cr, rp.trajectory, rp.candidate.steps, vehicle_type)
    if rp.steered_goal is None and not steered_reaches_goal(cr, ks):
        return False
    return steered_clear(cr, ks.centre, ks.states[:, 4])


def steered_clear(cr: CommonRoadProblem, centre: FloatArray, heading: FloatArray) -> bool:
    """Is the steered body (world centres and headings at the time steps ``0..K``) clear of every
    recorded vehicle's box at the steps ``1..K`` (:func:`body_overlap`, grown by
    :data:`CHECK_BUFFER_M`)?  :func:`steered_meets` stopped at the first vehicle met."""
    return not steered_meets(cr, centre, heading, first=True)


#: Lateral schedules of the guesses that pass a vehicle behind it (:func:`behind_guesses`): the
#: start's lane held until the first fraction of the horizon, a lane boundary reached at the
#: second, where the ego is :data:`BEHIND_GAP_M` behind the vehicle at its speed.
BEHIND_SCHEDULES = ((0.8, 0.9), (0.75, 0.88), (0.8, 0.92))
#: The fraction of the horizon at which a behind guess leaves the boundary for its final offset.
BEHIND_LEAVE = 0.95
#: Gap kept behind the vehicle at a behind guess's waypoint, beyond the body's margin [m].
BEHIND_GAP_M = 0.3
#: Corridor passes per behind guess.
BEHIND_PASSES = 2
#: Corridor QP solves of every behind guess together (a count, never a time).
BEHIND_SOLVES = 8
#: Evaluations of the ``KS`` refinements from the behind plans together (a count, never a time).
BEHIND_EVALUATIONS = 300


def steered_meets(cr: CommonRoadProblem, centre: FloatArray, heading: FloatArray,
                  first: bool = False) -> list[tuple[int, Obstacle]]:
    """The recorded vehicles the steered body (world centres and headings at the steps ``0..K``)
    meets at the steps ``1..K`` (:func:`body_overlap` grown by :data:`CHECK_BUFFER_M`), each with
    the first step it meets it, earliest first; with ``first``, only the first vehicle found (in
    the scenario's order: :func:`steered_clear`)."""
    sd = np.asarray(cr.frame.to_road(np.asarray(centre, dtype=float)), dtype=float)
    phi = (np.asarray(heading, dtype=float) - np.asarray(cr.frame.heading(sd[:, 0]), dtype=float)
           + math.pi) % (2 * math.pi) - math.pi
    K = len(sd) - 1
    out: list[tuple[int, Obstacle]] = []
    for ob in cr.obstacles:
        idx = np.rint(ob.t / cr.dt).astype(int)
        ok = (idx >= 1) & (idx <= K)
        if ok.any():
            j = idx[ok]
            depth = body_overlap(sd[j, 0], sd[j, 1], phi[j], ob.s_lo[ok], ob.s_hi[ok], ob.d_lo[ok], ob.d_hi[ok],
                                 cr.ego_length / 2, cr.ego_width / 2, CHECK_BUFFER_M)
            if np.any(depth > 0):
                out.append((int(j[np.argmax(depth > 0)]), ob))
                if first:
                    return out
    out.sort(key=lambda e: e[0])
    return out


def behind_guesses(cr: CommonRoadProblem, cand: Candidate, ob: Obstacle) -> list[FloatArray]:
    """Guesses on the time steps for :func:`corridor_qp` that let ``ob`` pass and cross its lane
    behind it: laterally the start's nearest lane held (reached by 0.3 of the horizon) until the
    first fraction of a :data:`BEHIND_SCHEDULES` pair, a boundary between two lanes reached at
    the step nearest the second (the waypoint step) and left for ``cand``'s offset from
    :data:`BEHIND_LEAVE` of the horizon; along the road the free cubics joined at the waypoint
    step, :data:`BEHIND_GAP_M` behind ``ob``'s rear (beyond the body's margin) at ``ob``'s speed
    there (the lateral speed of the guess is left to the QP, which starts from ``cr.x0``).  Every schedule and
    boundary inside the road where ``ob`` is recorded around that step, least intruding first
    (:func:`_box_depth`)."""
    K, T = cand.steps, cand.tf
    t: FloatArray = np.arange(K + 1, dtype=np.float64) * cr.dt
    sx, sy = ego_margins(cr.ego_length, cr.ego_width, HEADING_GUESS_RAD)
    lanes = sorted(cr.lanes)
    home = min(lanes, key=lambda ln: abs(ln - cr.x0[2])) if lanes else cr.x0[2]
    bounds = [m for m in (0.5 * (a + b) for a, b in zip(lanes[:-1], lanes[1:]))
              if cr.road_y[0] + sy <= m <= cr.road_y[1] - sy]
    rec = {int(k): i for i, k in enumerate(np.rint(ob.t / cr.dt).astype(int))}
    boxes = _step_boxes(cr, K)
    scored: list[tuple[float, int, FloatArray]] = []
    a0, va0 = _smoothstep(t, 0.0, 0.3 * T)
    a2, va2 = _smoothstep(t, BEHIND_LEAVE * T, T)
    for f1, f2 in BEHIND_SCHEDULES:
        kw = int(round(f2 * K))
        if not (0 < kw < K and kw - 1 in rec and kw in rec and kw + 1 in rec):
            continue
        s_w = float(ob.s_lo[rec[kw]]) - sx - BEHIND_GAP_M
        v_w = max(float(ob.s_lo[rec[kw + 1]] - ob.s_lo[rec[kw - 1]]) / (2 * cr.dt), 0.0)
        a1, va1 = _smoothstep(t, f1 * T, kw * cr.dt)  # on the boundary at the waypoint
        for mid in bounds:
            w = (s_w, v_w, mid, 0.0)
            lon = ViaTrajectory(FreeTrajectory(kw * cr.dt, cr.x0, w),
                                FreeTrajectory(T - kw * cr.dt, w, (cand.s, cand.vs, cand.d, cand.vd)), kw * cr.dt, 0.0)
            S = _step_guess(lon, K, cr.dt)
            d = cr.x0[2] + (home - cr.x0[2]) * a0 + (mid - home) * a1 + (cand.d - mid) * a2
            vd = (home - cr.x0[2]) * va0 + (mid - home) * va1 + (cand.d - mid) * va2
            G = np.column_stack([S[:, 0], S[:, 1], d, vd])
            scored.append((_box_depth(cr, G, boxes), len(scored), G))
    scored.sort(key=lambda e: (e[0], e[1]))
    return [G for _, _, G in scored]


def plan_behind(cr: CommonRoadProblem, p: RoadPlan,
                engine: KSEngine) -> tuple[KSTrajectory | None, Candidate | None, int, int]:
    """A steered solution that passes the vehicle the steered solution of ``p`` meets first on its
    other side in time -- behind it -- where it meets it beside or ahead of it (its centre not
    behind the vehicle's rear): corridor plans (:func:`corridor_qp`, the steered limits
    ``engine``, the final state free inside the goal rows of ``p``'s goal state at the last step
    of its window that a final state of ``cr.candidates`` has, else at ``p``'s own step) from
    :func:`behind_guesses`, :data:`BEHIND_PASSES` passes each, re-centred; a plan clear of every
    vehicle by the body check (road edges left to the refinement) is tracked
    (:func:`iamp.commonroad.ks.track`) and its ``KS`` inputs optimised
    (:func:`iamp.commonroad.ks_refine.refine`, accepted only by the checker's own simulation,
    vehicles, road and goal).  At most :data:`BEHIND_SOLVES` QP solves and
    :data:`BEHIND_EVALUATIONS` evaluations.

    Returns
    -------
    (KSTrajectory or None, Candidate or None, int, int)
        The accepted solution and its final state, the QP solves and the evaluations spent.
    """
    from iamp.commonroad.goal import goal_rows
    from iamp.commonroad.ks import KSTrajectory, track
    from iamp.commonroad.ks_refine import MAX_EVALUATIONS, refine, retimed

    cand = p.candidate
    if p.trajectory is None or cand is None or cand.goal_step < 0 or cand.steps < 2:
        return None, None, 0, 0
    vehicle_type = int(engine.vehicle_type)
    tracked = p.steered
    if not (isinstance(tracked, KSTrajectory) and tracked.vehicle_type == vehicle_type
            and len(tracked.states) == cand.steps + 1):
        tracked = track(cr, p.trajectory, cand.steps, vehicle_type)
    met = steered_meets(cr, tracked.centre, tracked.states[:, 4])
    if not met:
        return None, None, 0, 0
    k, ob = met[0]
    i = int(np.argmin(np.abs(ob.t - k * cr.dt)))
    s_k = float(cr.frame.to_road(tracked.centre[k:k + 1])[0, 0])
    if s_k < float(ob.s_lo[i]):  # already behind it: not the other order
        return None, None, 0, 0
    # the last step of the goal window (the vehicle leaves room in the goal latest), where a
    # final state of the same goal state has it
    late = [c for c in cr.candidates if c.element == cand.element and c.goal_step > cand.goal_step]
    if late:
        cand = max(late, key=lambda c: (c.goal_step, -c.cost0))
    rows = goal_rows(cr.goal, cand, cr.x0)
    solves = used = 0
    for G in behind_guesses(cr, cand, ob):
        for _ in range(BEHIND_PASSES):
            if solves >= BEHIND_SOLVES:
                return None, None, solves, used
            solves += 1
            got = corridor_qp(cr, cand, G, rows, engine)
            if got is None:
                break
            G = _step_guess(got, cand.steps, cr.dt)
            if any(not h.obstacle.road_edge for h in intrusions(cr, got, cand.tf)):
                continue
            if used >= BEHIND_EVALUATIONS:
                return None, None, solves, used
            ks, n = refine(cr, retimed(track(cr, got, cand.steps, vehicle_type), cand.steps), cand,
                           refine_checks(), min(MAX_EVALUATIONS, BEHIND_EVALUATIONS - used))
            used += n
            if ks is not None:
                return ks, cand, solves, used
            break
    return None, None, solves, used


def _plan_road(cr: CommonRoadProblem, planner: str = DEFAULT_PLANNER, *, max_candidates: int = MAX_CANDIDATES,
               steps: int = STEPS, max_plans: int = MAX_PLANS, via: bool = True, search: bool = True,
               corridor: bool = True, engine: tuple[float, ...] | None = None) -> RoadPlan:
    """Plan ``cr`` with ``planner`` (a key of :data:`PLANNERS`; module docstring).

    ``engine`` (the steered model's longitudinal limit ``(a_max, v_switch)``, :func:`ks_engine`)
    bounds the corridor planner's acceleration along the road (:func:`corridor_qp`); None for a
    point-mass solution.

    With ``search`` (the default) the final states are the goal region's clear poses
    (:func:`search_final_states`); without it ``cr.candidates`` as given, those clear of the
    vehicles first (:func:`clear_final_states`) -- the interactive loop's choice (its verification
    was measured with those; with the searched ones it ran into a car in one scene, see
    ``docs/commonroad.md``).

    The search is bounded by counts, never by time: at most ``max_candidates`` final states
    (:func:`_candidate_order`) and ``max_plans`` calls of the iamp planner over all of them (each
    avoidance QP at most :data:`AVOID_MAX_SOLVES` QP solves), then, where none gave a safe plan,
    the two-stage search (:func:`_via`, :data:`VIA_MAX_PLANS` calls of its own; none when
    ``max_plans`` is 0 or ``via`` is false), so the same problem gives the same answer on any machine.  When no
    final state gives a safe plan, the reason says which part of the goal region was searched; a
    goal no final state of which the model can reach is refused (status ``unreachable``) naming
    the goal state's element.
    """
    if planner not in PLANNERS:
        raise ScenarioError(f"unknown planner {planner!r}; choose from {', '.join(PLANNERS)}", "planner")
    iamp_planner, constraint, active = PLANNERS[planner]
    start = time.perf_counter()
    if not cr.candidates:
        bad = cr.goal.unreachable(cr.x0, cr.dt)
        reason = ("; ".join(bad.values()) if bad else
                  "no final state verified inside every element of a goal state (" + cr.goal.describe() + ")")
        return RoadPlan(planner, "unreachable", None, None, None, time.perf_counter() - start,
                        reason=f"the goal cannot be reached: {reason}")
    best: RoadPlan | None = None
    found = search_final_states(cr) if search else None
    clear = found.candidates if found is not None else clear_final_states(cr, cr.candidates)
    gentle = [c for c in clear if _free_peak(cr, c) <= cr.a_max]  # the free plan within the friction circle
    order = _candidate_order(gentle or clear or cr.candidates, max_candidates)
    queue = list(order)
    heading = HEADING_GUESS_RAD
    edge_heading = abs(math.atan2(cr.x0[3], max(cr.x0[1], 1e-6)))  # the start's, raised when a plan turns more
    budget = [max_plans, QP_MAX_SOLVES, PMP_MAX_BOXES]  # planner calls, equality-QP solves, PMP boxes
    repairs = MAX_REPAIRS
    n_tried = 0
    tried: list[Candidate] = []
    steered_miss: RoadPlan | None = None  # a safe plan whose steered solution misses the goal
    while queue and n_tried < max_candidates:
        cand = queue.pop(0)  # with the planner calls spent, only the free plans of the rest are tried
        n_tried += 1
        tried.append(cand)
        sx, sy = ego_margins(cr.ego_length, cr.ego_width, heading)
        result = _plan_candidate(cr, cand, planner, iamp_planner, constraint, active, sx, sy, steps, budget,
                                 edge_margins(cr, edge_heading))
        # a second pass when the plan turned more than its margins assumed: the vehicles' margins
        # (any plan passing a vehicle), the road edges' (a plan passing an edge that is not safe)
        turned = result.max_heading_rad > heading + 1e-9 and any(i >= 0 for i, _ in result.imposed)
        at_edge = (not result.safe and result.max_heading_rad > edge_heading + 1e-9
                   and any(i < 0 for i, _ in result.imposed))
        if (result.trajectory is not None and (turned or at_edge)
                and _affords(budget, iamp_planner, constraint, 1, steps)):
            if turned:
                heading = result.max_heading_rad + 0.01
            if at_edge:
                edge_heading = result.max_heading_rad + 0.01
            sx, sy = ego_margins(cr.ego_length, cr.ego_width, heading)
            again = _plan_candidate(cr, cand, planner, iamp_planner, constraint, active, sx, sy, steps, budget,
                                    edge_margins(cr, edge_heading))
            # a second pass replaces a safe first only if safe, an unsafe one only if not worse
            if again.safe or (not result.safe and not _worse(again, result)):
                result = again
        if planner != "free" and not result.safe and _edges_only(result) and repairs > 0:
            repairs -= 1  # the lateral repair: one convex QP, counted apart from the planner calls
            result = _repaired(cr, cand, result)
        result.candidates_tried = n_tried
        if result.safe and result.within_limits(cr) and road_checked(cr, result):
            result = steer_at_edges(cr, result, engine)
            result.solve_time_s = time.perf_counter() - start
            result.plans_used = max_plans - budget[0]
            if result.steered_goal is not False:
                return result
            # the steered car misses the goal (its heading, the rear axle's, lags the plan's
            # direction of travel by the slip angle): the next final state, the corridor's
            # rear-axle heading rows, else this plan
            steered_miss = steered_miss or result
            continue
        if best is None or _worse(best, result):
            best = result
        if result.blocked is not None:  # end beside it instead: the same time, across the goal shape
            sx, sy = ego_margins(cr.ego_length, cr.ego_width, heading)
            other = cr.goal.across(cand, cr.x0, _beside(result.blocked, cr.x0, sx, sy,
                                                        edge_margins(cr, edge_heading)))
            if other is not None and all(abs(other.d - c.d) > 1e-3 or other.steps != c.steps for c in tried + queue):
                queue.insert(0, other)
    if best is None:
        assert steered_miss is not None
        best = steered_miss
    if via and active and planner != "free" and best.candidate is not None and max_plans > 0:
        staged = _via(cr, best, planner, iamp_planner, constraint, steps, heading, edge_heading)
        if staged is not None and road_checked(cr, staged):
            staged = steer_at_edges(cr, staged, engine)
            staged.candidates_tried = n_tried
            staged.solve_time_s = time.perf_counter() - start
            staged.plans_used = max_plans - budget[0] + staged.plans_used
            if staged.steered_goal is not False:
                return staged
            steered_miss = steered_miss or staged
    if corridor and planner != "free" and best.candidate is not None and max_plans > 0:
        wide = plan_corridor(cr, best, planner, heading, others=tried + clear, engine=engine)
        if wide is not None and road_checked(cr, wide):
            wide = steer_at_edges(cr, wide, engine)
            wide.candidates_tried = n_tried
            wide.solve_time_s = time.perf_counter() - start
            wide.plans_used = max_plans - budget[0]
            if wide.steered_goal is not False or steered_miss is None:
                return wide
    if steered_miss is not None:
        steered_miss.candidates_tried = n_tried
        steered_miss.solve_time_s = time.perf_counter() - start
        steered_miss.plans_used = max_plans - budget[0]
        return steered_miss
    steps_tried = sorted({c.steps for c in tried})
    if found is None:
        ends = f"{len(cr.candidates) - len(clear)} of {len(cr.candidates)} final states end inside a vehicle"
    else:
        ends = (f"{found.roots - found.roots_clear} of the {found.roots} cheapest final states of its steps and "
                f"pieces end inside a vehicle or off the road; {len(clear)} clear found in {found.solves} QP "
                "solve(s)" + (", the search's budget spent" if found.exhausted else ""))
    searched = (f"no safe plan found over the goal region searched: {n_tried} final state(s) at step(s) "
                f"{', '.join(map(str, steps_tried))} of {cr.goal.describe()} ({ends}); {max_plans - budget[0]} planner "
                f"call(s) of {max_plans}" + (f", {QP_MAX_SOLVES - budget[1]} QP solve(s) of {QP_MAX_SOLVES}"
                                              if iamp_planner == "qp" and constraint == "equality" else ""))
    if found is not None and not clear:
        bad = {**cr.goal.unreachable(cr.x0, cr.dt, _elapsed(cr)), **found.blocked}
        if len(bad) == len(cr.goal.elements) and not found.exhausted:
            searched = ("no valid final state exists: " + "; ".join(bad[i] for i in sorted(bad))
                        + f" (the body grown by {BUFFER_M} m from the vehicles, {EDGE_BUFFER_M} m from the road's "
                        "edge); " + searched)
    breach = best.limit_breach(cr)
    if best.trajectory is not None and not best.intrusions and breach is not None:
        best.status = "exceeds limits"
        best.reason = best.reason or breach
    last = (best.reason or "").replace(": no safe plan exists", ": no safe plan for this final state")
    best.reason = searched + (f"; the best attempt: {last}" if last else "")
    best.solve_time_s = time.perf_counter() - start
    best.plans_used = max_plans - budget[0]
    return best


#: Planner calls of the two-stage search (:func:`_via`), apart from :data:`MAX_PLANS`.
VIA_MAX_PLANS = 24
#: Waypoint steps of the two-stage search, as fractions of the horizon, in the order tried.
VIA_FRACTIONS = (0.5, 0.3, 0.7)
#: Extra gap kept between the ego and the vehicle at a waypoint behind or ahead of it [m].
VIA_GAP_M = 0.1


class ViaTrajectory:
    """Two plans joined at a waypoint: ``first`` on ``[0, t_m]``, ``second`` (its own clock) after."""

    def __init__(self, first: Trajectory, second: Trajectory, t_m: float, cost: float):
        self.first, self.second, self.t_m, self._cost = first, second, t_m, cost

    def _joined(self, t: npt.ArrayLike, name: str, width: int) -> FloatArray:
        """``first.<name>`` up to ``t_m``, ``second.<name>`` on its own clock after."""
        tt = np.atleast_1d(np.asarray(t, dtype=float))
        early = tt <= self.t_m
        out = np.empty((tt.size, width))
        if early.any():
            out[early] = np.asarray(getattr(self.first, name)(tt[early]), dtype=float)
        if (~early).any():
            out[~early] = np.asarray(getattr(self.second, name)(tt[~early] - self.t_m), dtype=float)
        return out

    def states(self, t: npt.ArrayLike) -> FloatArray:
        return self._joined(t, "states", 4)

    def inputs(self, t: npt.ArrayLike) -> FloatArray:
        return self._joined(t, "inputs", 2)

    def cost(self) -> float:
        """½∫|u|² of both plans (their own costs, summed)."""
        return self._cost


def window(cr: CommonRoadProblem, t_from: float, t_to: float,
           x_from: tuple[float, float, float, float]) -> CommonRoadProblem:
    """``cr`` on ``[t_from, t_to]`` with its clock starting at ``t_from`` from the state ``x_from``:
    every recorded box of that window, each vehicle's motion fitted again on it
    (:func:`~iamp.commonroad.convert.fit_motion`: a shorter window, a smaller residual, a shorter
    imposed box) and its lateral extent the one it has there (a lane changer that has finished its
    change is one lane wide)."""
    from iamp.commonroad.convert import fit_motion

    def cut(ob: Obstacle) -> Obstacle | None:
        keep = (ob.t >= t_from - 1e-9) & (ob.t <= t_to + 1e-9)
        if not keep.any():
            return None
        t = ob.t[keep] - t_from
        cubic, resid, half = (ob.cubic, ob.fit_residual_m, ob.half_length) if ob.road_edge else fit_motion(
            t, ob.s_lo[keep], ob.s_hi[keep])
        return dataclasses.replace(ob, t=t, s_lo=ob.s_lo[keep], s_hi=ob.s_hi[keep], d_lo=ob.d_lo[keep],
                                   d_hi=ob.d_hi[keep], cubic=cubic, half_length=half, fit_residual_m=resid)

    obstacles = [o for o in (cut(ob) for ob in cr.obstacles) if o is not None]
    edges = [o for o in (cut(ob) for ob in cr.road_edges) if o is not None]
    return dataclasses.replace(cr, x0=x_from, obstacles=obstacles, road_edges=edges, candidates=[])


def _waypoints(cr: CommonRoadProblem, ob: Obstacle, cand: Candidate, sx: float,
               sy: float) -> list[tuple[int, tuple[float, float, float, float]]]:
    """Waypoints around ``ob`` at the steps :data:`VIA_FRACTIONS` of the horizon (the middle
    first): behind and ahead of it in its lane, beside it in the lanes either side, at its speed;
    those inside the road, clear of every vehicle and reachable in both stages; by step in that
    order and, at each, cheapest unconstrained two-stage cost first."""
    out = []
    for frac in VIA_FRACTIONS:
        k_m = int(round(cand.steps * frac))
        if 0 < k_m < cand.steps:
            out += _waypoints_at(cr, ob, cand, sx, sy, k_m)
    return out


def _waypoints_at(cr: CommonRoadProblem, ob: Obstacle, cand: Candidate, sx: float, sy: float,
                  k_m: int) -> list[tuple[int, tuple[float, float, float, float]]]:
    """The waypoints of :func:`_waypoints` at step ``k_m``."""
    from iamp.commonroad.convert import fit_motion, unconstrained_cost
    from iamp.commonroad.goal import axis_reachable

    t_m = k_m * cr.dt
    j = int(np.argmin(np.abs(ob.t - t_m)))
    if ob.t.size < 2 or abs(ob.t[j] - t_m) > 1e-6:
        return []
    xs = 0.5 * float(ob.s_lo[j] + ob.s_hi[j])
    yv = 0.5 * float(ob.d_lo[j] + ob.d_hi[j])
    # the gap the corners of both stages see: each stage's fitted motion and half length at t_m
    gap = 0.0
    vs = 0.0
    for part, at in ((ob.t <= t_m + 1e-9, t_m), (ob.t >= t_m - 1e-9, 0.0)):
        tt = ob.t[part] - (0.0 if at else t_m)
        cubic, _, half = fit_motion(tt, ob.s_lo[part], ob.s_hi[part])
        gap = max(gap, half + abs(float(np.polynomial.polynomial.polyval(at, cubic)) - xs))
        if not at:
            vs = float(np.polynomial.polynomial.polyval(0.0, np.polynomial.polynomial.polyder(cubic))) if len(
                cubic) > 1 else 0.0
    gap += sx + VIA_GAP_M
    above = [ln for ln in cr.lanes if ln > yv + 2.0]
    below = [ln for ln in cr.lanes if ln < yv - 2.0]
    points = [(xs - gap, yv), (xs + gap, yv)]
    if above:
        points.append((xs, min(above)))
    if below:
        points.append((xs, max(below)))
    out = []
    T1, T2 = t_m, cand.tf - t_m
    for s_m, d_m in points:
        w = (s_m, max(vs, 0.0), d_m, 0.0)
        if not (cr.road_y[0] + sy <= d_m <= cr.road_y[1] - sy):
            continue
        if not clear_final_states(cr, [Candidate(k_m, t_m, w[0], w[1], w[2], 0.0, 0.0)]):
            continue
        ok = all(axis_reachable(p0, v0, pf, vf, T, cr.a_max) for (p0, v0, pf, vf, T) in (
            (cr.x0[0], cr.x0[1], w[0], w[1], T1), (cr.x0[2], cr.x0[3], w[2], w[3], T1),
            (w[0], w[1], cand.s, cand.vs, T2), (w[2], w[3], cand.d, cand.vd, T2)))
        if not ok:
            continue
        cost = (unconstrained_cost(T1, cr.x0[0], cr.x0[1], w[0], w[1])
                + unconstrained_cost(T1, cr.x0[2], cr.x0[3], w[2], w[3])
                + unconstrained_cost(T2, w[0], w[1], cand.s, cand.vs)
                + unconstrained_cost(T2, w[2], w[3], cand.d, cand.vd))
        out.append((cost, k_m, w))
    out.sort(key=lambda e: e[0])
    return [(k, w) for _, k, w in out]


def _via(cr: CommonRoadProblem, best: RoadPlan, planner: str, iamp_planner: str, constraint: str, steps: int,
         heading: float, edge_heading: float) -> RoadPlan | None:
    """The two-stage search: where no final state gave a safe plan, pass the vehicle in the way
    through a waypoint around it (:func:`_waypoints`), each stage planned by the active set
    (the corner model allows one crossing per vehicle and stage, so a vehicle the ego must pass
    behind and then beside, or overtake in its lane, is two crossings), with at most
    :data:`VIA_MAX_PLANS` planner calls; the joined plan is judged by the body check."""
    cand = best.candidate
    assert cand is not None
    by_id = {ob.obstacle_id: ob for ob in cr.obstacles}
    seen: list[int] = []
    for ob in ([best.blocked] if best.blocked is not None else []) + [i.obstacle for i in best.intrusions] + [
            by_id[i] for i, _ in best.imposed if i in by_id]:
        if not ob.road_edge and ob.obstacle_id not in seen:
            seen.append(ob.obstacle_id)
    budget = [VIA_MAX_PLANS, QP_MAX_SOLVES, PMP_MAX_BOXES]
    sx, sy = ego_margins(cr.ego_length, cr.ego_width, heading)
    edge = edge_margins(cr, edge_heading)
    for oid in seen[:2]:
        for k_m, w in _waypoints(cr, by_id[oid], cand, sx, sy):
            if budget[0] < 2:
                return None
            t_m = k_m * cr.dt
            first_c = Candidate(k_m, t_m, w[0], w[1], w[2], 0.0, w[3])
            first = _plan_candidate(window(cr, 0.0, t_m, cr.x0), first_c, planner, iamp_planner, constraint, True, sx,
                                    sy, steps, budget, edge)
            if not first.safe or first.trajectory is None:
                continue
            later = window(cr, t_m, cand.tf, w)
            second_c = Candidate(cand.steps - k_m, cand.tf - t_m, cand.s, cand.vs, cand.d, 0.0, cand.vd,
                                 cand.element, cand.piece)
            second = _plan_candidate(later, second_c, planner, iamp_planner, constraint, True, sx, sy, steps, budget,
                                     edge)
            if not second.safe or second.trajectory is None:
                continue
            joined = ViaTrajectory(first.trajectory, second.trajectory, t_m,
                                   float(first.cost or 0.0) + float(second.cost or 0.0))
            hits = intrusions(cr, joined, cand.tf)
            h, peak = _heading_and_peak(joined, cand.tf)
            if hits or peak > cr.a_max:
                continue
            out = RoadPlan(planner, "optimal", cand, joined, joined.cost(), 0.0, first.imposed + second.imposed, [],
                           "via", 0, None, h, peak)
            out.plans_used = VIA_MAX_PLANS - budget[0]
            return out
    return None


#: QP solves of the corridor planner per problem (:func:`plan_corridor`; a count, never a time).
CORRIDOR_MAX_SOLVES = 30
#: Final states the corridor planner tries (``best``'s, then the goal's clear ones in order).
CORRIDOR_FINAL_STATES = 4
#: Convex passes per guess of the corridor planner (each re-centred on the last pass's plan).
CORRIDOR_PASSES = 4
#: A pass whose plan is not this much less deep in the vehicles than the last ends its guess.
CORRIDOR_PROGRESS = 0.8
#: How far the corridor plan's position may move from its guess at each step, per pass [m]
#: (the road corridor's narrowest bound is taken over this reach).
CORRIDOR_REACH_M = 6.0
#: Least bound on ``|tan φ|`` the corridor plan's steps get (the guess's own plus
#: :data:`CORRIDOR_TAN_SLACK` where it turns more), at most :data:`REPAIR_TAN_CAP`.
CORRIDOR_MIN_TAN = 0.1
CORRIDOR_TAN_SLACK = 0.05
#: The final step's bound on ``|tan φ|`` beyond the guess's own, with the final state free in the goal.
CORRIDOR_END_TAN_SLACK = 0.01
#: Share of the friction circle the corridor plan's inputs use: the world's accelerations differ
#: from the road frame's by the frame's curvature terms (a plan at 0.999 of it was infeasible by
#: CommonRoad's PM test on the US-101 bend of ``USA_US101-6``).
CORRIDOR_ACCEL_SHARE = 0.98
#: Cost of a metre of a side row's slack in the corridor QP (the rows are soft so that a pass
#: whose sides the guess chose badly still moves toward a plan whose sides are consistent; the
#: plan is accepted only by the body check).
CORRIDOR_SLACK_WEIGHT = 1e3
#: Cost of a metre of the road's slack (nearly hard: only a start at the road's edge needs it).
CORRIDOR_ROAD_SLACK_WEIGHT = 1e5
#: A box farther than this from the guess (beyond the body's margins) at a step gives no row [m].
CORRIDOR_NEAR_M = 8.0
#: Share of the steered model's engine limit and friction circle the corridor plan uses
#: (:func:`corridor_qp`): below the KS tracker's own input margin
#: (:data:`iamp.commonroad.ks.INPUT_MARGIN`), leaving its feedback room.
CORRIDOR_ENGINE_SHARE = 0.9
#: How far a point of the body's side can lie along the road from the step's position plus its
#: offset (the body turned by its heading: ``W/2 sin φ`` and ``L/2 (1 - cos φ)``) [m].
CORRIDOR_CORNER_M = 0.15
#: Share of the steered model's steering rate the corridor plan's change of lateral
#: acceleration uses (:func:`corridor_qp`): the rest covers the terms the row neglects (the
#: speed's change, the heading) and the tracker's feedback.
CORRIDOR_STEER_SHARE = 0.5


class KSEngine(NamedTuple):
    """The ``KS`` limits of a vehicle type the plan keeps (:func:`ks_engine`); a tuple, indexed as
    ``(a_max, v_switch, steering_rate_max, wheelbase, b, vehicle_type)``."""

    a_max: float
    v_switch: float
    steering_rate_max: float
    wheelbase: float
    b: float
    vehicle_type: int


def ks_engine(vehicle_type: int = 2) -> KSEngine:
    """The ``KS`` model's limits of a CommonRoad vehicle type that the corridor plan keeps
    (:func:`corridor_qp`): ``(a_max, v_switch, steering_rate_max, wheelbase, b)`` (above
    ``v_switch`` the acceleration is at most ``a_max v_switch / v``; the steering angle turns at
    most ``steering_rate_max``), from the parameters :mod:`iamp.commonroad.ks` tracks with, and
    the vehicle type itself (with it :func:`plan` checks the steered car at the road's edges,
    :func:`steer_at_edges`).

    Parameters
    ----------
    vehicle_type : int
        CommonRoad vehicle type (1, 2 or 3).

    Returns
    -------
    KSEngine
        ``a_max`` [m/s²], ``v_switch`` [m/s], the steering rate's bound [rad/s], the
        wheelbase ``a + b`` [m], the distance ``b`` from the centre to the rear axle [m] and the
        vehicle type.

    Raises
    ------
    iamp.ScenarioError
        A vehicle type without ``KS`` parameters.
    """
    from iamp.commonroad.ks import _params

    p = _params(vehicle_type)
    lon = p.longitudinal
    return KSEngine(float(lon.a_max), float(lon.v_switch), float(p.steering.v_max), float(p.a + p.b), float(p.b),
                    int(vehicle_type))


def engine_tangent(a_max: float, v_switch: float, v0: float) -> tuple[float, float]:
    r"""A linear row :math:`a + c\,v \le e` that implies the engine limit
    :math:`a \le a_{max} v_{switch} / v` at every speed :math:`v > 0`: the tangent of the convex
    :math:`f(v) = a_{max} v_{switch}/v` at :math:`v_0` (at least :math:`v_{switch}`),
    :math:`f(v_0) + f'(v_0)(v - v_0) = a_{max} v_{switch}(2/v_0 - v/v_0^2)`, lies below
    :math:`f` at every speed (sufficient, never optimistic; exact at :math:`v_0`).  With the row
    :math:`a \le a_{max}` it implies :math:`a \le \min(a_{max}, f(v))` (the set under
    :math:`f` is not convex, so one tangent per row, not their maximum).

    Parameters
    ----------
    a_max, v_switch : float
        The limit [m/s²] and the speed above which it falls [m/s].
    v0 : float
        The speed the tangent touches at [m/s] (raised to ``v_switch``).

    Returns
    -------
    (c, e) : tuple of float
        The row's speed coefficient and right-hand side.
    """
    v0 = max(float(v0), float(v_switch))
    return a_max * v_switch / v0**2, 2.0 * a_max * v_switch / v0


class StepTrajectory:
    """A plan whose inputs are held constant on each time step ``dt`` (zero-order hold on both
    axes, the point-mass model CommonRoad's ``PM`` checker integrates), from ``x0``."""

    def __init__(self, x0: tuple[float, float, float, float], dt: float, u: FloatArray):
        self.dt = dt
        self.u = np.asarray(u, dtype=float).reshape(-1, 2)
        n = self.u.shape[0]
        self.p = np.empty((n + 1, 2))
        self.v = np.empty((n + 1, 2))
        self.p[0], self.v[0] = (x0[0], x0[2]), (x0[1], x0[3])
        for k in range(n):
            self.p[k + 1] = self.p[k] + self.v[k] * dt + 0.5 * self.u[k] * dt * dt
            self.v[k + 1] = self.v[k] + self.u[k] * dt

    def _at(self, t: npt.ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
        tt = np.atleast_1d(np.asarray(t, dtype=float))
        k = np.clip(np.floor(tt / self.dt + 1e-9).astype(int), 0, self.u.shape[0] - 1)
        tau = (tt - k * self.dt)[:, None]
        u = self.u[k]
        return self.p[k] + self.v[k] * tau + 0.5 * u * tau**2, self.v[k] + u * tau, u

    def states(self, t: npt.ArrayLike) -> FloatArray:
        p, v, _ = self._at(t)
        return np.stack([p[:, 0], v[:, 0], p[:, 1], v[:, 1]], axis=1)

    def inputs(self, t: npt.ArrayLike) -> FloatArray:
        return self._at(t)[2]

    def cost(self) -> float:
        """½∫|u|² exactly (the inputs are constant on each step)."""
        return float(0.5 * np.sum(self.u**2) * self.dt)


def _step_guess(guess: Trajectory, K: int, dt: float) -> FloatArray:
    """``guess``'s states on the time steps ``0..K``, shape ``(K+1, 4)``."""
    return np.asarray(guess.states(np.arange(K + 1) * dt), dtype=float)


def corridor_sides(cr: CommonRoadProblem, G: FloatArray, sx: FloatArray, sy: FloatArray,
                   last: int | None = None) -> list[tuple[int, int, float, float]]:
    r"""The side of every recorded vehicle's box the corridor plan keeps the ego's body on, at
    every time step ``k = 1..last`` (``K - 1`` by default) where the box lies within
    :data:`CORRIDOR_NEAR_M` of the guess ``G`` (beyond the body's margins): the side on which the
    guess is farthest outside it (least deep inside it where it intrudes) -- ahead
    (:math:`s_k \ge s^+ + S_{x,k}`), behind, above (:math:`d_k \ge d^+ + S_{y,k}`) or below.
    Each vehicle enters at the steps it has a recorded box near the ego, with the box of that
    step: a lane changer occupies each lane over the steps it is in it, and a vehicle in a lane
    the ego crosses is met where it is.  (The road-edge boxes are the road's bounds of
    :func:`corridor_qp`; by default the final step is left to the final-state search, whose
    state is clear.)

    Parameters
    ----------
    cr : CommonRoadProblem
    G : (K+1, 4) array
        The guess's states on the time steps.
    sx, sy : (K+1,) arrays
        The body's margins at each step (along the road; across it without the heading's share,
        which :func:`corridor_qp` adds in its rows).
    last : int, optional
        The last step given rows.

    Returns
    -------
    list of (k, axis, sign, bound)
        Rows ``sign * x_k[axis] <= sign * bound``... written as ``sign * (x - bound) >= 0``:
        axis 0 is ``s``, 2 is ``d``; ``sign = +1`` keeps the ego at or above ``bound``.
    """
    K = G.shape[0] - 1
    last = K - 1 if last is None else last
    rows: list[tuple[int, int, float, float]] = []
    ks = np.arange(1, last + 1)
    s, d = G[ks, 0], G[ks, 2]
    vehicles = [o for o in cr.all_obstacles if not o.road_edge or o.hole]  # a hole is passed on a side too
    B = _step_boxes(SimpleNamespace(obstacles=vehicles, dt=cr.dt), K)[:, ks, :]  # type: ignore[arg-type]
    bounds = np.stack([B[1] + sx[ks, None], B[0] - sx[ks, None], B[3] + sy[ks, None], B[2] - sy[ks, None]])
    sep = np.stack([s[:, None] - bounds[0], bounds[1] - s[:, None], d[:, None] - bounds[2], bounds[3] - d[:, None]])
    sep = np.where(np.isnan(sep), -np.inf, sep)
    side = np.argmax(sep, axis=0)  # 0 ahead, 1 behind, 2 above, 3 below
    best = np.max(sep, axis=0)
    near = np.isfinite(best) & (best <= CORRIDOR_NEAR_M) & ~np.isnan(B[0])
    axes, signs = (0, 0, 2, 2), (1.0, -1.0, 1.0, -1.0)
    for i in range(len(vehicles)):
        for r in np.flatnonzero(near[:, i]):
            c = int(side[r, i])
            rows.append((int(ks[r]), axes[c], signs[c], float(bounds[c, r, i])))
    return rows


class SparseRows:
    """Linear rows ``sum_c v_c x_c (op) rhs`` gathered one at a time as a sparse matrix's triplets
    (:func:`corridor_qp`'s equality rows and its inequality rows are two of these)."""

    def __init__(self) -> None:
        self.r: list[int] = []
        self.c: list[int] = []
        self.v: list[float] = []
        self.rhs: list[float] = []

    def __len__(self) -> int:
        return len(self.rhs)

    def add(self, cols: list[tuple[int, float]], rhs: float) -> None:
        """Append the row with coefficients ``cols`` (column, value) and right-hand side ``rhs``."""
        r = len(self.rhs)
        for c, v in cols:
            self.r.append(r)
            self.c.append(c)
            self.v.append(v)
        self.rhs.append(rhs)

    def matrix(self, n: int) -> Any:
        """The rows as a ``len(self) x n`` sparse matrix."""
        from scipy import sparse

        return sparse.coo_matrix((self.v, (self.r, self.c)), shape=(len(self.rhs), n))


def corridor_qp(cr: CommonRoadProblem, cand: Candidate, G: FloatArray,
                goal_rows: tuple[FloatArray, FloatArray] | None = None,
                engine: tuple[float, ...] | None = None) -> StepTrajectory | None:
    r"""One convex pass of the corridor planner: the minimum-energy zero-order-hold plan on the
    time steps from ``cr.x0`` to ``cand`` that keeps, at every step, the body on the side of every
    box :func:`corridor_sides` chose from the guess ``G``, inside the road corridor's narrowest
    bounds over its reach, its heading within a bound and its inputs in the friction circle.

    The states are affine in the inputs :math:`u_k = (u_{s,k}, u_{d,k})`; minimises
    :math:`\tfrac12\sum_k |u_k|^2 \Delta t` subject to: the final state ``cand`` exactly;
    :math:`|(u_{s,k},\ u_{d,k} + \kappa \dot s_k^2)| \le` :data:`CORRIDOR_ACCEL_SHARE` :math:`a_{max}`
    (a second-order cone per step: the world's acceleration on a bend, :math:`\kappa` and
    :math:`\dot s_k` the guess's); :math:`|\dot d_k| \le \tau_k \dot s_k`
    with :math:`\tau_k` the guess's own :math:`|\tan\varphi|` plus :data:`CORRIDOR_TAN_SLACK`, at
    least :data:`CORRIDOR_MIN_TAN`, at most :data:`REPAIR_TAN_CAP` (so the body's extents along
    and across the road are at most :math:`S_{x,k}, S_{y,k}` of
    :func:`~iamp.commonroad.convert.ego_margins` at :math:`\arctan\tau_k`); the speed along the
    road within the problem's range; :math:`|s_k - G_{k,s}| \le` :data:`CORRIDOR_REACH_M` and
    :math:`d^-_k + S^e_{y,k} \le d_k \le d^+_k - S^e_{y,k}` with :math:`d^\pm_k` the corridor's
    narrowest over the body's reach (``cr.road_y`` where it has none).

    Parameters
    ----------
    cr : CommonRoadProblem
    cand : Candidate
        The final state (its step count ``cand.steps``).
    G : (K+1, 4) array
        The guess on the time steps.
    goal_rows : (A, b), optional
        Rows ``A z <= b`` of the goal state's final state ``z = (s, vs, d, vd)``
        (:func:`~iamp.commonroad.goal.goal_rows`): the final state is then free inside them, with
        the final step's own rows, instead of ``cand``'s state.
    engine : (a_max, v_switch), optional
        The steered model's longitudinal limit (:func:`ks_engine`): the acceleration along the
        world speed's direction, at most :math:`u_{s,k} + \tau_k |u_{d,k}|` (the across-road share
        :math:`|\dot d|/v \le \tau_k`), is kept below :data:`CORRIDOR_ENGINE_SHARE` of
        :math:`a_{max}` and of the limit's tangent at the guess's world speed
        (:func:`engine_tangent`) at the step's both end speeds, each speed taken as an upper bound
        on the world speed, :math:`v \le \dot s\,(1 + |\kappa|(|d| + R))\sqrt{1 + \tau_k^2}`
        (:math:`\kappa` at the guess, :math:`R` its reach; the tangent falls with the speed):
        linear, and sufficient at any speed since a tangent lies below the convex limit (nearly
        exact near the guess's speed, which each pass re-centres); the friction circle's
        radius is then the same share of :math:`a_{max}`.  With a steering-rate bound
        :math:`\dot\delta_{max}` and wheelbase :math:`l` (``engine[2:4]``, :func:`ks_engine`): the
        steered car's curvature :math:`\kappa = \tan\delta / l` changes at least as fast as
        :math:`\dot\delta / l` allows, so its lateral acceleration :math:`v^2\kappa` by at most
        about :math:`v^2\dot\delta_{max}/l` per second; the rows
        :math:`|(u_{d,k+1} + b_{k+1}) - (u_{d,k} + b_k)| \le`
        :data:`CORRIDOR_STEER_SHARE` :math:`\dot\delta_{max} v^2 \Delta t / l` (:math:`b_k`
        the bend's :math:`\kappa_{road}\dot s^2`), with :math:`v^2` replaced by its tangent at the
        guess's speed :math:`2 v_g \dot s_j - v_g^2 \le \dot s_j^2` at each of the three speeds
        :math:`j = k, k+1, k+2` the two steps span (linear, and sufficient at any speed), keep
        the plan's lateral jerk within it.  None
        (a point-mass solution): no such rows, the radius :data:`CORRIDOR_ACCEL_SHARE` of ``cr.a_max``.

    Returns
    -------
    StepTrajectory or None
        None when the QP is infeasible or fails.
    """
    import clarabel
    from scipy import sparse

    K, dt = cand.steps, cr.dt
    if K < 2:
        return None
    L, W = cr.ego_length, cr.ego_width
    vs_g = np.maximum(G[:, 1], 0.5)
    tau = np.clip(np.abs(G[:, 3]) / vs_g + CORRIDOR_TAN_SLACK, CORRIDOR_MIN_TAN, REPAIR_TAN_CAP)
    tau[0] = max(tau[0], abs(cr.x0[3]) / max(cr.x0[1], 0.5))
    # the final heading is the goal's (or cand's): the band about the guess's own, not the least bound
    # (at least cand's own: a guess that ends straight, as the lane schedules do, would shut out a
    # goal whose orientation interval lies off the lane's heading)
    tau[K] = max(abs(G[K, 3]) / vs_g[K], abs(cand.vd) / max(cand.vs, 0.5)) + (
        CORRIDOR_END_TAN_SLACK if goal_rows is not None else 0.0)
    phi = np.arctan(tau)
    sx = np.array([ego_margins(L, W, float(min(p, math.atan(W / L))), BUFFER_M)[0] for p in phi])
    # across the road the body reaches L/2 sin φ + W/2 cos φ <= W/2 + L/2 |tan φ|, tan φ = vd / vs
    # with vs the guess's (re-centred every pass): W/2 and the buffer here, the heading term in the rows
    sy = np.full(K + 1, W / 2 + BUFFER_M)
    edge_sy = np.full(K + 1, W / 2 + REPAIR_EDGE_BUFFER_M)
    lever = L / 2 / vs_g
    # points along the body's side (rear corner to front corner) and how far a corner can lie beyond
    # the linear bound d + o tan φ + W/2 at the step's heading bound
    offsets = np.linspace(-L / 2, L / 2, 5)
    edges = np.array([(float(ob.s_lo[0]), float(ob.s_hi[0]), float(ob.d_lo[0]), float(ob.d_hi[0]))
                      for ob in cr.road_edges if not ob.hole], dtype=float).reshape(-1, 4)
    excess = np.array([corner_excess(L / 2, W / 2, float(x)) + W / 2 * (math.sqrt(1.0 + x * x) - 1.0)
                       for x in tau])
    # how far a step's position may move from the guess's: both leave x0 within the friction circle
    move = np.minimum(CORRIDOR_REACH_M, cr.a_max * (np.arange(K + 1) * dt) ** 2 + 0.05)
    # where a step's position can be: within move of the guess, and within the friction circle
    # from the start's coasting (|u_s| <= a_max): the road's bounds are taken over this reach
    t_steps = np.arange(K + 1) * dt
    coast = cr.x0[0] + cr.x0[1] * t_steps
    s_min = np.maximum(G[:, 0] - move, coast - 0.5 * cr.a_max * t_steps**2)
    s_max = np.minimum(G[:, 0] + move, coast + 0.5 * cr.a_max * t_steps**2)
    # variables: the states X_k = (s, vs, d, vd) of steps 0..K, then the inputs U_k = (us, ud) of steps 0..K-1
    last = K - 1 if goal_rows is None else K
    sides = corridor_sides(cr, G, sx, sy, last)
    nx = 4 * (K + 1)
    n_u = nx + 2 * K
    n_road = n_u + len(sides)  # the road's slacks: two per step (its upper, its lower bound)
    n = n_road + 2 * last  # the states, the inputs, one slack per side row, the road's
    eqs, les = SparseRows(), SparseRows()  # sum v x_c == rhs, sum v x_c <= rhs
    eq, le = eqs.add, les.add
    for i, x in enumerate(cr.x0):
        eq([(i, 1.0)], float(x))
    if goal_rows is None:
        for i, x in enumerate((cand.s, cand.vs, cand.d, cand.vd)):
            eq([(4 * K + i, 1.0)], float(x))
    for k in range(K):
        for axis in (0, 1):  # p' = p + v dt + u dt²/2, v' = v + u dt
            p, v, u = 4 * k + 2 * axis, 4 * k + 2 * axis + 1, nx + 2 * k + axis
            eq([(p + 4, 1.0), (p, -1.0), (v, -dt), (u, -0.5 * dt * dt)], 0.0)
            eq([(v + 4, 1.0), (v, -1.0), (u, -dt)], 0.0)
    v_lo, v_hi = cr.speed_range
    y_lo, y_hi = cr.road_y
    grid = lo = hi = None
    if cr.corridor is not None:
        grid, lo, hi = cr.corridor
    if goal_rows is not None:
        for a, rhs in zip(*goal_rows):
            le([(4 * K + i, float(a[i])) for i in range(4) if a[i] != 0.0], float(rhs))
    for k in range(1, last + 1):
        s_, vs_, d_, vd_ = 4 * k, 4 * k + 1, 4 * k + 2, 4 * k + 3
        le([(vd_, 1.0), (vs_, -float(tau[k]))], 0.0)  # the heading bound
        le([(vd_, -1.0), (vs_, -float(tau[k]))], 0.0)
        le([(vs_, -1.0)], -max(v_lo, 0.1))
        le([(vs_, 1.0)], v_hi)
        le([(s_, 1.0)], float(G[k, 0] + move[k]))  # the reach about the guess
        le([(s_, -1.0)], -float(G[k, 0] - move[k]))
        # the body's sides at points along it (its corners included) below the road's bound near
        # each point: d + o tan φ + W/2 (+ the corner's excess beyond the linear bound) per side
        up, down = n_road + 2 * k - 2, n_road + 2 * k - 1  # soft: a start at the edge touches it
        for o in offsets:
            # the point's reach along the road: its step's (about the guess and from the start
            # within the friction circle), and CORRIDOR_CORNER_M for the corner's own shift
            a, b_ = s_min[k] + o - CORRIDOR_CORNER_M, s_max[k] + o + CORRIDOR_CORNER_M
            lean = o / float(vs_g[k])
            if grid is not None and lo is not None and hi is not None:
                lines = _edge_line(grid, hi, a, b_, True), _edge_line(grid, lo, a, b_, False)
                if all(np.isfinite(v) for ln in lines for v in ln):  # the road's bounds as lines in s
                    for (v0, m), sg, slack in zip(lines, (1.0, -1.0), (up, down)):
                        # sg (d + lean vd) <= sg (v0 + m (s + o - a)) - |m| CORRIDOR_CORNER_M - margins
                        le([(d_, sg), (vd_, sg * lean), (s_, -sg * m), (slack, -1.0)],
                           sg * (v0 + m * (o - a)) - abs(m) * CORRIDOR_CORNER_M - edge_sy[k] - excess[k])
                    continue
            h_b, l_b = y_hi, y_lo
            if grid is not None and lo is not None and hi is not None:
                h, lw = _narrowest(grid, hi, a, b_, True), _narrowest(grid, lo, a, b_, False)
                h_b = min(h_b, h) if np.isfinite(h) else h_b
                l_b = max(l_b, lw) if np.isfinite(lw) else l_b
            near = edges[(edges[:, 0] <= b_) & (edges[:, 1] >= a)]
            # the road-edge boxes (each beyond one side of the road): the road's bound where they lie
            below = near[near[:, 2] + near[:, 3] < y_lo + y_hi]
            above = near[near[:, 2] + near[:, 3] >= y_lo + y_hi]
            h_b = min(h_b, float(above[:, 2].min())) if above.size else h_b
            l_b = max(l_b, float(below[:, 3].max())) if below.size else l_b
            le([(d_, 1.0), (vd_, lean), (up, -1.0)], float(h_b - edge_sy[k] - excess[k]))
            le([(d_, -1.0), (vd_, -lean), (down, -1.0)], -float(l_b + edge_sy[k] + excess[k]))
        le([(up, -1.0)], 0.0)
        le([(down, -1.0)], 0.0)
    if engine is not None:  # the steered model's engine: us + tau |ud| <= share * a_max and the tangent at g vs
        kap = np.abs(np.asarray(cr.frame.curvature(G[:, 0]), dtype=float))
        grow = (1.0 + kap * (np.abs(G[:, 2]) + CORRIDOR_REACH_M)) * np.sqrt(1.0 + tau**2)
        for k in range(K):
            us_, ud_ = nx + 2 * k, nx + 2 * k + 1
            g, t_k = float(max(grow[k], grow[k + 1])), float(max(tau[k], tau[k + 1]))
            for pm in (-1.0, 1.0):
                le([(us_, 1.0), (ud_, pm * t_k)], CORRIDOR_ENGINE_SHARE * engine[0])
                for j in (k, k + 1):  # the tangent at the guess's world speed (re-centred each pass)
                    c, e = engine_tangent(engine[0], engine[1], g * float(G[j, 1]))
                    le([(us_, 1.0), (ud_, pm * t_k), (4 * j + 1, CORRIDOR_ENGINE_SHARE * c * g)],
                       CORRIDOR_ENGINE_SHARE * e)
    if engine is not None and len(engine) >= 4:  # the steering rate: the lateral jerk's bound
        bend_k = np.asarray(cr.frame.curvature(G[:K, 0]), dtype=float) * G[:K, 1] ** 2
        rate = CORRIDOR_STEER_SHARE * engine[2] * dt / engine[3]
        for k in range(K - 1):
            db = float(bend_k[k + 1] - bend_k[k])
            for j in (k, k + 1, k + 2):  # v² >= its tangent at the guess's speed: 2 v_g v - v_g², at each end speed
                v_g = float(max(G[j, 1], 0.5))
                le([(nx + 2 * k + 3, 1.0), (nx + 2 * k + 1, -1.0), (4 * j + 1, -2.0 * rate * v_g)],
                   -rate * v_g**2 - db)
                le([(nx + 2 * k + 3, -1.0), (nx + 2 * k + 1, 1.0), (4 * j + 1, -2.0 * rate * v_g)],
                   -rate * v_g**2 + db)
        if goal_rows is not None and len(engine) >= 5:
            # the goal's heading rows (a_v vs + a_d vd <= r) for the rear axle's heading too: it
            # leaves the centre's direction of travel by the slip angle, tan ψ ~ (vd - b vs κ) / vs
            # with κ ~ (u_d + bend) / vs² on the last step (the guess's vs)
            v_f = float(max(G[K, 1], 0.5))
            for a, rhs in zip(*goal_rows):
                if a[0] == 0.0 and a[2] == 0.0 and a[3] != 0.0:
                    lean = -float(a[3]) * engine[4] / v_f
                    le([(4 * K + 1, float(a[1])), (4 * K + 3, float(a[3])), (nx + 2 * (K - 1) + 1, lean)],
                       float(rhs) - lean * float(bend_k[K - 1]))
    # the vehicles (and road-edge boxes) on their chosen sides, sign * x + slack >= sign * bound
    for i, (k, axis, sign, bound) in enumerate(sides):
        if axis == 2:  # sign * d - L/2 |vd| / vs + slack >= sign * bound
            for pm in (-1.0, 1.0):
                le([(4 * k + 2, -sign), (4 * k + 3, pm * float(lever[k])), (n_u + i, -1.0)], -sign * bound)
        else:
            le([(4 * k + axis, -sign), (n_u + i, -1.0)], -sign * bound)
        le([(n_u + i, -1.0)], 0.0)
    # the friction circle: (a_max, us_k, ud_k) in the second-order cone
    so_r: list[int] = []
    so_c: list[int] = []
    so_v: list[float] = []
    b_soc = np.zeros(3 * K)
    # in the world the acceleration across the road gains the curvature's κ vs² (at the guess)
    bend = np.asarray(cr.frame.curvature(G[:K, 0]), dtype=float) * G[:K, 1] ** 2
    # the steered model's friction circle leaves its tracker's feedback room (CORRIDOR_ENGINE_SHARE)
    circle = CORRIDOR_ACCEL_SHARE * cr.a_max if engine is None else CORRIDOR_ENGINE_SHARE * min(cr.a_max, engine[0])
    for k in range(K):
        b_soc[3 * k] = circle
        b_soc[3 * k + 2] = float(bend[k])
        so_r += [3 * k + 1, 3 * k + 2]
        so_c += [nx + 2 * k, nx + 2 * k + 1]
        so_v += [-1.0, -1.0]
    m_eq, m_in = len(eqs), len(les)
    A = sparse.vstack([eqs.matrix(n), les.matrix(n),
                       sparse.coo_matrix((so_v, (so_r, so_c)), shape=(3 * K, n))]).tocsc()
    b = np.concatenate([eqs.rhs, les.rhs, b_soc])
    cones = [clarabel.ZeroConeT(m_eq), clarabel.NonnegativeConeT(m_in)] + [clarabel.SecondOrderConeT(3)] * K
    q_diag = np.concatenate([np.zeros(nx), np.full(2 * K, dt), np.zeros(n - n_u)])
    q_lin = np.concatenate([np.zeros(n_u), np.full(n_road - n_u, CORRIDOR_SLACK_WEIGHT),
                            np.full(n - n_road, CORRIDOR_ROAD_SLACK_WEIGHT)])
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    solver = clarabel.DefaultSolver(sparse.diags(q_diag).tocsc(), q_lin, A, b, cones, settings)
    sol = solver.solve()
    if str(sol.status) not in ("Solved", "AlmostSolved"):
        return None
    found = np.asarray(sol.x, dtype=float)
    A_in = A[m_eq:m_eq + m_in]
    if not np.all(A_in @ found <= np.asarray(les.rhs) + 1e-6):
        return None
    return StepTrajectory(cr.x0, dt, found[nx:n_u])


def _smoothstep(t: FloatArray, t0: float, t1: float) -> tuple[FloatArray, FloatArray]:
    """The cubic step from 0 at ``t0`` to 1 at ``t1`` and its time derivative."""
    if t1 <= t0:
        return (t >= t1).astype(float), np.zeros_like(t)
    x = np.clip((t - t0) / (t1 - t0), 0.0, 1.0)
    return x * x * (3 - 2 * x), 6 * x * (1 - x) / (t1 - t0)


#: Fractions of the horizon at which a lane schedule of the corridor planner's guesses arrives
#: in its intermediate lane and leaves it (:func:`_schedule_guesses`).
CORRIDOR_ARRIVE = (0.25, 0.45)
CORRIDOR_LEAVE = (0.6, 0.8)
#: Guesses of the lane schedules the corridor planner solves at most (the least intruding).
CORRIDOR_SCHEDULES = 4
#: The late schedules (:func:`_schedule_guesses`): the start's lane held until this fraction of
#: the horizon, then a lane boundary reached at the second and left at the third, for a goal a
#: vehicle passes through until the window's last steps (entered from beside it at the end).
CORRIDOR_LATE = (0.65, 0.85, 0.92)
#: Late schedules solved at most (the least intruding), besides :data:`CORRIDOR_SCHEDULES`.
CORRIDOR_LATE_SCHEDULES = 2
#: QP solves of the late schedules, after the corridor planner's ``max_solves``.
CORRIDOR_LATE_SOLVES = 10


def _step_boxes(cr: CommonRoadProblem, K: int) -> FloatArray:
    """Every vehicle's recorded box at the time steps ``0..K``: shape ``(4, K+1, m)`` (``s_lo,
    s_hi, d_lo, d_hi``; NaN where it has no record at a step)."""
    out = np.full((4, K + 1, len(cr.obstacles)), np.nan)
    for i, ob in enumerate(cr.obstacles):
        idx = np.rint(ob.t / cr.dt).astype(int)
        ok = (idx >= 0) & (idx <= K) & (np.abs(ob.t / cr.dt - idx) < 1e-6)
        for a, arr in enumerate((ob.s_lo, ob.s_hi, ob.d_lo, ob.d_hi)):
            out[a, idx[ok], i] = arr[ok]
    return out


def _box_depth(cr: CommonRoadProblem, G: FloatArray, boxes: FloatArray) -> float:
    """How deep a guess on the time steps goes into the vehicles: for every vehicle, the deepest
    overlap over the steps of the body's box along the road (at heading 0, grown by
    :data:`CHECK_BUFFER_M`) with its recorded box, summed (a ranking, not a check)."""
    s, d = G[:, 0:1], G[:, 2:3]
    L2, W2 = cr.ego_length / 2 + CHECK_BUFFER_M, cr.ego_width / 2 + CHECK_BUFFER_M
    ov_s = np.minimum(s + L2, boxes[1]) - np.maximum(s - L2, boxes[0])
    ov_d = np.minimum(d + W2, boxes[3]) - np.maximum(d - W2, boxes[2])
    depth = np.nan_to_num(np.minimum(ov_s, ov_d), nan=0.0)
    return float(np.sum(np.maximum(np.max(depth, axis=0), 0.0)))


def _schedule_guesses(cr: CommonRoadProblem, cand: Candidate, late: bool = False) -> list[FloatArray]:
    """Guesses on the time steps for :func:`plan_corridor` that pass through one lane on the way:
    the longitudinal motion the free cubic to ``cand``'s final state or to the farthest-ahead and
    farthest-behind point of its goal rows (an overtaking plan ends as far ahead of the vehicle it
    passes as the goal lets it), the lateral motion a smooth change from the start's offset to a
    lane's centre arriving at one of :data:`CORRIDOR_ARRIVE` of the horizon and from it to the
    final offset leaving at one of :data:`CORRIDOR_LEAVE`; every lane of ``cr.lanes`` on the road.
    Ranked by how deep the body check finds them in the vehicles (:func:`intrusions`), then by
    their free cost; the :data:`CORRIDOR_SCHEDULES` least intruding.  With ``late``, instead the
    late schedules: the start's nearest lane held, a boundary between two lanes reached between
    the fractions :data:`CORRIDOR_LATE` of the horizon and left for the final offset at the last
    (a goal a vehicle drives through until the window's end is entered from beside it), the
    :data:`CORRIDOR_LATE_SCHEDULES` least intruding."""
    from iamp.commonroad.goal import goal_rows, solve_small_qp

    K, T = cand.steps, cand.tf
    t: FloatArray = np.arange(K + 1, dtype=np.float64) * cr.dt
    ends = [(cand.s, cand.vs)]
    if cand.goal_step >= 0:
        A, b = goal_rows(cr.goal, cand, cr.x0)
        for push in (60.0, -60.0):
            z = solve_small_qp(np.eye(4), np.array([cand.s + push, cand.vs, cand.d, cand.vd]), A, b)
            if z is not None and abs(float(z[0]) - cand.s) > 0.2:
                ends.append((float(z[0]) - 0.1 * np.sign(push), float(z[1])))
    lon = [FreeTrajectory(T, cr.x0, (s_e, v_e, cand.d, cand.vd)).states(t)[:, :2] for s_e, v_e in ends]
    sy = ego_margins(cr.ego_length, cr.ego_width, HEADING_GUESS_RAD, 0.0)[1]
    lanes = [ln for ln in cr.lanes if cr.road_y[0] + sy <= ln <= cr.road_y[1] - sy]
    boxes = _step_boxes(cr, K)
    scored: list[tuple[float, float, int, FloatArray]] = []
    n = 0
    for S in lon if not late else []:
        for ln in lanes:
            for fa in CORRIDOR_ARRIVE:
                for fl in CORRIDOR_LEAVE:
                    a1, va1 = _smoothstep(t, 0.0, fa * T)
                    a2, va2 = _smoothstep(t, fl * T, T)
                    d = cr.x0[2] + (ln - cr.x0[2]) * a1 + (cand.d - ln) * a2
                    vd = (ln - cr.x0[2]) * va1 + (cand.d - ln) * va2
                    G = np.column_stack([S[:, 0], S[:, 1], d, vd])
                    energy = float(np.sum(np.diff(G[:, 1]) ** 2 + np.diff(G[:, 3]) ** 2))
                    scored.append((_box_depth(cr, G, boxes), energy, n, G))
                    n += 1
    scored.sort(key=lambda e: (e[0], e[1], e[2]))
    # late: hold the start's lane, slip to a lane boundary (beside the goal's lane) near the end
    # and into the goal in the last steps
    home = min(lanes, key=lambda ln: abs(ln - cr.x0[2])) if lanes else cr.x0[2]
    tail: list[tuple[float, float, int, FloatArray]] = []
    a0, va0 = _smoothstep(t, 0.0, 0.3 * T)
    a1, va1 = _smoothstep(t, CORRIDOR_LATE[0] * T, CORRIDOR_LATE[1] * T)
    a2, va2 = _smoothstep(t, CORRIDOR_LATE[2] * T, T)
    bounds = [0.5 * (a + b) for a, b in zip(sorted(cr.lanes)[:-1], sorted(cr.lanes)[1:])]
    for S in lon if late else []:
        for mid in bounds:
            if not cr.road_y[0] + sy <= mid <= cr.road_y[1] - sy:
                continue
            d = cr.x0[2] + (home - cr.x0[2]) * a0 + (mid - home) * a1 + (cand.d - mid) * a2
            vd = (home - cr.x0[2]) * va0 + (mid - home) * va1 + (cand.d - mid) * va2
            G = np.column_stack([S[:, 0], S[:, 1], d, vd])
            energy = float(np.sum(np.diff(G[:, 1]) ** 2 + np.diff(G[:, 3]) ** 2))
            tail.append((_box_depth(cr, G, boxes), energy, n, G))
            n += 1
    tail.sort(key=lambda e: (e[0], e[1], e[2]))
    return [G for _, _, _, G in scored[:CORRIDOR_SCHEDULES] + tail[:CORRIDOR_LATE_SCHEDULES]]


def _corridor_guesses(cr: CommonRoadProblem, best: RoadPlan, cand: Candidate, heading: float) -> list[FloatArray]:
    """The guesses of the corridor planner for ``cand`` on the time steps: ``best``'s plan, the
    free cubics joined at each waypoint around the vehicles in its way (:func:`_waypoints`), then
    the lane schedules (:func:`_schedule_guesses`)."""
    K = cand.steps
    out: list[FloatArray] = []
    if best.trajectory is not None:
        out.append(_step_guess(best.trajectory, K, cr.dt))
    by_id = {ob.obstacle_id: ob for ob in cr.obstacles}
    seen: list[int] = []
    for ob in ([best.blocked] if best.blocked is not None else []) + [i.obstacle for i in best.intrusions]:
        if not ob.road_edge and ob.obstacle_id not in seen:
            seen.append(ob.obstacle_id)
    sx, sy = ego_margins(cr.ego_length, cr.ego_width, heading)
    for oid in seen[:2]:
        for k_m, w in _waypoints(cr, by_id[oid], cand, sx, sy):
            t_m = k_m * cr.dt
            first = FreeTrajectory(t_m, cr.x0, w)
            second = FreeTrajectory(cand.tf - t_m, w, (cand.s, cand.vs, cand.d, cand.vd))
            out.append(_step_guess(ViaTrajectory(first, second, t_m, 0.0), K, cr.dt))
    return out + _schedule_guesses(cr, cand)

def plan_corridor(cr: CommonRoadProblem, best: RoadPlan, planner: str, heading: float = HEADING_GUESS_RAD,
                  max_solves: int = CORRIDOR_MAX_SOLVES, others: list[Candidate] | None = None,
                  engine: tuple[float, ...] | None = None) -> RoadPlan | None:
    """The corridor planner: where the active set and the two-stage search found no safe plan,
    plan the whole horizon on the time steps with every recorded box on a side chosen from a
    guess (:func:`corridor_qp`), re-centred on its own plan for up to :data:`CORRIDOR_PASSES`
    passes, the final state free inside the goal state's rows at its step and piece
    (:func:`~iamp.commonroad.goal.goal_rows`; a final state the search found clear may touch a
    vehicle's margin that an overtaking plan cannot reach, one farther ahead in the goal can be);
    guesses from :func:`_corridor_guesses`, for ``best``'s final state and then ``others`` (up to
    :data:`CORRIDOR_FINAL_STATES` in all), and last the late lane schedules
    (:func:`_schedule_guesses`) to the last step of ``best``'s goal window where one of
    ``others`` has it.  A
    plan is accepted when its final state passes the goal's own test
    (:meth:`~iamp.commonroad.goal.GoalRegion.verify`), the body check (:func:`intrusions`) finds
    it safe and the solution written from it accelerates within the friction circle in the world
    (:func:`_world_peak`); a pass whose body leaves only the road is re-planned laterally at the
    body's own heading (:func:`repair_at_edges`, counted as a solve) and accepted on the same
    terms.  Guesses are tried best's own plan first, then least intruding first
    (:func:`_box_depth`); a guess's passes stop when one is not :data:`CORRIDOR_PROGRESS` less
    deep than the last; a guess or pass met before is not solved again.  At most ``max_solves``
    QP solves (a count, never a time), and :data:`CORRIDOR_LATE_SOLVES` more for the late
    schedules.

    Parameters
    ----------
    cr : CommonRoadProblem
    best : RoadPlan
        The best attempt (its final state's step and piece are tried first).
    planner : str
        The label of the plan returned.
    heading : float
        The heading the vehicles' margins of the waypoints assume [rad].
    max_solves : int
        QP solves over every final state, guess and pass.
    others : list of Candidate, optional
        Further final states tried (other steps or pieces of the goal).
    engine : (a_max, v_switch), optional
        The steered model's longitudinal limit (:func:`corridor_qp`); None for a point mass.

    Returns
    -------
    RoadPlan or None
        A safe plan (``iamp_status`` ``"corridor"``), or None.
    """
    from iamp.commonroad.goal import goal_rows

    first = best.candidate
    if first is None:
        return None
    cands = [first]
    for c in others or []:
        if len(cands) < CORRIDOR_FINAL_STATES and all((c.steps, c.element, c.piece) != (o.steps, o.element, o.piece)
                                                      for o in cands):
            cands.append(c)
    # the last step of the first's goal window (a vehicle leaving the goal late leaves room only
    # there), where another final state has it: its late schedules, after every other guess
    last = [c for c in others or [] if c.element == first.element and c.goal_step > first.goal_step]
    end_state = max(last, key=lambda c: (c.goal_step, -c.cost0)) if last else None
    elapsed = _elapsed(cr) if cr.candidates else 0
    # every final state's guesses, then round robin: the first guess of each, the second of each, ...
    jobs: list[tuple[float, int, Candidate, FloatArray]] = []
    for cand in cands:
        if cand.steps < 2:
            continue
        start = best if cand is first else dataclasses.replace(best, trajectory=None, candidate=cand, blocked=None,
                                                                intrusions=[])
        boxes = _step_boxes(cr, cand.steps)
        for G in _corridor_guesses(cr, start, cand, heading):
            jobs.append((-1.0 if not jobs else _box_depth(cr, G, boxes), len(jobs), cand, G))
    jobs.sort(key=lambda j: (j[0], j[1]))  # best's own plan first, then the least intruding guesses
    if end_state is not None and end_state.steps >= 2:
        n_first = len(jobs)
        jobs += [(0.0, len(jobs), end_state, G) for G in _schedule_guesses(cr, end_state, late=True)]
    else:
        n_first = len(jobs)
    solves = 0
    seen: set[bytes] = set()  # the guesses and passes already solved (to the centimetre)
    for j_index, (_, _, cand, G) in enumerate(jobs):
        if j_index == n_first:  # the late schedules: a budget of their own
            max_solves = solves + CORRIDOR_LATE_SOLVES
        rows = goal_rows(cr.goal, cand, cr.x0) if cand.goal_step >= 0 else None
        e = cr.goal.elements[cand.element]
        depth = math.inf
        for _ in range(CORRIDOR_PASSES):
            key = np.round(G, 2).tobytes()
            if key in seen:
                break
            seen.add(key)
            if solves >= max_solves:
                break
            solves += 1
            got = corridor_qp(cr, cand, G, rows, engine)
            if got is None:
                break
            z = got.states([cand.tf])[0]
            end = dataclasses.replace(cand, s=float(z[0]), vs=float(z[1]), d=float(z[2]), vd=float(z[3]))
            hits = intrusions(cr, got, cand.tf)
            h, peak = _heading_and_peak(got, cand.tf)
            in_goal = rows is None or cr.goal.verify(e, cand.steps + elapsed, _tuple4(z)) is None
            if not hits and _world_peak(cr, got, cand.steps) <= cr.a_max and in_goal:
                return RoadPlan(planner, "optimal", end, got, got.cost(), 0.0, [], [], "corridor", 0, None, h, peak)
            if hits and in_goal and all(i.obstacle.road_edge for i in hits) and solves < max_solves:
                # off the road only: its lateral motion re-planned inside the corridor at the
                # body's own heading (the corridor QP's rows linearise the heading at the guess's
                # speed and are conservative near an edge that narrows; the repair is neither)
                solves += 1
                fixed = repair_at_edges(cr, got, end)
                if (fixed is not None and not intrusions(cr, fixed, cand.tf)
                        and _world_peak(cr, fixed, cand.steps) <= cr.a_max):
                    h, peak = _heading_and_peak(fixed, cand.tf)
                    return RoadPlan(planner, "optimal", end, fixed, fixed.cost(), 0.0, [], [], "corridor", 0, None,
                                    h, peak)
            now = sum(i.depth_m for i in hits)
            if now > CORRIDOR_PROGRESS * depth:  # the passes no longer get it out of the vehicles
                break
            depth = now
            G = _step_guess(got, cand.steps, cr.dt)
    return None

def _world_peak(cr: CommonRoadProblem, trajectory: Trajectory, steps: int) -> float:
    """The largest acceleration of the solution written from ``trajectory`` (the world velocities
    at the steps, differenced: what CommonRoad's ``PM`` test integrates) [m/s²]."""
    from iamp.commonroad.solution import world_states

    _, V, _ = world_states(cr, trajectory, steps)
    return float(np.max(np.linalg.norm(np.diff(V, axis=0), axis=1))) / cr.dt


def _tuple4(z: FloatArray) -> tuple[float, float, float, float]:
    return (float(z[0]), float(z[1]), float(z[2]), float(z[3]))

def _free_peak(cr: CommonRoadProblem, c: Candidate) -> float:
    """Peak |u| of the free plan to ``c`` (its inputs are linear in t: at t = 0 or t_f)."""
    U = FreeTrajectory(c.tf, cr.x0, (c.s, c.vs, c.d, c.vd)).inputs([0.0, c.tf])
    return float(np.max(np.hypot(U[:, 0], U[:, 1])))


def _beside(ob: Obstacle, x0: tuple[float, float, float, float], sx: float, sy: float,
            edge: tuple[float, float]) -> tuple[float, float]:
    """Final offsets beside ``ob`` on the side the ego starts (the lateral half-plane of
    :func:`corner_for`, 1 cm inside it; ``edge`` the margins at a road edge)."""
    if ob.road_edge:
        sy_e = edge[1]
        top, bottom = float(ob.d_hi.max()), float(ob.d_lo.min())
        return (top + sy_e + 0.01, math.inf) if ob.y < x0[2] else (-math.inf, bottom - sy_e - 0.01)
    band = ob.box_width / 2 + sy
    return (ob.y + band + 0.01, math.inf) if x0[2] >= ob.y else (-math.inf, ob.y - band - 0.01)


def _edges_only(p: RoadPlan) -> bool:
    """Is ``p`` unsafe only at road edges (every intrusion, and the vehicle without a corner, a
    road-edge box)?"""
    if p.trajectory is None or not p.intrusions:
        return False
    return all(i.obstacle.road_edge for i in p.intrusions) and (p.blocked is None or p.blocked.road_edge)


def _repaired(cr: CommonRoadProblem, cand: Candidate, p: RoadPlan) -> RoadPlan:
    """``p`` with its lateral motion re-planned inside the road corridor (:func:`repair_at_edges`),
    if that is safe; else ``p``."""
    assert p.trajectory is not None
    fixed = repair_at_edges(cr, p.trajectory, cand)
    if fixed is None:
        return p
    hits = intrusions(cr, fixed, cand.tf)
    h, peak = _heading_and_peak(fixed, cand.tf)
    if hits or peak > cr.a_max:
        return p
    return RoadPlan(p.planner, "optimal", cand, fixed, fixed.cost(), p.solve_time_s, list(p.imposed), [],
                    "edge-repair", 0, None, h, peak)


def edge_margins(cr: CommonRoadProblem, heading: float) -> tuple[float, float]:
    """The body's margins ``(S_x, S_y)`` at a road edge: its half extents turned by ``heading``
    (:func:`~iamp.commonroad.convert.ego_margins`) plus
    :data:`~iamp.commonroad.convert.EDGE_BUFFER_M`.

    :func:`plan` starts from the start's own heading to the road, not the vehicles' guess
    :data:`~iamp.commonroad.convert.HEADING_GUESS_RAD` (at 0.06 rad the body is 13.5 cm wider than
    at 0: a lane beside a narrowing edge that the body fits is shut), and plans again with the
    plan's largest heading when a plan that passes an edge turned more and is not safe
    (:func:`intrusions` judges the body at its own heading).
    """
    return ego_margins(cr.ego_length, cr.ego_width, heading, EDGE_BUFFER_M)


def _worse(a: RoadPlan, b: RoadPlan) -> bool:
    """Is ``a`` a worse fallback than ``b``? (no trajectory < intruding < too hard)."""
    def key(p: RoadPlan) -> tuple[int, float]:
        if p.trajectory is None:
            return (0, 0.0)
        return (1, -sum(i.depth_m for i in p.intrusions) - max(0.0, p.peak_accel_mps2 - 11.5))
    return key(a) < key(b)


def _candidate_order(cands: list[Candidate], n: int) -> list[Candidate]:
    """At most ``n`` final states spread over the goal region: the cheapest, the cheapest of every
    other goal state and position piece, then the window's ends and middle (deterministic)."""
    if len(cands) <= n:
        return list(cands)
    out: list[Candidate] = []

    def add(c: Candidate) -> None:
        if c not in out and len(out) < n:
            out.append(c)

    add(cands[0])
    groups: dict[tuple[int, int], Candidate] = {}
    for c in cands:
        groups.setdefault((c.element, c.piece), c)
    by_time = sorted(cands, key=lambda c: (c.steps, c.cost0))
    spread = [by_time[0], by_time[-1], by_time[len(by_time) // 2]]
    firsts = sorted(groups.values(), key=lambda c: c.cost0)
    for c in cands[1: max(1, n - len(spread) - min(len(firsts), 2))]:
        add(c)
    for c in firsts[:2] + spread + firsts[2:] + cands:
        add(c)
    return out


def lane_segment(cr: CommonRoadProblem, ob: Obstacle, t_hit: float) -> Obstacle:
    """The part of a lane changer's record in the lane it occupies at ``t_hit`` (the contiguous
    run of time steps whose centre is nearest that lane), so that it is imposed with the lateral
    box of that lane only; any other vehicle unchanged."""
    if not ob.lane_change or len(cr.lanes) < 2 or ob.t.size < 2:
        return ob
    centre = 0.5 * (ob.d_lo + ob.d_hi)
    lane = np.argmin(np.abs(centre[:, None] - np.asarray(cr.lanes)[None, :]), axis=1)
    k = int(np.argmin(np.abs(ob.t - t_hit)))
    same = lane == lane[k]
    lo = k
    while lo > 0 and same[lo - 1]:
        lo -= 1
    hi = k
    while hi < same.size - 1 and same[hi + 1]:
        hi += 1
    run = slice(lo, hi + 1)
    return dataclasses.replace(ob, t=ob.t[run], s_lo=ob.s_lo[run], s_hi=ob.s_hi[run], d_lo=ob.d_lo[run],
                               d_hi=ob.d_hi[run], lane=int(lane[k]))


def _plan_candidate(cr: CommonRoadProblem, cand: Candidate, label: str, iamp_planner: str, constraint: str,
                    active: bool, sx: float, sy: float, steps: int, budget: list[int],
                    edge: tuple[float, float]) -> RoadPlan:
    free = FreeTrajectory(cand.tf, cr.x0, (cand.s, cand.vs, cand.d, cand.vd))
    free_hits = intrusions(cr, free, cand.tf)
    if label == "free" or (active and not free_hits):
        # the free baseline is the optimum of the problem without vehicles: as a road plan it is
        # unsafe where it enters one (its intrusions say which)
        h, peak = _heading_and_peak(free, cand.tf)
        return RoadPlan(label, "unsafe" if free_hits else "optimal", cand, free, free.cost(), 0.0, [], free_hits,
                        None, 0, None, h, peak)
    margin_y = ego_margins(cr.ego_length, cr.ego_width, HEADING_GUESS_RAD, 0.0)[1]
    if not active:
        chosen = _relevant(cr, cand, free, sy)
        vehicles = []
        imposed = []
        for ob in chosen:
            corner = corner_for(ob, cand, cr.x0, sy, sx, edge)
            if corner is not None:
                vehicles.append(_avoided(ob, corner, sx, sy, edge))
                imposed.append((ob.obstacle_id, corner))
        if not vehicles or not _affords(budget, iamp_planner, constraint, len(vehicles), steps):
            h, peak = _heading_and_peak(free, cand.tf)
            return RoadPlan(label, "optimal" if not free_hits else "unsafe", cand, free, free.cost(), 0.0, [],
                            free_hits, None, 0, None if not vehicles else "the planner calls are spent", h, peak)
        return _finish(cr, cand, label, iamp_planner, constraint, vehicles, imposed, margin_y, steps, budget)
    vehicles, imposed = [], []
    keys: set[tuple[int, int]] = set()
    blocked: Obstacle | None = None
    current: RoadPlan | None = None
    hits = free_hits
    spent = False
    for _ in range(MAX_IMPOSED):
        if not _affords(budget, iamp_planner, constraint, len(vehicles) + 1, steps):
            spent = True
            break
        new = None
        for hit in hits:
            seg = lane_segment(cr, hit.obstacle, hit.time_s)
            if (seg.obstacle_id, seg.lane) in keys:
                continue
            corner = corner_for(seg, cand, cr.x0, sy, sx, edge)
            if corner is not None:
                new = (seg, corner)
                break
        if new is None:
            blocked = next((h.obstacle for h in hits if (h.obstacle.obstacle_id, h.obstacle.lane) not in keys), None)
            break
        vehicles.append(_avoided(new[0], new[1], sx, sy, edge))
        imposed.append((new[0].obstacle_id, new[1]))
        keys.add((new[0].obstacle_id, new[0].lane))
        current = _finish(cr, cand, label, iamp_planner, constraint, vehicles, imposed, margin_y, steps, budget)
        if current.trajectory is None or current.safe:
            return current
        hits = current.intrusions
    if current is None:
        h, peak = _heading_and_peak(free, cand.tf)
        why = ("the planner calls are spent" if spent else
               "a vehicle in the way has no corner (the ego starts and ends in its lane)")
        out = RoadPlan(label, "unsafe", cand, free, free.cost(), 0.0, [], free_hits, None, 0, why, h, peak)
        out.blocked = blocked
        return out
    current.status = "unsafe"
    current.blocked = blocked
    return current


def _avoided(ob: Obstacle, corner: str, sx: float, sy: float, edge: tuple[float, float]) -> SurroundingVehicle:
    """The iamp vehicle of ``ob``: a vehicle with the body margins ``sx, sy`` (which include
    :data:`~iamp.commonroad.convert.BUFFER_M`), a road edge with the margins ``edge``
    (:func:`edge_margins`: only :data:`~iamp.commonroad.convert.EDGE_BUFFER_M` of clearance beyond
    the body)."""
    if ob.road_edge:
        return ob.vehicle(corner, *edge)
    return ob.vehicle(corner, sx, sy)


def _relevant(cr: CommonRoadProblem, cand: Candidate, free: FreeTrajectory, sy: float) -> list[Obstacle]:
    lo, hi = min(cr.x0[2], cand.d), max(cr.x0[2], cand.d)
    out = []
    for ob in cr.all_obstacles:
        if ob.d_hi.max() + sy < lo or ob.d_lo.min() - sy > hi:
            continue
        keep = ob.t <= cand.tf
        if not keep.any():
            continue
        s = free.states(ob.t[keep])[:, 0]
        gap = np.maximum(ob.s_lo[keep] - s, s - ob.s_hi[keep])
        if float(np.min(gap)) <= RELEVANT_S_M:
            out.append(ob)
    return out


def _finish(cr: CommonRoadProblem, cand: Candidate, label: str, iamp_planner: str, constraint: str,
            vehicles: list[SurroundingVehicle], imposed: list[tuple[int, str]], margin_y: float,
            steps: int, budget: list[int]) -> RoadPlan:
    """One call of the iamp planner, charged to ``budget`` (calls, equality-QP solves, PMP boxes)."""
    budget[0] -= 1
    if iamp_planner == "qp" and constraint == "equality":
        steps = qp_steps(len(vehicles), steps, budget[1])
        budget[1] -= math.perm(steps - 1, len(vehicles))
    boxes = min(PMP_MAX_BOXES, budget[2])
    try:
        result = _iamp_plan(cr, cand, vehicles, margin_y, iamp_planner, constraint, steps, boxes)
    except IampError as exc:
        if iamp_planner == "pmp":
            budget[2] -= boxes
        return RoadPlan(label, "refused", cand, None, None, 0.0, list(imposed), [], None, 0, str(exc))
    if iamp_planner == "pmp":
        search = getattr(result.diagnostics, "search", None)
        used = search.get("boxes") if isinstance(search, dict) else None
        budget[2] -= int(used) if isinstance(used, (int, np.integer)) else boxes
    if not result.ok and not only_lateral_bound_exceeded(result):
        return RoadPlan(label, result.status, cand, None, None, result.solve_time_s, list(imposed), [],
                        result.status, 0, str(result.info.get("reason") or result.status))
    h, peak = _heading_and_peak(result, cand.tf)
    hits = intrusions(cr, result, cand.tf)
    return RoadPlan(label, "optimal" if not hits else "unsafe", cand, result, result.cost, result.solve_time_s,
                    list(imposed), hits, result.status, 0, None, h, peak)


def only_lateral_bound_exceeded(result: Plan) -> bool:
    """Is ``result`` a plan with a trajectory that exceeds only its lateral bound ``y``?

    The bound ``y`` of :meth:`~iamp.commonroad.convert.CommonRoadProblem.limits` stands in for the
    road edges (their narrowest offsets less the body's half width); the QP planners impose it at
    their grid nodes, and between nodes the plan may pass it by a fraction of a millimetre
    (US101-5's two-goal-state variant: 0.56 mm).  The body check (:func:`intrusions`) judges the
    plan against the road-edge boxes at the body's own heading, so such a plan is judged there
    (and repaired at the edges if needed, :func:`repair_at_edges`), not thrown away.

    Parameters
    ----------
    result : iamp.core.plan.Plan
        A plan of the iamp planner.

    Returns
    -------
    bool
        ``True`` when its status is ``limits_violated``, it has a cost and a trajectory, and every
        exceeded bound is ``y``.
    """
    from iamp.core.status import LIMITS_VIOLATED

    if result.status != LIMITS_VIOLATED or result.cost is None or result.trajectory is None:
        return False
    peaks = result.peaks
    exceeded = [] if peaks is None else peaks.exceeded
    return bool(exceeded) and all(p.name == "y" for p in exceeded)


def describe(p: RoadPlan) -> RoadPlanJSON:
    """The JSON object of a road plan."""
    c = p.candidate
    return {
        "planner": p.planner, "status": p.status, "iamp_status": p.iamp_status,
        "cost": None if p.cost is None else float(p.cost), "solve_time_s": float(p.solve_time_s),
        "tf": None if c is None else c.tf, "final_state": None if c is None else
        {"s": c.s, "vs": c.vs, "d": c.d, "vd": c.vd, "steps": c.steps},
        "candidates_tried": p.candidates_tried, "planner_calls": p.plans_used,
        "imposed": [{"obstacle": i, "corner": k} for i, k in p.imposed],
        "intrusions": [{"obstacle": i.obstacle.obstacle_id, "depth_m": i.depth_m, "t": i.time_s}
                       for i in p.intrusions],
        "off_road_s": list(p.off_road_s),
        "max_heading_rad": p.max_heading_rad, "peak_accel_mps2": p.peak_accel_mps2,
        "reason": p.reason,
    }


def heading_deg(rad: float) -> float:
    return math.degrees(rad)


#: Largest tangent of the heading to the road a repaired plan may have (19°; the body's corner
#: bounds of :func:`repair_at_edges` hold exactly for ``|tan φ| <= W/L`` = 0.357), unless the
#: plan repaired turns more (:func:`repair_tan_bound`).
REPAIR_MAX_TAN = 0.35
#: The repaired plan may turn this much more (in tan φ) than the plan it repairs.
REPAIR_TAN_SLACK = 0.02
#: Never more than the goal's largest heading to the lane (tan 0.5 rad).
REPAIR_TAN_CAP = math.tan(0.5)
#: Lateral repairs per problem (:func:`plan`; a count of convex QPs, apart from the planner calls).
MAX_REPAIRS = 2
#: Clearance of the repaired body from the road's bound [m] (the frame's fit is exact to 1 cm
#: on the lanelets' vertices, the checker's boundary is their triangulation).
REPAIR_EDGE_BUFFER_M = 0.003
#: Half width of the window along the road in which a corner's bound is taken (the corner moves
#: by ``W/2 sin φ`` along the road when the body turns) [m].
REPAIR_CORNER_M = 0.15


class LateralRepair:
    """A plan whose longitudinal motion is a given trajectory's and whose lateral motion is a
    zero-order-hold input sequence on the time steps ``dt`` (:func:`repair_at_edges`)."""

    def __init__(self, base: Trajectory, dt: float, d0: float, vd0: float, u: FloatArray):
        self.base, self.dt = base, dt
        self.u = np.asarray(u, dtype=float)
        n = self.u.size
        self.d = np.empty(n + 1)
        self.vd = np.empty(n + 1)
        self.d[0], self.vd[0] = d0, vd0
        for k in range(n):
            self.d[k + 1] = self.d[k] + self.vd[k] * dt + 0.5 * self.u[k] * dt * dt
            self.vd[k + 1] = self.vd[k] + self.u[k] * dt

    def _lateral(self, t: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        k = np.clip(np.floor(t / self.dt + 1e-9).astype(int), 0, self.u.size - 1)
        tau = t - k * self.dt
        u = self.u[k]
        return self.d[k] + self.vd[k] * tau + 0.5 * u * tau**2, self.vd[k] + u * tau, u

    def states(self, t: npt.ArrayLike) -> FloatArray:
        tt = np.atleast_1d(np.asarray(t, dtype=float))
        X = np.array(self.base.states(tt), dtype=float)
        X[:, 2], X[:, 3], _ = self._lateral(tt)
        return X

    def inputs(self, t: npt.ArrayLike) -> FloatArray:
        tt = np.atleast_1d(np.asarray(t, dtype=float))
        U = np.array(self.base.inputs(tt), dtype=float)
        U[:, 1] = self._lateral(tt)[2]
        return U

    def cost(self) -> float:
        """½∫|u|²: the longitudinal part of the base (4-point Gauss-Legendre on every step), the
        lateral exactly."""
        x, w = np.polynomial.legendre.leggauss(4)
        t = (np.arange(self.u.size)[:, None] + 0.5 * (x[None, :] + 1)) * self.dt
        us = np.array(self.base.inputs(t.ravel()), dtype=float)[:, 0].reshape(t.shape)
        return float(0.25 * self.dt * np.sum(w[None, :] * us**2) + 0.5 * np.sum(self.u**2) * self.dt)


def repair_tan_bound(base_tan_max: float) -> float:
    """The bound ``τ`` on ``|tan φ|`` of a repaired plan whose base turns to ``base_tan_max``:
    :data:`REPAIR_MAX_TAN`, or the base's own plus :data:`REPAIR_TAN_SLACK` where it turns more
    (a plan that crosses lanes at low speed), at most :data:`REPAIR_TAN_CAP`.

    Parameters
    ----------
    base_tan_max : float
        Largest ``|ḋ/ṡ|`` of the plan repaired on the time steps.

    Returns
    -------
    float
    """
    return float(min(REPAIR_TAN_CAP, max(REPAIR_MAX_TAN, base_tan_max + REPAIR_TAN_SLACK)))


def corner_excess(half_length: float, half_width: float, tau: float) -> float:
    r"""How far a corner of the body can lie beyond the linear bound of :func:`repair_at_edges`.

    A corner of the left side lies at :math:`d + c\,\tfrac L2 \sin\varphi + \tfrac W2\cos\varphi`
    (:math:`c = \pm 1`, front or rear); the QP's row bounds it by :math:`d + c\,\tfrac L2\tan\varphi +
    \tfrac W2`.  The difference is at most
    :math:`\tfrac L2(\tan\varphi - \sin\varphi) - \tfrac W2(1 - \cos\varphi) =
    (1 - \cos\varphi)(\tfrac L2\tan\varphi - \tfrac W2)` at :math:`\varphi = |\varphi|`: at most 0
    for :math:`\tan\varphi \le W/L`, and increasing beyond, so over :math:`|\tan\varphi| \le \tau`
    its largest value is at :math:`\tan\varphi = \tau`.

    Parameters
    ----------
    half_length, half_width : float
        The body's half extents [m].
    tau : float
        Bound on ``|tan φ|``.

    Returns
    -------
    float
        The excess [m] (>= 0), added to the corner rows' clearance.
    """
    return max(0.0, (1.0 - 1.0 / math.sqrt(1.0 + tau * tau)) * (half_length * tau - half_width))


def _edge_line(grid: FloatArray, bound: FloatArray, a: float, b: float, up: bool) -> tuple[float, float]:
    """A line :math:`v_0 + m (s - a)` below the piecewise-linear upper ``bound`` over ``[a, b]``
    (above it for a lower bound, ``up`` false): the chord between its values at ``a`` and ``b``,
    moved by the farthest sample between them beyond it (exact where the bound is straight).
    Returns ``(v_0, m)``, ``nan`` outside the samples or where a sample is off every lanelet."""
    if a < grid[0] or b > grid[-1] or b <= a:
        return math.nan, math.nan
    sel = (grid >= a - 1e-9 - EDGE_STEP_M) & (grid <= b + 1e-9 + EDGE_STEP_M)
    if not np.all(np.isfinite(bound[sel])):
        return math.nan, math.nan
    va, vb = np.interp([a, b], grid, bound)
    m = float((vb - va) / (b - a))
    inside = (grid > a) & (grid < b)
    gap = float(va) + m * (grid[inside] - a) - bound[inside]
    shift = float(np.max(gap, initial=0.0)) if up else float(np.min(gap, initial=0.0))
    return float(va) - shift, m


def _narrowest(grid: FloatArray, bound: FloatArray, a: float, b: float, up: bool) -> float:
    """The narrowest value of the piecewise-linear ``bound`` over ``[a, b]`` (lowest for an upper
    bound, highest for a lower one; ``nan`` outside the samples)."""
    if a < grid[0] or b > grid[-1]:
        return math.nan
    inside = bound[(grid > a) & (grid < b)]
    vals = np.concatenate([np.interp([a, b], grid, bound), inside])
    return float(np.min(vals)) if up else float(np.max(vals))


def repair_at_edges(cr: CommonRoadProblem, base: Trajectory, cand: Candidate,
                    buffer: float | FloatArray | None = None) -> LateralRepair | None:
    r"""Keep ``base``'s longitudinal motion and re-plan its lateral motion so that the ego's body,
    at its own heading, stays inside the road corridor and beside every vehicle it is beside in
    ``base``: one convex QP on the CommonRoad time steps (the solution's own states).

    With :math:`s_k, \dot s_k` fixed, the heading's tangent :math:`\tan\varphi_k = \dot d_k/\dot s_k`
    is linear in the lateral state, and so are conservative bounds of the body's sides:
    a corner of the left side lies at :math:`d + \cos\varphi(\pm\tfrac L2\tan\varphi + \tfrac W2)
    \le d \pm \tfrac L2 \tan\varphi + \tfrac W2` (for :math:`|\tan\varphi| \le W/L`; beyond, plus
    :func:`corner_excess`), a point of the side at arc length :math:`\sigma` at
    :math:`d + (\sigma - s)\tan\varphi + \tfrac W2 \sec\varphi`, with :math:`\tfrac W2\sec\varphi`
    below the chord of :math:`\tfrac W2\sqrt{1 + x^2}` over :math:`|x| \le \tau_k`.  The bound
    :math:`|\tan\varphi_k| \le \tau_k` is :data:`REPAIR_MAX_TAN`, or the base's own heading at
    step ``k`` plus :data:`REPAIR_TAN_SLACK` where it turns more (:func:`repair_tan_bound`: a
    plan that crosses lanes at low speed near an edge it starts at).  Every sample of the corridor
    (``cr.corridor``) the body spans, and each corner against the corridor's narrowest value
    within 0.3 m of it, gives a row; every recorded vehicle that overlaps the body along the
    road at a step keeps the body on the side it is on in ``base``.  Inputs: the friction circle
    less the longitudinal input of the step; the start and the final state are ``base``'s.
    Minimises :math:`\sum u_k^2`.  Returns ``None`` when the QP is infeasible or fails.
    ``buffer`` is the body's clearance from the road's bound, one value or one per time step
    ``0..K`` (default :data:`REPAIR_EDGE_BUFFER_M`).
    """
    import clarabel
    from scipy import sparse

    if cr.corridor is None:
        return None
    dt, K = cr.dt, cand.steps
    buf = np.broadcast_to(np.asarray(REPAIR_EDGE_BUFFER_M if buffer is None else buffer, dtype=float), (K + 1,))
    L2, W2 = cr.ego_length / 2, cr.ego_width / 2
    t = np.arange(K + 1) * dt
    X = np.array(base.states(t), dtype=float)
    S, VS = X[:, 0], np.maximum(X[:, 1], 0.1)
    mid = np.array(base.inputs(np.concatenate([t[:-1], t[:-1] + 0.5 * dt, t[1:]])), dtype=float)[:, 0]
    us = np.max(np.abs(mid.reshape(3, K)), axis=0)
    ud_max = np.sqrt(np.maximum(cr.a_max**2 - us**2, 0.0)) * 0.99
    grid, lo, hi = cr.corridor
    d0, vd0 = cr.x0[2], cr.x0[3]
    # per step: the bound on |tan φ| (the base's own where it turns more than REPAIR_MAX_TAN) and what it costs
    tau = np.array([repair_tan_bound(float(x)) for x in np.abs(X[:, 3]) / VS])
    excess = np.array([corner_excess(L2, W2, float(x)) for x in tau])
    # the lateral state is affine in the inputs u (zero-order hold on the steps)
    kk_, jj_ = np.meshgrid(np.arange(K + 1), np.arange(K), indexing="ij")
    Vm = np.where(jj_ < kk_, dt, 0.0)
    Dm = np.where(jj_ < kk_, dt * dt * (kk_ - jj_ - 0.5), 0.0)
    d_free = d0 + t * vd0
    # W/2 sec φ <= W/2 + sec |tan φ| (the chord of the convex sqrt(1 + x²) over |x| <= REPAIR_MAX_TAN)
    sec = W2 * (np.sqrt(1.0 + tau**2) - 1.0) / tau
    rows: list[tuple[int, float, float, float]] = []  # (k, coefficient of tan φ, bound, +1 upper / -1 lower)
    for k in range(1, K + 1):
        for sign, bound in ((1.0, hi), (-1.0, lo)):
            for corner in (-1.0, 1.0):  # rear, front corners: the narrowest value near them
                b = _narrowest(grid, bound, S[k] + corner * L2 - REPAIR_CORNER_M, S[k] + corner * L2 + REPAIR_CORNER_M,
                               sign > 0)
                if np.isfinite(b):
                    rows.append((k, corner * L2, b - sign * (W2 + buf[k] + excess[k]), sign))
            inside = np.flatnonzero((grid > S[k] - L2 + 0.3) & (grid < S[k] + L2 - 0.3) & np.isfinite(bound))
            for j in inside:  # the side between them, with the secant's bound
                for pm in (-1.0, 1.0):
                    rows.append((k, float(grid[j] - S[k]) + pm * float(sec[k]) * sign,
                                 float(bound[j]) - sign * (W2 + buf[k]), sign))
    # vehicles: stay on the side of each vehicle the base is on, where they overlap along the road
    reach = L2 + sec
    for ob in [*cr.obstacles, *(o for o in cr.road_edges if o.hole)]:
        idx = np.rint(ob.t / dt).astype(int)
        for j in np.flatnonzero((idx >= 1) & (idx <= K)):
            k = int(idx[j])
            pad = W2 * float(tau[k]) + BUFFER_M
            if S[k] + L2 + pad < ob.s_lo[j] or S[k] - L2 - pad > ob.s_hi[j]:
                continue
            if X[k, 2] > 0.5 * (ob.d_lo[j] + ob.d_hi[j]):
                rows += [(k, pm * float(reach[k]), float(ob.d_hi[j]) + W2 + CHECK_BUFFER_M, -1.0) for pm in (-1.0, 1.0)]
            else:
                rows += [(k, pm * float(reach[k]), float(ob.d_lo[j]) - W2 - CHECK_BUFFER_M, 1.0) for pm in (-1.0, 1.0)]
    # rows: sign * (d_k + a tan φ_k) <= sign * c, tan φ_k = vd_k / VS_k; drop those far from binding
    if rows:
        R = np.array(rows)
        k_ = R[:, 0].astype(int)
        a_, c_, sg = R[:, 1], R[:, 2], R[:, 3]
        slack = sg * (c_ - (X[k_, 2] + a_ * X[k_, 3] / VS[k_]))
        keep = slack < 0.5 + L2 * tau[k_]
        k_, a_, c_, sg = k_[keep], a_[keep], c_[keep], sg[keep]
        coef = (a_ / VS[k_])[:, None]
        A_edge = sg[:, None] * (Dm[k_] + coef * Vm[k_])
        b_edge = sg * (c_ - d_free[k_] - (a_ / VS[k_]) * vd0)
    else:
        A_edge, b_edge = np.zeros((0, K)), np.zeros(0)
    eye = np.eye(K)
    A_in = np.vstack([eye, -eye, Vm[1:], -Vm[1:], A_edge])
    b_in = np.concatenate([ud_max, ud_max, tau[1:] * VS[1:] - vd0, tau[1:] * VS[1:] + vd0, b_edge])
    A_eq = np.vstack([Dm[K], Vm[K]])
    b_eq = np.array([cand.d - d_free[K], cand.vd - vd0])
    A = sparse.csc_matrix(np.vstack([A_eq, A_in]))
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    solver = clarabel.DefaultSolver(sparse.csc_matrix(eye), np.zeros(K), A, np.concatenate([b_eq, b_in]),
                                    [clarabel.ZeroConeT(2), clarabel.NonnegativeConeT(b_in.size)], settings)
    sol = solver.solve()
    if str(sol.status) not in ("Solved", "AlmostSolved"):
        return None
    u = np.asarray(sol.x, dtype=float)
    if not np.all(A_in @ u <= b_in + 1e-6):
        return None
    return LateralRepair(base, dt, d0, vd0, u)




#: Passes of the steered car's edge repair (:func:`steer_at_edges`; a count, not a time).
STEER_PASSES = 3
#: Clearance from CommonRoad's road boundary the steered body is given where it had less [m].
STEER_CLEAR_M = 0.005
#: Bisection steps of :func:`road_clearance` (its resolution: 0.25 m / 2^12 = 0.06 mm).
CLEARANCE_ITERATIONS = 12
#: A body farther than this from the corridor's widest bounds and from every road-edge box is on
#: CommonRoad's road without asking its checker (they are within 2 cm of its road) [m].
NEAR_EDGE_M = 0.1


def near_road_edges(cr: CommonRoadProblem, centre: FloatArray, heading: FloatArray,
                    near: float = NEAR_EDGE_M) -> npt.NDArray[np.bool_]:
    """Which bodies (world centres and headings) come within ``near`` of the road's edge in the
    road frame: of the corridor's widest bounds ``cr.road_y``, of a road-edge box (a narrower
    part or a hole, :func:`body_overlap`), or beyond the corridor's ends.  Only those need
    CommonRoad's road check (:func:`off_road_poses`, whose checker costs 0.4 s to build).

    Parameters
    ----------
    cr : CommonRoadProblem
    centre : ndarray, shape (n, 2)
    heading : ndarray, shape (n,)
    near : float
        The distance [m].

    Returns
    -------
    ndarray of bool, shape (n,)
    """
    sd = np.asarray(cr.frame.to_road(np.asarray(centre, dtype=float)), dtype=float)
    s, d = sd[:, 0], sd[:, 1]
    phi = (np.asarray(heading, dtype=float) - np.asarray(cr.frame.heading(s), dtype=float) + math.pi) % (
        2 * math.pi) - math.pi
    L2, W2 = cr.ego_length / 2, cr.ego_width / 2
    across = L2 * np.abs(np.sin(phi)) + W2 * np.abs(np.cos(phi))
    lo, hi = cr.road_y
    out = (d + across > hi - near) | (d - across < lo + near)
    if cr.corridor is not None:
        grid = cr.corridor[0]
        out |= (s - L2 - near < grid[0]) | (s + L2 + near > grid[-1])
    for ob in cr.road_edges:
        one = np.ones_like(s)
        out |= body_overlap(s, d, phi, float(ob.s_lo.min()) * one, float(ob.s_hi.max()) * one,
                            float(ob.d_lo.min()) * one, float(ob.d_hi.max()) * one, L2, W2, near) > 0
    return np.asarray(out, dtype=bool)


def steered_off_road(cr: CommonRoadProblem, centre: FloatArray, heading: FloatArray,
                     grow: float = 0.0) -> npt.NDArray[np.bool_]:
    """:func:`off_road_poses`, asked only for the bodies :func:`near_road_edges` (with ``grow``
    added to its distance); the others are on the road."""
    C, H = np.asarray(centre, dtype=float), np.asarray(heading, dtype=float)
    near = near_road_edges(cr, C, H, NEAR_EDGE_M + max(grow, 0.0))
    out = np.zeros(len(C), dtype=bool)
    if near.any():
        out[near] = off_road_poses(cr, C[near], H[near], grow)
    return out


def steered_reaches_goal(cr: CommonRoadProblem, ks: Any) -> bool:
    """Does the tracked ``KS`` solution (:class:`iamp.commonroad.ks.KSTrajectory`) reach the goal
    by CommonRoad's own goal test (commonroad-io's, as the checker runs it on ``KS`` states)?"""
    from commonroad.scenario.trajectory import Trajectory as CRTrajectory

    from iamp.commonroad.solution import ks_states

    ok, _ = cr.planning_problem.goal_reached(CRTrajectory(initial_time_step=0, state_list=ks_states(ks)))
    return bool(ok)


def road_clearance(cr: CommonRoadProblem, centre: FloatArray, heading: FloatArray,
                   lo: float = -0.2, hi: float = 0.05) -> FloatArray:
    """How far each body (world centres and headings, as :func:`off_road_poses`) is inside
    CommonRoad's road: the largest growth ``g`` of both half extents in ``[lo, hi]`` at which the
    body is still on the road, by bisection (:data:`CLEARANCE_ITERATIONS` steps, the lower end
    returned; negative: the body leaves the road by about ``-g``; ``lo`` where even the body
    shrunk by ``-lo`` leaves it, ``hi`` where the body grown by ``hi`` is on it).

    Parameters
    ----------
    cr : CommonRoadProblem
    centre : ndarray, shape (n, 2)
    heading : ndarray, shape (n,)
    lo, hi : float
        The interval searched [m].

    Returns
    -------
    ndarray, shape (n,)
    """
    C = np.asarray(centre, dtype=float)
    H = np.asarray(heading, dtype=float)
    out = np.empty(len(C))
    for j in range(len(C)):
        a, b = lo, hi
        if off_road_poses(cr, C[j:j + 1], H[j:j + 1], a)[0]:
            out[j] = a
            continue
        if not off_road_poses(cr, C[j:j + 1], H[j:j + 1], b)[0]:
            out[j] = b
            continue
        for _ in range(CLEARANCE_ITERATIONS):
            m = 0.5 * (a + b)
            if off_road_poses(cr, C[j:j + 1], H[j:j + 1], m)[0]:
                b = m
            else:
                a = m
        out[j] = a
    return out


def steer_at_edges(cr: CommonRoadProblem, p: RoadPlan, engine: tuple[float, ...] | None) -> RoadPlan:
    """A safe plan whose steered (``KS``) solution leaves CommonRoad's road, repaired laterally so
    that it does not.

    The ``KS`` solution follows the plan within millimetres, but its body is turned to the rear
    axle's heading, which lags the plan's direction of travel where the plan turns (US101-5: the
    plan clears the road's edge by 12 mm at 0.5 s and 3-5 mm later, the steered body, turned
    6 mrad less, leaves it by 5 mm at 0.5-0.7 s).  When the tracked solution
    (:func:`iamp.commonroad.ks.track`, the one written) is off the road at some step, the plan's
    lateral motion is re-planned (:func:`repair_at_edges`) with the body's clearance from the
    road raised, at each step where the steered body is less than :data:`STEER_CLEAR_M` inside
    the road (:func:`road_clearance`), by what it lacks (kept between passes: an iterative
    learning of the margin); the result is tracked again and taken when the steered body is on
    the road by CommonRoad's own check, the plan clear of every vehicle (:func:`intrusions`) and
    within the friction circle.  At most :data:`STEER_PASSES` passes (a count); otherwise ``p``
    is returned unchanged.

    Parameters
    ----------
    cr : CommonRoadProblem
    p : RoadPlan
        A plan of :func:`plan`.
    engine : KSEngine or None
        :func:`ks_engine`'s tuple (its ``vehicle_type`` names the steered model); ``None`` or a
        tuple without it (a point-mass solution): ``p`` unchanged.

    Returns
    -------
    RoadPlan
        ``p``, or the repaired plan (``iamp_status`` ``steered-edge-repair``), with
        ``steered_goal`` set: whether the tracked solution reaches the goal (CommonRoad's test).
    """
    vehicle_type = getattr(engine, "vehicle_type", None)
    if vehicle_type is None or not p.safe or p.candidate is None or p.trajectory is None:
        return p
    from iamp.commonroad.ks import track

    cand, base = p.candidate, p.trajectory
    K = cand.steps
    ks = track(cr, base, K, int(vehicle_type))
    p.steered_goal = steered_reaches_goal(cr, ks)
    p.steered = ks
    if not steered_off_road(cr, ks.centre, ks.states[:, 4]).any():
        return p
    margin = np.zeros(K + 1)
    for _ in range(STEER_PASSES):
        near = steered_off_road(cr, ks.centre, ks.states[:, 4], STEER_CLEAR_M)
        near[0] = False  # the initial state is the problem's
        if not near.any():
            return p
        idx = np.flatnonzero(near)
        margin[idx] += STEER_CLEAR_M - road_clearance(cr, ks.centre[idx], ks.states[idx, 4])
        fixed = repair_at_edges(cr, base, cand, REPAIR_EDGE_BUFFER_M + margin)
        if fixed is None:
            return p
        h, peak = _heading_and_peak(fixed, cand.tf)
        if intrusions(cr, fixed, cand.tf) or peak > cr.a_max:
            return p
        ks = track(cr, fixed, K, int(vehicle_type))
        if not steered_off_road(cr, ks.centre, ks.states[:, 4]).any():
            return RoadPlan(p.planner, "optimal", cand, fixed, fixed.cost(), p.solve_time_s, list(p.imposed), [],
                            "steered-edge-repair", 0, None, h, peak, steered_goal=steered_reaches_goal(cr, ks),
                            steered=ks)
    return p
