r"""A CommonRoad goal region in the road frame, and the final states the planner may aim for.

A CommonRoad goal is a list of **goal states**; the goal is reached when one state of the
trajectory lies inside **every** element of **one** goal state: its time-step interval, its
position (a shape, a group of shapes, or the lanelets named for it), its velocity interval
(the speed :math:`|v|`) and its orientation interval (the heading
:math:`\operatorname{atan2}(v_y, v_x)`); an element a goal state does not give is no constraint.

**Final states.**  For every goal state and every time step ``k`` of its window
(:math:`T = k\,\Delta t`) the final state :math:`z = (s_f, \dot s_f, d_f, \dot d_f)` is the
minimiser of the unconstrained minimum-energy cost of the double integrator per axis,

.. math::  J_0(z) = \sum_{axes} \tfrac12 (D, \delta v) \begin{pmatrix} 12/T^3 & -6/T^2 \\ -6/T^2 & 4/T
           \end{pmatrix} (D, \delta v)^\top, \quad D = p_f - p_0 - v_0 T,\ \delta v = v_f - v_0,

over the goal's elements written as linear constraints in the road frame:

* **position**: :math:`(s_f, d_f)` inside each convex piece of the goal's shape mapped to the road
  frame (a rectangle's corners; a lanelet cut into pieces of at most :data:`LANELET_PIECE_M` along
  the road between its two bounds), every edge moved inwards by :data:`POSITION_MARGIN_M`; a goal
  state without a position (a time step only: 27 of 47 US-101 problems outside the shared set)
  keeps the ego's lane, anywhere along it **on the mapped road**: :math:`s_f \le`
  :attr:`GoalRegion.s_max`, half a body and its buffer before the end of the lane's chain of
  lanelets (a body beyond it is off CommonRoad's road);
* **velocity**: :math:`(1 - \kappa d_c)\dot s_f` inside the speed interval less
  :data:`SPEED_MARGIN_MPS` (the upper end also less the speed the heading adds);
* **orientation**: with :math:`\theta` the lane's heading at the piece's centre, the heading in
  the road frame :math:`\varphi = \operatorname{atan2}(\dot d_f, \dot s_f)` inside the interval
  less :math:`\theta` and :data:`HEADING_MARGIN_RAD`, i.e. the cone
  :math:`\dot s_f \tan(\varphi^-) \le \dot d_f \le \dot s_f \tan(\varphi^+)`: the final lateral
  speed follows from the heading, :math:`\dot d_f = \dot s_f \tan(\varphi)`.

This is a strictly convex QP in four variables with at most a dozen rows; it is solved exactly
by enumerating active sets (every set of at most four rows, smallest first; the first whose KKT
point is primal and dual feasible is the optimum), so the answer is the same on any machine.
A margin that empties a small region is halved down to zero.  Each final state is then
**verified in the world** against the goal state by CommonRoad's own element tests (position
``contains_point``, the intervals' ``contains``); one that fails is dropped.

**Final states that can be valid** (:func:`clear_goal_states`).  The minimiser above may end
with the body inside a vehicle or off the road, while other poses of the same goal are clear.
For every goal state, time step and piece the planner is offered instead the cheapest pose
that a clearance test accepts (the body off every recorded vehicle at that step and on the
road, :func:`~iamp.commonroad.planning.final_state_clearance`): a best-first branch and bound
whose children add one way around the deepest obstacle met (ahead of it, behind it, above or
below it: one linear row with the body's margins at a heading band around the heading nearest
the lane's) to the same QP, every child's cost bounding its subtree's.  The QP solves are
counted (:data:`CLEAR_MAX_SOLVES`, :data:`CLEAR_MAX_NODES`); the same problem gives the same
states on any machine.  A goal state none of whose poses is accepted at any step, the search
complete, is out of reach by its **position** over its whole window, and the sentence names
what blocks it.

**Refusals.**  A goal state the model cannot reach names its element
(:func:`GoalRegion.unreachable`): a time window already over, a speed interval outside the
vehicle's speed range or beyond :math:`a_{max} T` of the initial speed at every time of the
window, an orientation across or against the road, a position beyond
:math:`a_{max} T^2/2` of the coasting point at every time, a mapped road that ends within a body of
the start (a goal state without a position), or elements that admit no common final state (the
element whose removal makes the QP feasible is named).
"""

from __future__ import annotations

import dataclasses
import heapq
import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from iamp.commonroad.frame import RoadFrame

FloatArray = npt.NDArray[np.float64]

#: Every edge of a goal shape is moved inwards by this much (ZOH drift, frame fit error) [m].
POSITION_MARGIN_M = 0.2
#: Margin kept inside the goal's speed interval [m/s].
SPEED_MARGIN_MPS = 0.3
#: Margin kept inside the goal's orientation interval [rad]: the steered (``KS``) car's heading
#: is the rear axle's, which leaves the point-mass plan's direction of travel by the slip angle
#: of its centre while it turns.  Measured on US-101 goal variants: 0.01 left two KS solutions
#: 0.001 and 0.02 rad outside the interval at the final step; 0.02 one; 0.03 none, but it made
#: two variants whose interval starts at the lane heading end turned more and fail as PM too.
HEADING_MARGIN_RAD = 0.02
#: A lanelet goal is cut into pieces of at most this length along the road [m].
LANELET_PIECE_M = 10.0
#: Largest heading relative to the lane the road-frame planner may end with [rad].
MAX_REL_HEADING_RAD = 0.5
#: ... where the goal gives no orientation [rad].
FREE_REL_HEADING_RAD = 0.2
#: A goal without position: the ego's lane, this far inside its bounds [m].
LANE_KEEP_MARGIN_M = 0.5


@dataclass(frozen=True)
class Candidate:
    """A final state and horizon: ``k`` steps, ``(s, vs, d, vd)`` in the road frame, the
    unconstrained cost ``cost0`` (:math:`J_0`), the goal state ``element`` it lies in, the
    region piece ``piece`` of that state and the goal's time step ``goal_step``."""

    steps: int
    tf: float
    s: float
    vs: float
    d: float
    cost0: float
    vd: float = 0.0
    element: int = 0
    piece: int = 0
    #: The goal's own time step the state is for (``-1``: not a goal final state, e.g. a waypoint);
    #: ``goal_step - steps`` steps had passed when it was made.
    goal_step: int = -1


@dataclass(frozen=True)
class Piece:
    """One convex piece of a goal position in the road frame: ``A p <= b`` with ``p = (s, d)``
    (edges not yet moved inwards), its centre and the lane heading there (world, rad)."""

    A: FloatArray
    b: FloatArray
    centre: tuple[float, float]
    lane_heading: float
    curvature: float


@dataclass(frozen=True)
class GoalElement:
    """One goal state: its intervals (``None`` where the goal gives none), its position pieces
    (``None``: no position) and the CommonRoad goal state itself (for the world test)."""

    index: int
    steps: tuple[int, int]
    speed: tuple[float, float] | None
    orientation: tuple[float, float] | None
    pieces: list[Piece] | None
    state: Any = field(repr=False, compare=False, default=None)
    lanelets: tuple[int, ...] = ()

    @property
    def label(self) -> str:
        return f"goal state {self.index}"


@dataclass
class GoalRegion:
    """Every goal state of a planning problem in the road frame (module docstring)."""

    elements: list[GoalElement]
    frame: RoadFrame
    ego_lane: tuple[float, float]
    v_range: tuple[float, float]
    a_max: float
    #: The largest arc length [m] of the body's centre at a final state of a goal state without a
    #: position: where the mapped road ends ahead (:func:`~iamp.commonroad.convert.load`, the
    #: corridor's end less half the body and its buffer), a body beyond it is off CommonRoad's
    #: road; ``inf`` where the road reaches beyond every final state.
    s_max: float = math.inf

    # --- the window over every goal state (the closed loop's end, the CLI's text) --------------
    @property
    def steps(self) -> tuple[int, int]:
        return (min(e.steps[0] for e in self.elements), max(e.steps[1] for e in self.elements))

    @property
    def s(self) -> float:
        """Arc length of the first goal state's first piece (or of nothing: NaN)."""
        for e in self.elements:
            if e.pieces:
                return e.pieces[0].centre[0]
        return math.nan

    @property
    def d(self) -> float:
        for e in self.elements:
            if e.pieces:
                return e.pieces[0].centre[1]
        return 0.5 * (self.ego_lane[0] + self.ego_lane[1])

    def describe(self) -> str:
        """One line: the goal states searched (time window, pieces, intervals)."""
        parts = []
        for e in self.elements:
            pos = ("no position" if e.pieces is None else
                   f"{len(e.pieces)} position piece(s)" + (f" (lanelets {', '.join(map(str, e.lanelets))})"
                                                           if e.lanelets else ""))
            spd = "any speed" if e.speed is None else f"speed [{e.speed[0]:.2f}, {e.speed[1]:.2f}] m/s"
            ori = ("any orientation" if e.orientation is None else
                   f"orientation [{e.orientation[0]:.3f}, {e.orientation[1]:.3f}] rad")
            parts.append(f"{e.label}: steps {e.steps[0]}-{e.steps[1]}, {pos}, {spd}, {ori}")
        return "; ".join(parts)

    # --- reachability -----------------------------------------------------------------------
    def unreachable(self, x0: tuple[float, float, float, float], dt: float, elapsed_steps: int = 0) -> dict[int, str]:
        """Goal states the model cannot reach, each with the element named (module docstring)."""
        out: dict[int, str] = {}
        for e in self.elements:
            why = _unreachable(self, e, x0, dt, elapsed_steps)
            if why is not None:
                out[e.index] = f"{e.label}: {why}"
        return out

    # --- final states -------------------------------------------------------------------------
    def final_states(self, x0: tuple[float, float, float, float], dt: float,
                     elapsed_steps: int = 0) -> list[Candidate]:
        """Every verified final state (module docstring), cheapest :math:`J_0` first."""
        out: list[Candidate] = []
        bad = self.unreachable(x0, dt, elapsed_steps)
        for e in self.elements:
            if e.index in bad:
                continue
            for k in range(max(e.steps[0], elapsed_steps + 1), e.steps[1] + 1):
                T = (k - elapsed_steps) * dt
                for j, piece in enumerate(self._pieces(e, x0, T)):
                    z = _final_state(self, e, piece, x0, T)
                    if z is None:
                        continue
                    if self.verify(e, k, z) is not None or not _within_limits(x0, z, T, self.a_max):
                        continue
                    out.append(Candidate(k - elapsed_steps, T, z[0], z[1], z[2], _cost0(T, x0, z), z[3], e.index, j,
                                         k))
        out.sort(key=lambda c: (c.cost0, c.steps, c.element, c.piece))
        return out

    def across(self, cand: Candidate, x0: tuple[float, float, float, float], d_range: tuple[float, float],
               elapsed_steps: int = 0) -> Candidate | None:
        """The cheapest final state of ``cand``'s goal state, piece and time with the final offset
        inside ``d_range`` (the search across the goal shape: a final state beside a vehicle or
        road edge the first choice ends behind), verified; None where the piece has none."""
        e = self.elements[cand.element]
        pieces = self._pieces(e, x0, cand.tf)
        if cand.piece >= len(pieces):
            return None
        z = _final_state(self, e, pieces[cand.piece], x0, cand.tf, d_range=d_range)
        if z is None or self.verify(e, cand.steps + elapsed_steps, z) is not None:
            return None
        return Candidate(cand.steps, cand.tf, z[0], z[1], z[2], _cost0(cand.tf, x0, z), z[3], cand.element,
                         cand.piece, cand.goal_step)

    def _pieces(self, e: GoalElement, x0: tuple[float, float, float, float], T: float) -> list[Piece]:
        if e.pieces is not None:
            return e.pieces
        # no position: the ego's lane, anywhere along it on the mapped road
        lo, hi = self.ego_lane
        s_lo, s_hi = x0[0] - 1.0, min(x0[0] + (self.v_range[1] + 1.0) * T, self.s_max)
        if not s_hi > s_lo:  # the road ends within a body of the start: no final state on it
            return []
        return [_box_piece(self.frame, s_lo, s_hi, lo + LANE_KEEP_MARGIN_M - POSITION_MARGIN_M,
                           hi - LANE_KEEP_MARGIN_M + POSITION_MARGIN_M)]

    def verify(self, e: GoalElement, k: int, z: tuple[float, float, float, float]) -> str | None:
        """The element of goal state ``e`` the road-frame state ``z`` at step ``k`` misses, or None."""
        pos = self.frame.to_world(z[0], z[2]).reshape(-1)
        vel = self.frame.velocity_to_world(z[0], z[2], z[1], z[3]).reshape(-1)
        return element_missed(e, k, pos, float(np.hypot(vel[0], vel[1])), float(math.atan2(vel[1], vel[0])))


@dataclass(frozen=True)
class Blocked:
    """Why a final state cannot be valid, as the clearance test of :func:`clear_goal_states`
    reports it: the names of what the body enters (``"vehicle 477"``, ``"road edge"``) and the
    ways around the deepest of them, each one linear row ``a @ z <= b`` in ``z = (s, vs, d, vd)``
    (ahead of it, behind it, beside it), valid for a heading within the band it was asked for."""

    names: tuple[str, ...]
    options: tuple[tuple[FloatArray, float], ...]


#: The clearance test: ``(T, z, band) -> None`` when the final state ``z`` at horizon ``T`` keeps
#: the body clear and on the road, else what blocks it (:class:`Blocked`), its rows valid for a
#: heading relative to the road within ``±band``.
ClearanceTest = Callable[[float, tuple[float, float, float, float], float], "Blocked | None"]


@dataclass
class ClearSearch:
    """The answer of :func:`clear_goal_states`: the cheapest clear final state of
    every goal state, time step and piece that has one (cheapest first), the QP solves spent,
    whether a budget cut the search short (``exhausted``: then a goal state without a clear
    state is not claimed to have none), and for every goal state without any, the sentence that
    says why (its element named)."""

    candidates: list[Candidate]
    solves: int
    exhausted: bool
    blocked: dict[int, str]
    roots: int = 0
    roots_clear: int = 0


#: QP solves of the clearance search over the whole goal region (a count, never a time).
CLEAR_MAX_SOLVES = 1500
#: Branch-and-bound nodes expanded per goal state, time step, piece and margin.
CLEAR_MAX_NODES = 40
#: The heading band the search's rows assume around the heading nearest the lane's [rad]
#: (the planner's own margins assume :data:`~iamp.commonroad.convert.HEADING_GUESS_RAD`).
CLEAR_BAND_RAD = 0.06
#: The narrow band tried where the first finds none (a goal at a narrowing road edge) [rad].
CLEAR_NARROW_BAND_RAD = 0.005
#: Margin scales tried in turn for a goal state none of whose poses is clear at the full margins;
#: the last keeps 1 cm inside the goal's shape (a pose on its edge leaves it by the plan's
#: millimetres of ZOH drift: US101-9's seed-1 ``lanes3`` goal, whose clear poses lie within 4 cm
#: of its edge, was ``goal missed`` at 0).
CLEAR_SCALES = (1.0, 0.5, 0.25, 0.05)


def _position_feasible(A: FloatArray, b: FloatArray) -> bool:
    """Is the polygon of the rows that involve only ``(s, d)`` non-empty?  (Clipping; the rows on
    the speeds are feasible by construction, so an infeasible QP is known without solving it.)"""
    pos = (A[:, 1] == 0.0) & (A[:, 3] == 0.0)
    poly = [(-1e6, -1e6), (1e6, -1e6), (1e6, 1e6), (-1e6, 1e6)]
    for a, bb in zip(A[pos], b[pos]):
        a_s, a_d = float(a[0]), float(a[2])
        out: list[tuple[float, float]] = []
        for i in range(len(poly)):
            p, q = poly[i], poly[(i + 1) % len(poly)]
            fp, fq = a_s * p[0] + a_d * p[1] - bb, a_s * q[0] + a_d * q[1] - bb
            if fp <= 1e-9:
                out.append(p)
            if (fp < -1e-9 < fq) or (fq < -1e-9 < fp):
                r = fp / (fp - fq)
                out.append((p[0] + r * (q[0] - p[0]), p[1] + r * (q[1] - p[1])))
        poly = out
        if len(poly) == 0:
            return False
    return True


def _search_piece(region: GoalRegion, e: GoalElement, k: int, j: int, piece: Piece,
                  x0: tuple[float, float, float, float], T: float, scale: float, elapsed: int, root: FloatArray,
                  clear: ClearanceTest, budget: list[int], names: set[str]) -> tuple[Candidate | None, bool]:
    r"""The cheapest final state of goal state ``e`` at step ``k`` in ``piece`` (margins at
    ``scale``) that the clearance test accepts, by best-first branch and bound from ``root``, the
    QP's minimiser: where a node is blocked, one child per way around the deepest obstacle (its
    row added, the heading within a band around the heading nearest the lane's: first
    :data:`CLEAR_BAND_RAD` wide, then, where that finds none, :data:`CLEAR_NARROW_BAND_RAD`, whose
    body margins are narrower); a child's cost bounds its subtree's, so the first accepted node
    popped is the cheapest accepted one (up to the band's body margins).  ``budget[0]`` counts
    QP solves; the names of everything met go into ``names``.  Returns the state (or None) and
    whether the search was complete (neither :data:`CLEAR_MAX_NODES` nor the budget cut it
    short)."""
    lo, hi = _cone(e, piece, scale)
    phi = 0.0 if lo <= 0.0 <= hi else min(abs(lo), abs(hi))
    complete = True
    for band in (max(CLEAR_BAND_RAD, phi + 0.02), phi + CLEAR_NARROW_BAND_RAD):
        got, done = _branch_and_bound(region, e, k, j, piece, x0, T, scale, elapsed, root, clear, budget, names, band)
        complete &= done
        if got is not None:
            return got, True
        if budget[0] <= 0:
            return None, False
    return None, complete


def _branch_and_bound(region: GoalRegion, e: GoalElement, k: int, j: int, piece: Piece,
                      x0: tuple[float, float, float, float], T: float, scale: float, elapsed: int, root: FloatArray,
                      clear: ClearanceTest, budget: list[int], names: set[str],
                      band: float) -> tuple[Candidate | None, bool]:
    """:func:`_search_piece` with the heading within ``±band`` below the root."""
    c = np.array([x0[0] + x0[1] * T, x0[1], x0[2] + x0[3] * T, x0[3]])
    Q = _hessian(T)
    Ab, bb = _rows(region, e, piece, scale, heading_cap=band)
    seq = itertools.count()
    heap: list[tuple[float, int, tuple[tuple[float, ...], ...], FloatArray]] = [
        (_cost0(T, x0, _tuple(root)), next(seq), (), root)]
    seen: set[tuple[tuple[float, ...], ...]] = set()
    nodes = 0
    while heap and nodes < CLEAR_MAX_NODES:
        _, _, extra, z = heapq.heappop(heap)
        nodes += 1
        zt = _tuple(z)
        blk = clear(T, zt, band)
        if blk is None:
            missed = region.verify(e, k, zt)
            if missed is None and _within_limits(x0, zt, T, region.a_max):
                return Candidate(k - elapsed, T, zt[0], zt[1], zt[2], _cost0(T, x0, zt), zt[3], e.index, j, k), True
            names.add(f"a state missing the goal's {missed}" if missed else "a state beyond the acceleration limit")
            continue
        names.update(blk.names)
        for a, rhs in blk.options:
            row = (*(float(v) for v in a), float(rhs))
            if row in extra:  # a way the node already takes: solving again gives the same node
                continue
            rows = extra + (row,)  # the parent's rows, then the new one
            key = tuple(sorted(rows))
            if key in seen:
                continue
            seen.add(key)
            A = np.vstack([Ab, np.array([r[:4] for r in rows])])
            b = np.concatenate([bb, [r[4] for r in rows]])
            if not _position_feasible(A, b):
                continue
            if budget[0] <= 0:
                return None, False
            budget[0] -= 1
            z2 = solve_small_qp(Q, c, A, b, first=_active_guesses(A[:-1], b[:-1], z, len(b) - 1))
            if z2 is not None:
                heapq.heappush(heap, (_cost0(T, x0, _tuple(z2)), next(seq), rows, z2))
    return None, not heap


def _tuple(z: FloatArray) -> tuple[float, float, float, float]:
    return (float(z[0]), float(z[1]), float(z[2]), float(z[3]))


def clear_goal_states(region: GoalRegion, x0: tuple[float, float, float, float], dt: float, clear: ClearanceTest,
                       elapsed_steps: int = 0, max_solves: int = CLEAR_MAX_SOLVES,
                       known: list[Candidate] | None = None) -> ClearSearch:
    r"""Final states that can be valid: inside every element of a goal state **and** accepted
    by ``clear`` (the body off every obstacle and on the road at that step), the cheapest of every
    goal state, time step and piece, cheapest :math:`J_0` first.

    Every goal state, time step of its window and piece of its position is searched by
    :func:`_search_piece` (in the order of its unconstrained optimum's cost, so a budget that
    runs out leaves the dearest); a goal state none of whose poses is accepted at the full
    margins is searched again at the smaller :data:`CLEAR_SCALES`.  A goal state with none at
    all is reported with its element named: its **position** at every step of its window
    (what blocks it), or the budget spent before the search could say.

    Parameters
    ----------
    region : GoalRegion
    x0 : (float, float, float, float)
        The start ``(s, vs, d, vd)`` in the road frame.
    dt : float
        The scenario's time step [s].
    clear : callable
        The clearance test (:data:`ClearanceTest`).
    elapsed_steps : int
        Steps already passed (the closed loop).
    max_solves : int
        QP solves over the whole search.
    known : list of Candidate, optional
        The goal's final states already made (:meth:`GoalRegion.final_states` with the same
        ``elapsed_steps``): one the test accepts is its step and piece's answer without a solve.

    Returns
    -------
    ClearSearch
    """
    bad = region.unreachable(x0, dt, elapsed_steps)
    budget = [max_solves]
    out: list[Candidate] = []
    blocked: dict[int, str] = {}
    roots = roots_clear = 0
    incomplete = False
    given = {(c.element, c.goal_step, c.piece): c for c in known or [] if c.goal_step - c.steps == elapsed_steps}
    for e in region.elements:
        if e.index in bad:
            continue
        ks = list(range(max(e.steps[0], elapsed_steps + 1), e.steps[1] + 1))
        names: set[str] = set()
        found: list[Candidate] = []
        complete = True
        for scale in CLEAR_SCALES:
            jobs = []
            for k in ks:
                T = (k - elapsed_steps) * dt
                for j, piece in enumerate(region._pieces(e, x0, T)):
                    ready = given.get((e.index, k, j)) if scale == CLEAR_SCALES[0] else None
                    if ready is not None and clear(T, (ready.s, ready.vs, ready.d, ready.vd), CLEAR_BAND_RAD) is None:
                        found.append(ready)  # the cheapest pose of its step and piece is clear: the answer
                        roots += 1
                        roots_clear += 1
                        continue
                    if budget[0] <= 0:
                        complete = False
                        break
                    budget[0] -= 1
                    A, b = _rows(region, e, piece, scale)
                    z = solve_small_qp(_hessian(T), np.array([x0[0] + x0[1] * T, x0[1], x0[2] + x0[3] * T, x0[3]]),
                                       A, b)
                    if z is not None:
                        jobs.append((_cost0(T, x0, _tuple(z)), k, j, piece, T, z))
            jobs.sort(key=lambda t: (t[0], t[1], t[2]))
            for cost, k, j, piece, T, z in jobs:
                got, done = _search_piece(region, e, k, j, piece, x0, T, scale, elapsed_steps, z, clear, budget,
                                          names)
                complete &= done
                if scale == CLEAR_SCALES[0]:
                    roots += 1
                    roots_clear += int(got is not None and got.cost0 <= cost + 1e-9)
                if got is not None:
                    found.append(got)
            if found or budget[0] <= 0:
                break
        out += found
        if not found:
            if not complete:
                blocked[e.index] = (f"{e.label}: the search for a final state clear of the vehicles and on the road "
                                    f"reached its budget ({max_solves} QP solves, {CLEAR_MAX_NODES} nodes per step "
                                    "and piece) before covering the goal region")
                incomplete = True
            else:
                what = ", ".join(sorted(names, key=_name_key)) or "nothing it could pass"
                blocked[e.index] = (f"{e.label}: position: at every time_step {ks[0]}-{ks[-1]} of its window every "
                                    f"pose of the goal's position inside its velocity and orientation meets {what}")
    out.sort(key=lambda c: (c.cost0, c.steps, c.element, c.piece))
    return ClearSearch(out, max_solves - budget[0], budget[0] <= 0 or incomplete, blocked, roots, roots_clear)


def _name_key(name: str) -> tuple[int, str]:
    tail = name.rsplit(" ", 1)[-1]
    return (int(tail), name) if tail.lstrip("-").isdigit() else (10**9, name)


def element_missed(e: GoalElement, k: int, pos: FloatArray, speed: float, heading: float) -> str | None:
    """Which element of goal state ``e`` the world state misses (CommonRoad's own tests), or None."""
    if not e.steps[0] <= k <= e.steps[1]:
        return "time_step"
    st = e.state
    if st is not None and st.has_value("position") and not st.position.contains_point(np.asarray(pos, dtype=float)):
        return "position"
    if st is not None and st.has_value("velocity") and not st.velocity.contains(speed):
        return "velocity"
    if st is not None and st.has_value("orientation") and not st.orientation.contains(heading):
        return "orientation"
    return None


def axis_reachable(p0: float, v0: float, pf: float, vf: float, T: float, a: float) -> bool:
    r"""Can the double integrator :math:`\ddot p = u`, :math:`|u| \le a`, go from ``(p0, v0)`` to
    ``(pf, vf)`` in exactly ``T``?  Iff :math:`|v_f - v_0| \le aT` and :math:`p_f` lies between
    the bang-bang extremes (full ``+a`` then ``-a``, and the reverse, switching where the speed
    ends at :math:`v_f`).  Per axis this is necessary for the friction circle
    :math:`|u| \le a` of both axes together."""
    if abs(vf - v0) > a * T + 1e-9:
        return False
    t1 = (vf - v0 + a * T) / (2 * a)  # +a for t1, then -a
    hi = p0 + v0 * t1 + 0.5 * a * t1**2 + (v0 + a * t1) * (T - t1) - 0.5 * a * (T - t1) ** 2
    t2 = (v0 - vf + a * T) / (2 * a)  # -a for t2, then +a
    lo = p0 + v0 * t2 - 0.5 * a * t2**2 + (v0 - a * t2) * (T - t2) + 0.5 * a * (T - t2) ** 2
    return lo - 1e-9 <= pf <= hi + 1e-9


def _within_limits(x0: tuple[float, float, float, float], z: tuple[float, float, float, float], T: float,
                   a: float) -> bool:
    return (axis_reachable(x0[0], x0[1], z[0], z[1], T, a) and axis_reachable(x0[2], x0[3], z[2], z[3], T, a))


def _wrap(a: float) -> float:
    return (a + math.pi) % (2 * math.pi) - math.pi


def _cost0(T: float, x0: tuple[float, float, float, float], z: tuple[float, float, float, float]) -> float:
    out = 0.0
    for (p0, v0), (pf, vf) in (((x0[0], x0[1]), (z[0], z[1])), ((x0[2], x0[3]), (z[2], z[3]))):
        D, dv = pf - p0 - v0 * T, vf - v0
        out += 6 * D * D / T**3 - 6 * D * dv / T**2 + 2 * dv * dv / T
    return out


def _hessian(T: float) -> FloatArray:
    H = np.array([[12 / T**3, -6 / T**2], [-6 / T**2, 4 / T]])
    Q = np.zeros((4, 4))
    Q[:2, :2] = H
    Q[2:, 2:] = H
    return Q


def solve_small_qp(Q: FloatArray, c: FloatArray, A: FloatArray, b: FloatArray, max_active: int = 4,
                   tol: float = 1e-9, first: tuple[tuple[int, ...], ...] = ()) -> FloatArray | None:
    r"""Minimise :math:`\tfrac12 (z - c)^\top Q (z - c)` subject to :math:`A z \le b` exactly
    (``Q`` positive definite): every active set of at most ``max_active`` rows, smallest first;
    the first KKT point that is primal and dual feasible is the optimum (a strictly convex QP
    has one).

    Parameters
    ----------
    Q : (n, n) array
        Positive definite.
    c : (n,) array
        The unconstrained minimiser.
    A, b : (m, n), (m,) arrays
        The rows.
    max_active : int
        Largest active set tried (``n`` suffices when the rows are in general position).
    tol : float
        Feasibility tolerance.
    first : tuple of tuple of int
        Active sets to try before the enumeration (a guess, e.g. a similar QP's active rows);
        the answer does not depend on them, only the number of linear solves.

    Returns
    -------
    (n,) array or None
        The minimiser, or None when no active set gives a feasible KKT point (infeasible rows).
    """
    n, m = Q.shape[0], A.shape[0]
    if m == 0 or np.all(A @ c <= b + tol):
        return c.copy()
    r = b - A @ c  # rows in y = z - c: A y <= r
    guesses = (tuple(W) for W in first if 0 < len(W) <= min(max_active, n) and all(0 <= i < m for i in W))
    every = (W for size in range(1, min(max_active, n, m) + 1) for W in itertools.combinations(range(m), size))
    for W in itertools.chain(guesses, every):
        Aw = A[list(W)]
        size = len(W)
        K = np.zeros((n + size, n + size))
        K[:n, :n] = Q
        K[:n, n:] = Aw.T
        K[n:, :n] = Aw
        rhs = np.concatenate([np.zeros(n), r[list(W)]])
        try:
            sol = np.linalg.solve(K, rhs)
        except np.linalg.LinAlgError:
            continue
        y, lam = sol[:n], sol[n:]
        if np.all(lam >= -tol) and np.all(A @ y <= r + tol * (1 + np.abs(r))):
            return np.asarray(c + y, dtype=float)
    return None


def _active_guesses(A: FloatArray, b: FloatArray, z: FloatArray, new: int) -> tuple[tuple[int, ...], ...]:
    """Likely active sets of a QP whose row ``new`` was added to rows ``A z <= b`` at whose
    minimiser ``z`` the active rows are known: those rows with ``new``, then subsets of them."""
    act = [int(i) for i in np.flatnonzero(np.abs(A @ z - b) <= 1e-7 * (1 + np.abs(b))) if i != new][:4]
    out: list[tuple[int, ...]] = []
    for size in range(len(act), -1, -1):
        for sub in itertools.combinations(act, size):
            out.append((*sub, new))
    return tuple(out)


def _cone(e: GoalElement, piece: Piece, margin_scale: float) -> tuple[float, float]:
    """The interval of the final heading relative to the lane at the piece's centre [rad]
    (module docstring: the goal's orientation less its margin, or the free one); empty when
    ``lo > hi``."""
    if e.orientation is None:
        return -FREE_REL_HEADING_RAD, FREE_REL_HEADING_RAD
    lo = _wrap(e.orientation[0] - piece.lane_heading)
    hi = lo + (e.orientation[1] - e.orientation[0])
    mh = HEADING_MARGIN_RAD * margin_scale
    if hi - lo > 2 * mh:
        lo, hi = lo + mh, hi - mh
    else:
        lo = hi = 0.5 * (lo + hi)
    return max(lo, -MAX_REL_HEADING_RAD), min(hi, MAX_REL_HEADING_RAD)


def goal_rows(region: GoalRegion, cand: Candidate, x0: tuple[float, float, float, float],
              margin_scale: float = 1.0) -> tuple[FloatArray, FloatArray]:
    """The linear rows ``A z <= b`` of the final state ``z = (s, vs, d, vd)`` of ``cand``'s goal
    state, position piece and horizon (position, speed and heading cone with the margins at
    ``margin_scale``): the region a planner may move ``cand``'s final state in.

    Parameters
    ----------
    region : GoalRegion
    cand : Candidate
    x0 : (float, float, float, float)
        The start (a goal without a position: the piece along the ego's lane depends on it).
    margin_scale : float
        Scale of :data:`POSITION_MARGIN_M`, :data:`SPEED_MARGIN_MPS`, :data:`HEADING_MARGIN_RAD`.

    Returns
    -------
    (A, b) : ((m, 4) array, (m,) array)
    """
    e = region.elements[cand.element]
    piece = region._pieces(e, x0, cand.tf)[cand.piece]
    return _rows(region, e, piece, margin_scale)


def _rows(region: GoalRegion, e: GoalElement, piece: Piece, margin_scale: float,
          drop: str | None = None, d_range: tuple[float, float] | None = None,
          heading_cap: float | None = None) -> tuple[FloatArray, FloatArray]:
    """The linear rows of the final-state QP in ``z = (s, vs, d, vd)`` (module docstring), with
    the final offset kept in ``d_range`` when given and the heading relative to the lane within
    ``±heading_cap`` when given."""
    rows: list[FloatArray] = []
    rhs: list[float] = []
    if d_range is not None:
        if math.isfinite(d_range[0]):
            rows.append(np.array([0.0, 0.0, -1.0, 0.0]))
            rhs.append(-d_range[0])
        if math.isfinite(d_range[1]):
            rows.append(np.array([0.0, 0.0, 1.0, 0.0]))
            rhs.append(d_range[1])
    if drop != "position":
        m = POSITION_MARGIN_M * margin_scale
        for a, bb in zip(piece.A, piece.b):
            rows.append(np.array([a[0], 0.0, a[1], 0.0]))
            rhs.append(float(bb) - m * float(np.hypot(a[0], a[1])))
    scale = 1.0 - piece.curvature * piece.centre[1]
    # the heading cone (relative to the lane at the piece's centre)
    lo, hi = _cone(e if drop != "orientation" else dataclasses.replace(e, orientation=None), piece, margin_scale)
    if heading_cap is not None:
        lo, hi = max(lo, -heading_cap), min(hi, heading_cap)
    if lo <= hi:
        rows += [np.array([0.0, scale * math.tan(lo), 0.0, -1.0]), np.array([0.0, -scale * math.tan(hi), 0.0, 1.0])]
        rhs += [0.0, 0.0]
    else:  # an empty cone: keep it empty
        rows += [np.array([0.0, 0.0, 0.0, 0.0])]
        rhs += [-1.0]
    # the speed interval on the along-road speed; the heading adds at most 1/cos(max |heading|)
    v_lo, v_hi = region.v_range
    if e.speed is not None and drop != "velocity":
        ms = SPEED_MARGIN_MPS * margin_scale
        lo_v, hi_v = e.speed
        if hi_v - lo_v > 2 * ms:
            lo_v, hi_v = lo_v + ms, hi_v - ms
        else:
            lo_v = hi_v = 0.5 * (lo_v + hi_v)
        v_lo, v_hi = max(v_lo, lo_v), min(v_hi, hi_v)
    cos_max = math.cos(max(abs(lo), abs(hi))) if lo <= hi else 1.0
    rows += [np.array([0.0, -scale, 0.0, 0.0]), np.array([0.0, scale, 0.0, 0.0])]
    rhs += [-v_lo, v_hi * cos_max]
    return np.array(rows), np.array(rhs)


def _final_state(region: GoalRegion, e: GoalElement, piece: Piece, x0: tuple[float, float, float, float],
                 T: float, drop: str | None = None,
                 d_range: tuple[float, float] | None = None) -> tuple[float, float, float, float] | None:
    """The cheapest final state of goal state ``e`` in ``piece`` at horizon ``T`` (margins halved
    down to zero where they empty the region; the final offset in ``d_range`` if given), or None."""
    c = np.array([x0[0] + x0[1] * T, x0[1], x0[2] + x0[3] * T, x0[3]])
    Q = _hessian(T)
    for scale in (1.0, 0.5, 0.25, 0.0):
        A, b = _rows(region, e, piece, scale, drop, d_range)
        z = solve_small_qp(Q, c, A, b)
        if z is not None:
            return (float(z[0]), float(z[1]), float(z[2]), float(z[3]))
    return None


def _unreachable(region: GoalRegion, e: GoalElement, x0: tuple[float, float, float, float], dt: float,
                 elapsed: int) -> str | None:
    ks = range(max(e.steps[0], elapsed + 1), e.steps[1] + 1)
    if len(ks) == 0:
        return f"time_step [{e.steps[0]}, {e.steps[1]}] is over (the plan starts at step {elapsed})"
    Ts = [(k - elapsed) * dt for k in ks]
    a = region.a_max
    v_lo, v_hi = region.v_range
    speed0 = math.hypot(x0[1], x0[3])
    if e.speed is not None:
        lo, hi = e.speed
        if hi < v_lo or lo > v_hi:
            return (f"velocity [{lo:.2f}, {hi:.2f}] m/s lies outside the vehicle's speed range "
                    f"[{v_lo:.2f}, {v_hi:.2f}] m/s")
        gap = max(lo - speed0, speed0 - hi, 0.0)
        if gap > a * Ts[-1]:
            return (f"velocity [{lo:.2f}, {hi:.2f}] m/s is out of reach: {gap:.2f} m/s from the initial speed "
                    f"needs {gap / Ts[-1]:.2f} m/s^2 over the whole window (limit {a:.2f})")
    if e.orientation is not None and e.pieces:
        th = e.pieces[0].lane_heading
        lo = _wrap(e.orientation[0] - th)
        hi = lo + (e.orientation[1] - e.orientation[0])
        if hi < -MAX_REL_HEADING_RAD or lo > MAX_REL_HEADING_RAD:
            return (f"orientation [{e.orientation[0]:.3f}, {e.orientation[1]:.3f}] rad points across or against "
                    f"the road (lane heading {th:.3f} rad; the plan may turn at most {MAX_REL_HEADING_RAD} rad "
                    "from it)")
    if e.pieces:
        need = math.inf
        for T in Ts:
            p = np.array([x0[0] + x0[1] * T, x0[2] + x0[3] * T])
            for pc in e.pieces:
                need = min(need, 2 * _distance_to_piece(pc, p) / T**2)
        if need > a:
            return (f"position is out of reach: the nearest point of the goal shape needs {need:.2f} m/s^2 "
                    f"(limit {a:.2f}) at every time of the window")
    if e.pieces is None and not region._pieces(e, x0, Ts[-1]):
        return (f"no position, and the mapped road ends ahead: the body's centre must stay before "
                f"s = {region.s_max:.2f} m, the start is at s = {x0[0]:.2f} m")
    # a common final state of every element (in some piece, at some time)?
    probe_T = Ts[len(Ts) // 2]
    if all(_final_state(region, e, pc, x0, probe_T) is None for pc in region._pieces(e, x0, probe_T)):
        for name in ("orientation", "velocity", "position"):
            if any(_final_state(region, e, pc, x0, probe_T, drop=name) is not None
                   for pc in region._pieces(e, x0, probe_T)):
                return f"{name} admits no final state together with the goal's other elements"
        return "its elements admit no common final state"
    for T in Ts:
        for pc in region._pieces(e, x0, T):
            z = _final_state(region, e, pc, x0, T)
            if z is not None and _within_limits(x0, z, T, a):
                return None
    what = "velocity and position" if e.speed is not None else "position"
    return (f"{what} together are out of reach: the cheapest final state of every time of the window needs more "
            f"than {a:.2f} m/s^2 on one axis (bang-bang bound)")


def _distance_to_piece(pc: Piece, p: FloatArray) -> float:
    """Distance from ``p`` to the convex piece (0 inside); by its vertices' hull edges."""
    viol = pc.A @ p - pc.b
    if np.all(viol <= 0):
        return 0.0
    norms = np.hypot(pc.A[:, 0], pc.A[:, 1])
    return float(np.max(viol / norms))  # a lower bound of the distance (exact off a single edge)


def _hull_piece(frame: RoadFrame, pts_road: FloatArray) -> Piece:
    """The convex hull of road-frame points as rows ``A p <= b``."""
    P = np.unique(np.round(pts_road, 9), axis=0)
    hull = _convex_hull(P)
    A, b = [], []
    for i in range(len(hull)):
        p, q = hull[i], hull[(i + 1) % len(hull)]
        edge = q - p
        n = np.array([edge[1], -edge[0]])  # outward normal of a counter-clockwise hull
        A.append(n)
        b.append(float(n @ p))
    centre = P.mean(axis=0)
    return Piece(np.array(A), np.array(b), (float(centre[0]), float(centre[1])),
                 float(frame.heading(float(centre[0]))), float(frame.curvature(float(centre[0]))))


def _box_piece(frame: RoadFrame, s_lo: float, s_hi: float, d_lo: float, d_hi: float) -> Piece:
    return _hull_piece(frame, np.array([[s_lo, d_lo], [s_hi, d_lo], [s_hi, d_hi], [s_lo, d_hi]]))


def _convex_hull(P: FloatArray) -> FloatArray:
    """Andrew's monotone chain, counter-clockwise."""
    pts = sorted(map(tuple, P))
    if len(pts) <= 2:
        return np.array(pts, dtype=float)

    def cross(o: tuple[float, ...], a: tuple[float, ...], b: tuple[float, ...]) -> float:
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower: list[tuple[float, ...]] = []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    upper: list[tuple[float, ...]] = []
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    return np.array(lower[:-1] + upper[:-1], dtype=float)


def _shape_pieces(frame: RoadFrame, shape: Any) -> list[Piece]:
    """Convex road-frame pieces of a CommonRoad shape (rectangle, polygon, circle, group)."""
    kind = type(shape).__name__
    if kind == "ShapeGroup":
        return [p for sh in shape.shapes for p in _shape_pieces(frame, sh)]
    if kind == "Circle":
        a = np.linspace(0.0, 2 * math.pi, 8, endpoint=False)  # the inscribed octagon
        pts = np.asarray(shape.center, dtype=float) + float(shape.radius) * np.stack([np.cos(a), np.sin(a)], axis=1)
    else:
        pts = np.asarray(shape.vertices, dtype=float)
    return [_hull_piece(frame, frame.to_road(pts))]


def _lanelet_pieces(frame: RoadFrame, lanelet: Any) -> list[Piece]:
    """A lanelet cut into trapezoids of at most :data:`LANELET_PIECE_M` along the road."""
    r = frame.to_road(np.asarray(lanelet.right_vertices, dtype=float))
    lf = frame.to_road(np.asarray(lanelet.left_vertices, dtype=float))
    r, lf = r[np.argsort(r[:, 0])], lf[np.argsort(lf[:, 0])]
    s_lo, s_hi = max(r[0, 0], lf[0, 0]), min(r[-1, 0], lf[-1, 0])
    if s_hi <= s_lo:
        return []
    n = max(1, int(math.ceil((s_hi - s_lo) / LANELET_PIECE_M)))
    cuts = np.linspace(s_lo, s_hi, n + 1)
    out = []
    for a, b in zip(cuts[:-1], cuts[1:]):
        ra, rb = float(np.interp(a, r[:, 0], r[:, 1])), float(np.interp(b, r[:, 0], r[:, 1]))
        la, lb = float(np.interp(a, lf[:, 0], lf[:, 1])), float(np.interp(b, lf[:, 0], lf[:, 1]))
        lo_d, hi_d = sorted((ra, la)), sorted((rb, lb))
        out.append(_hull_piece(frame, np.array([[a, lo_d[0]], [b, hi_d[0]], [b, hi_d[1]], [a, lo_d[1]]])))
    return out


def read_goal(pp: Any, network: Any, frame: RoadFrame, ego_lane: tuple[float, float],
              v_range: tuple[float, float], a_max: float) -> GoalRegion:
    """The goal region of planning problem ``pp`` in ``frame`` (module docstring).

    Parameters
    ----------
    pp : commonroad.planning.planning_problem.PlanningProblem
    network : commonroad.scenario.lanelet.LaneletNetwork
    frame : RoadFrame
    ego_lane : (float, float)
        Lateral bounds of the ego's lane at its start (a goal without position keeps it).
    v_range : (float, float)
        The vehicle's speed range [m/s].
    a_max : float
        The vehicle's largest acceleration [m/s²].

    Returns
    -------
    GoalRegion
    """
    lanelet_ids = dict(pp.goal.lanelets_of_goal_position or {})
    elements = []
    for i, st in enumerate(pp.goal.state_list):
        ts = st.time_step
        steps = (int(ts.start), int(ts.end)) if hasattr(ts, "start") else (int(ts), int(ts))
        speed = (float(st.velocity.start), float(st.velocity.end)) if st.has_value("velocity") else None
        orient = (float(st.orientation.start), float(st.orientation.end)) if st.has_value("orientation") else None
        pieces: list[Piece] | None = None
        ids: tuple[int, ...] = ()
        if i in lanelet_ids:
            ids = tuple(int(x) for x in lanelet_ids[i])
            pieces = [p for lid in ids for p in _lanelet_pieces(frame, network.find_lanelet_by_id(lid))]
        elif st.has_value("position"):
            pieces = _shape_pieces(frame, st.position)
        elements.append(GoalElement(i, steps, speed, orient, pieces, st, ids))
    return GoalRegion(elements, frame, ego_lane, v_range, a_max)
