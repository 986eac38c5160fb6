r"""The decision layer: which gap, and whether a plan into it may be driven (SPEC §15).

It is the same for every iamp planner and knows nothing about how a planner works: it builds
one lane-change :class:`~iamp.core.problem.Problem` per candidate gap, calls the planner, and
accepts the **first** gap whose plan is

1. **verified** — status ``optimal`` or ``local`` (the planner checked its own residuals);
2. **within the limits** — the plan's peaks (sampled every ``check_dt``) inside
   :data:`~iamp.core.physical.PASSENGER_CAR`'s ``ax``, ``ay``, ``a_total`` and ``vx``
   (the jerk bound is measured on the executed trajectory but not used here: the paper's
   PMP input jumps at its contact times by construction, so every constrained PMP plan
   would fail it);
2b. **drivable** — the plan's path turns no tighter than a car's turning radius and does not
   start sideways (:mod:`iamp.simulation.kinematics`, ``kappa_max``; reason ``kinematics``);
3. **intrusion-free** — :func:`iamp.core.safety.safety_report` of the plan's own continuous
   trajectory against *every* predicted neighbour in the two lanes within ``relevant_m``
   (not only the constrained ones) says the ego's point never enters a safety region.

Candidate gaps
--------------
The target-lane vehicles within ``relevant_m`` (or, with :attr:`DecisionConfig.rss`, within
their RSS distance of the ego plus a margin) sorted by ``x`` bound gaps (the first and
last open-ended).  Each gap ``(f, l)`` is scored by how far its usable middle at ``T`` is from
where the ego would be at constant speed, ``x_0 + v_{x,0} T``; the ``max_gaps`` nearest are
tried, nearest first.

The problem for one gap
-----------------------
After ``T = horizon_s`` the ego is at the target lane's centre ``y_f`` with ``v_{y,f}=0`` and

* ``v_{x,f}`` = the mean predicted speed of ``f`` and ``l`` at ``T`` (those that exist; the
  ego's own speed if neither), clipped to what ``REACH = 0.8`` of the ``a_x`` bounds held for
  ``T`` reaches, ``v_{x,0} + 0.8 [a_{x,min}, a_{x,max}] T`` (a slow on-ramp entry cannot match
  the main road's speed in one horizon), and to ``[0, speed_cap]``;
* ``x_f`` = the constant-acceleration end point ``x_0 + (v_{x,0} + v_{x,f})T/2`` moved into
  the part of the predicted gap at ``T`` that leaves a bumper-to-bumper headway
  ``headway_s·v_{x,f}`` to ``f`` and ``l`` (its middle if the gap is shorter).

The problem carries ``cfg.limits`` (:data:`~iamp.core.physical.PASSENGER_CAR`) as
``Problem.limits``.  The constraint set (a change to the left, +y; mirrored to the right): the target-lane
follower ``f`` → ``front-lower``, the target-lane leader ``l`` → ``rear-lower``, the current
lane's leader ``c`` → ``rear-upper``; safety region ``S_x × S_y`` (SPEC §8: 5 m, 0.5 m)
around each body.  A vehicle whose corner the ego has already passed laterally is met and
left out.  If the ego already stands closer than ``S_x`` behind ``c`` (a queue), ``c``'s
region is shrunk to the present gap less 0.5 m so that a plan is judged on not closing in.
For a planner that imposes every vehicle as the paper's equality (``cfg.equality``: ``pmp``,
``qp``) the problem keeps only the corners in the way (:func:`corners_in_the_way`): the vehicles
whose region the unconstrained cubic enters, one per side, the deepest.

The ego in the forecast (optional)
----------------------------------
Given ``react`` (``simulate --ego-in-forecast``), each candidate gap with a follower ``f`` is
planned by the fixed-point iteration of
:func:`iamp.prediction.leader.ego.iterate_with_planner`: plan against ``f``'s cubic ``c_k``,
predict ``c_{k+1} = P(c_k)`` = ``f`` following the nearer of its leader and that plan
(``react``), re-plan, at most ``react_iter`` re-plans, stopping when
``max_{t∈[0,T]} |c_{k+1}(t) - c_k(t)| < react_tol_m``.  The plan returned is the one made
against the last cubic planned for, and the §9 check sees ``f`` with that cubic.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from iamp.core.free import FreeTrajectory
from iamp.core.physical import PASSENGER_CAR, PhysicalLimits
from iamp.core.plan import Plan
from iamp.core.problem import EgoBoundary, Problem, SurroundingVehicle
from iamp.core.safety import SAFETY_TOLERANCE_M, safety_report
from iamp.core.status import SUCCESS
from iamp.prediction.leader.ego import iterate_with_planner
from iamp.simulation.kinematics import KAPPA_MAX, STOP_HEADING_MAX, TOL_REL, sampled_turning, stop_heading
from iamp.simulation.rss import RssParameters, within_rss_reach

#: A :class:`Problem` holds at most 8 vehicles: the §9 check takes the nearest ones.
MAX_CHECKED = 8
#: The end speed is reachable at this fraction of the ``a_x`` bounds held over the horizon.
REACH = 0.8


@dataclass(frozen=True, init=False)
class Neighbour:
    """A predicted neighbour: ``x(t) = Σ poly[k] t^k`` from now, its lateral centre and body."""

    name: str
    poly: tuple[float, ...]
    y: float
    length: float
    width: float
    lane: int
    vy: float = 0.0  # observed lateral speed (one-step difference), for the body check's sweep
    #: The observed state now, as the monitor's RSS judge measures it: centre ``x``, longitudinal
    #: speed ``v cos ψ`` and heading ``ψ`` (SUMO's); ``None`` where only the prediction is known.
    #: The prediction's cubic starts within about 0.5 m/s of it (a car braking at 2 m/s² while it
    #: changed lanes behind the ego: its RSS distance 1.1 m shorter than the judge's).
    now: tuple[float, float, float] | None = None

    def __init__(self, name: str, poly: tuple[float, ...], y: float, length: float, width: float, lane: int,
                 vy: float = 0.0, now: tuple[float, float, float] | None = None) -> None:
        # the dataclass's own ``__init__`` with the fields written straight into the instance's dict:
        # a frozen dataclass's generated one sets each through ``object.__setattr__`` (about twice the
        # time; the loop builds thousands of neighbours per episode); the same attributes, in field order
        d = self.__dict__
        d["name"] = name
        d["poly"] = poly
        d["y"] = y
        d["length"] = length
        d["width"] = width
        d["lane"] = lane
        d["vy"] = vy
        d["now"] = now

    def x(self, t: float) -> float:
        return horner(self._position_poly, t)

    def x_now(self) -> float:
        """The observed centre now (:attr:`now`), else the prediction's ``x(0)``."""
        return self.now[0] if self.now is not None else self.x(0.0)

    def v_now(self) -> float:
        """The observed longitudinal speed now (:attr:`now`), else the prediction's ``v(0)``."""
        return self.now[1] if self.now is not None else self.v(0.0)

    def v(self, t: float) -> float:
        return horner(self._velocity_poly, t)

    @functools.cached_property
    def _position_poly(self) -> tuple[float, ...]:
        """:attr:`poly` as Python floats (:func:`float_coefficients`), once per neighbour (the loop asks for
        positions thousands of times per episode)."""
        return float_coefficients(self.poly)

    @functools.cached_property
    def _velocity_poly(self) -> tuple[float, ...]:
        """:func:`poly_derivative` of :attr:`poly` (Python floats), once per neighbour (the loop asks for
        speeds thousands of times per episode)."""
        return poly_derivative(self.poly)


def poly_derivative(poly: Sequence[float]) -> tuple[float, ...]:
    """The coefficients of ``d/dt Σ poly[k] t^k``: ``k poly[k]`` for ``k >= 1`` (``(0.0,)`` for a
    constant), the same floats as ``numpy.polynomial.polynomial.polyder``.

    Parameters
    ----------
    poly : sequence of float
        Coefficients, lowest power first (at least one).

    Returns
    -------
    tuple of float
    """
    if len(poly) < 2:
        return (float(poly[0]) * 0,)
    return tuple(k * float(poly[k]) for k in range(1, len(poly)))


def clip_scalar(x: float, lo: float, hi: float) -> float:
    """``float(np.clip(x, lo, hi))`` of three numbers without the arrays (the loop clips a few thousand
    scalars per episode): numpy's rule for floats, bit for bit — a ``nan`` bound is the result (the lower
    one first), else a ``nan`` ``x``; otherwise ``x`` raised to ``lo`` unless ``x >= lo`` and then lowered to
    ``hi`` unless ``<= hi`` (so ``-0.0`` stays ``-0.0`` between zero bounds, and ``lo > hi`` gives ``hi``).

    Parameters
    ----------
    x, lo, hi : float

    Returns
    -------
    float
    """
    if lo != lo:
        return float(lo)
    if hi != hi:
        return float(hi)
    if x != x:
        return float(x)
    m = x if x >= lo else lo
    return float(m if m <= hi else hi)


def float_coefficients(poly: Sequence[float]) -> tuple[float, ...]:
    """``poly``'s coefficients as Python floats (``float`` of each), the input of :func:`horner`."""
    return tuple([float(c) for c in poly])


def horner(coefficients: tuple[float, ...], t: float) -> float:
    """``Σ c[k] t^k`` of Python float coefficients (:func:`float_coefficients`, lowest power first, at least
    one) at a scalar ``t`` by Horner's rule in the order of ``numpy.polynomial.polynomial.polyval`` (the same
    float, bit for bit, without its per-call array overhead: the loop evaluates neighbours' cubics
    thousands of times per episode; a neighbour converts its coefficients once).

    Parameters
    ----------
    coefficients : tuple of float
        Python floats, lowest power first.
    t : float

    Returns
    -------
    float
    """
    if len(coefficients) == 4:  # a neighbour's cubic: the loop below unrolled (the same operations)
        c0, c1, c2, c3 = coefficients
        return float(c0 + (c1 + (c2 + (c3 + t * 0) * t) * t) * t)
    if len(coefficients) == 3:  # its speed
        c0, c1, c2 = coefficients
        return float(c0 + (c1 + (c2 + t * 0) * t) * t)
    acc = coefficients[-1] + t * 0
    for k in range(len(coefficients) - 2, -1, -1):
        acc = coefficients[k] + acc * t
    return float(acc)


def poly_value(poly: Sequence[float], t: float) -> float:
    """``Σ poly[k] t^k`` at a scalar ``t`` by Horner's rule in the order of
    ``numpy.polynomial.polynomial.polyval`` (the same float, bit for bit, without its per-call
    array overhead): :func:`horner` of :func:`float_coefficients`.

    Parameters
    ----------
    poly : sequence of float
        Coefficients, lowest power first (at least one).
    t : float

    Returns
    -------
    float
    """
    return horner(float_coefficients(poly), t)


@dataclass(frozen=True)
class EgoNow:
    """The ego's centre state now."""

    x: float
    vx: float
    y: float
    vy: float
    length: float = 4.8
    width: float = 1.8


@dataclass(frozen=True)
class Gap:
    """A gap of the target lane: its follower and leader (None: open at that end).

    ``speed`` is the lane's speed for a gap with neither [m/s] (the closed loop: the road's speed
    limit, at which traffic from beyond the view arrives); None: the ego's own speed
    (:func:`iamp.simulation.tactical.gap_speed`).
    """

    follower: Neighbour | None
    leader: Neighbour | None
    speed: float | None = None


@dataclass(frozen=True)
class DecisionConfig:
    """Parameters of the decision layer (module docstring)."""

    horizon_s: float = 5.0
    #: SPEC §8's region around each neighbour's body (the closed loop uses :data:`BODY_REGION`).
    safety_x: float = 5.0
    safety_y: float = 0.5
    headway_s: float = 1.0
    relevant_m: float = 60.0
    max_gaps: int = 3
    speed_cap: float = 40.0
    check_dt: float = 0.01
    limits: PhysicalLimits = field(default=PASSENGER_CAR)
    #: The largest curvature of a plan's path [1/m] (a car's turning radius,
    #: :mod:`iamp.simulation.kinematics`; None: not tested).
    kappa_max: float | None = KAPPA_MAX
    #: The largest angle to the road [rad] a plan may leave the ego standing at
    #: (:func:`iamp.simulation.kinematics.stop_heading`; tested with ``kappa_max``).
    stop_heading_max: float = STOP_HEADING_MAX
    #: The planner imposes every vehicle of its problem as the paper's corner *equality* (``pmp``,
    #: ``qp``; the registry's ``constraint == "equality"``): the problem carries only the corners in
    #: the way (:func:`corners_in_the_way`).
    equality: bool = False
    #: With RSS's parameters (the closed loop, SPEC §17), a target-lane vehicle beyond
    #: ``relevant_m`` still bounds a gap while it is within its RSS distance of the ego plus
    #: :data:`~iamp.simulation.rss.RSS_REACH_MARGIN_M` (:func:`~iamp.simulation.rss.within_rss_reach`:
    #: a fast follower far behind); None: ``relevant_m`` alone.
    rss: RssParameters | None = None


def _near(n: Neighbour, ego: EgoNow, cfg: DecisionConfig) -> bool:
    """``n`` within ``relevant_m`` of the ego, or within its RSS reach (:attr:`DecisionConfig.rss`)."""
    dx = n.x(0.0) - ego.x
    if abs(dx) <= cfg.relevant_m:
        return True
    return cfg.rss is not None and within_rss_reach(dx, n.length, n.v(0.0), ego.vx, ego.length, cfg.rss)


#: ``(safety_x, safety_y)`` of the closed loop (SPEC §17): the region around each neighbour's body
#: contains the ego's body at a heading up to 5°: half the ego's length (2.4 m) + 1 m, half its
#: width (0.9 m) + 0.3 m; along ``x`` the RSS-sized regions of
#: :func:`iamp.simulation.tactical.rss_regions` replace it for the constrained vehicles.
BODY_REGION = (3.5, 1.2)


@dataclass
class Verdict:
    """What the layer concluded about one plan: ``accepted`` or the first failed test."""

    accepted: bool
    reason: str  # "accepted", "failed:<status>", "limits:<field>", "intrusion:<vehicle>"
    plan: Plan | None = None
    gap: Gap | None = None
    problem: Problem | EgoBoundary | None = None
    check: Problem | None = None


def candidate_gaps(ego: EgoNow, target: Sequence[Neighbour], cfg: DecisionConfig) -> list[Gap]:
    """The ``max_gaps`` gaps of the target lane nearest the ego's constant-speed end point."""
    T = cfg.horizon_s
    near = sorted((n for n in target if _near(n, ego, cfg)), key=lambda n: n.x(0.0))
    bounds: list[Neighbour | None] = [None, *near, None]
    gaps = [Gap(bounds[k], bounds[k + 1]) for k in range(len(bounds) - 1)]
    x_cs = ego.x + ego.vx * T

    def score(g: Gap) -> float:
        lo = -np.inf if g.follower is None else g.follower.x(T) + g.follower.length / 2 + ego.length / 2
        hi = np.inf if g.leader is None else g.leader.x(T) - g.leader.length / 2 - ego.length / 2
        if lo <= x_cs <= hi:
            return 0.0
        return float(min(abs(x_cs - lo), abs(x_cs - hi)))

    return sorted(gaps, key=score)[: cfg.max_gaps]


def end_state(ego: EgoNow, gap: Gap, cfg: DecisionConfig, T: float) -> tuple[float, float]:
    """``(x_f, v_{x,f})`` into ``gap`` after ``T`` (module docstring)."""
    speeds = [n.v(T) for n in (gap.follower, gap.leader) if n is not None]
    vxf = float(np.mean(speeds)) if speeds else ego.vx
    ax = cfg.limits.ax or (-np.inf, np.inf)  # reachable at a constant REACH of the a_x bounds
    vxf = clip_scalar(vxf, ego.vx + REACH * ax[0] * T, ego.vx + REACH * ax[1] * T)
    vxf = clip_scalar(vxf, 0.0, cfg.speed_cap)
    x = ego.x + (ego.vx + vxf) * T / 2
    head = cfg.headway_s * vxf
    lo = -np.inf if gap.follower is None else gap.follower.x(T) + gap.follower.length / 2 + ego.length / 2
    hi = np.inf if gap.leader is None else gap.leader.x(T) - gap.leader.length / 2 - ego.length / 2
    if hi - lo >= 2 * head:
        x = clip_scalar(x, lo + head, hi - head)
    else:
        x = float((lo + hi) / 2)
    return x, vxf


def _vehicle(n: Neighbour, corner: str, cfg: DecisionConfig, safety_x: float | None = None) -> SurroundingVehicle:
    return SurroundingVehicle(n.poly, corner, n.y, n.length, n.width,
                              cfg.safety_x if safety_x is None else safety_x, cfg.safety_y, name=n.name)


#: ``region(vehicle, role, boundary) -> safety_x``: the length of a constrained vehicle's safety
#: region (``role`` ``"follower"``, ``"leader"`` or ``"current"``), e.g. RSS-sized
#: (:func:`iamp.simulation.tactical.rss_regions`); ``None``: ``cfg.safety_x``.
Region = Callable[[Neighbour, str, EgoBoundary], float]


def lane_change_problem(ego: EgoNow, y_target: float, gap: Gap, current_leader: Neighbour | None,
                        cfg: DecisionConfig, T: float, end: tuple[float, float] | None = None,
                        region: Region | None = None) -> Problem | EgoBoundary:
    """The problem into ``gap`` over ``T`` with the constraint set of the module docstring
    (an :class:`EgoBoundary` when no vehicle is left to constrain); ``region`` sizes each
    vehicle's region along ``x`` (:data:`Region`)."""
    d = 1.0 if y_target > ego.y else -1.0
    xf, vxf = end if end is not None else end_state(ego, gap, cfg, T)
    boundary = EgoBoundary(tf=T, x0=ego.x, y0=ego.y, vx0=ego.vx, vy0=ego.vy, xf=xf, yf=y_target, vxf=vxf, vyf=0.0)
    low, up = ("lower", "upper") if d > 0 else ("upper", "lower")
    vehicles: list[SurroundingVehicle] = []
    for n, corner, role in ((gap.follower, "front-" + low, "follower"), (gap.leader, "rear-" + low, "leader"),
                            (current_leader, "rear-" + up, "current")):
        if n is None:
            continue
        sx = None if region is None else region(n, role, boundary)
        if n is current_leader:
            gap_now = n.x(0.0) - n.length / 2 - ego.x
            if gap_now < (cfg.safety_x if sx is None else sx):
                sx = max(gap_now - 0.5, 0.0)
        sv = _vehicle(n, corner, cfg, sx)
        if d * (ego.y - sv.corner_y) < 0:  # not yet passed laterally
            vehicles.append(sv)
    if not vehicles:
        return boundary
    prob = Problem(boundary, tuple(vehicles), "lane-change", cfg.limits)
    return corners_in_the_way(prob) if cfg.equality else prob


def corners_in_the_way(problem: Problem, tolerance_m: float = SAFETY_TOLERANCE_M) -> Problem | EgoBoundary:
    r"""The problem for a planner that imposes each vehicle as the paper's corner **equality**:
    only the corners in the way.

    The equality makes the ego *pass through* the corner (SPEC §1). Two kinds of corner make it
    ask the impossible of a car:

    * a corner the unconstrained plan (the minimum-energy cubic to the same end state) stays clear
      of: the equality drags the ego back to it (SPEC §2 identity 4, the dragging sign) -- in the
      loop typically a target-lane follower already far behind, reached only by braking beyond the
      ``a_x`` bounds or by reversing, so with the car's limits no contact time admits a plan
      (merge, dense, seed 1: 53 of 62 follower-only problems ``infeasible``);
    * two corners on the same side of the ego's lateral path (a gap's follower ``front-lower`` and
      leader ``rear-lower``, both at the target lane's edge less ``S_y``): a lateral motion crosses
      that line once, so it would have to be at two places at once (exactly so when their ``y``
      agree); only a lateral wiggle through the line three times meets both, which the ``a_y``
      bounds forbid (merge, dense, seed 1: 292 of 311 problems, all ``infeasible``).

    So a vehicle is kept only if the cubic enters its safety region deeper than ``tolerance_m``
    (the §9 report, exact), and of the vehicles kept on one side (``lower``/``upper``) only the one
    entered deepest. The others are left to the decision layer's test of the plan (the §9 report or
    the body, RSS and fail-safe verification), as a vehicle already passed laterally is.

    Parameters
    ----------
    problem : Problem
        The lane-change problem with every constrained vehicle.
    tolerance_m : float
        Depth up to which entering a region is a touch (:data:`~iamp.core.safety.SAFETY_TOLERANCE_M`).

    Returns
    -------
    Problem or EgoBoundary
        The problem with the vehicles in the way (same order), or its boundary when none is.
    """
    rep = safety_report(problem, FreeTrajectory.of(problem.ego))
    best: dict[str, tuple[float, int]] = {}
    for k, (v, s) in enumerate(zip(problem.vehicles, rep.vehicles)):
        if not s.unsafe_beyond(tolerance_m):
            continue
        side = v.corner.split("-")[1]
        if side not in best or s.max_intrusion_m > best[side][0]:
            best[side] = (s.max_intrusion_m, k)
    keep = sorted(k for _, k in best.values())
    if not keep:
        return problem.ego
    if len(keep) == problem.m:
        return problem
    return problem.with_vehicles(problem.vehicles[k] for k in keep)


def check_problem(boundary: EgoBoundary, ego: EgoNow, neighbours: Sequence[Neighbour], lanes: Sequence[int],
                  cfg: DecisionConfig) -> Problem | None:
    """The ``MAX_CHECKED`` neighbours in ``lanes`` within ``relevant_m`` nearest the ego, as
    vehicles for the §9 report (a :class:`Problem` holds at most 8)."""
    vs = []
    near = sorted((n for n in neighbours if n.lane in lanes and abs(n.x(0.0) - ego.x) <= cfg.relevant_m),
                  key=lambda n: abs(n.x(0.0) - ego.x))[:MAX_CHECKED]
    for n in near:
        sx = cfg.safety_x
        ahead_same = n.lane == lanes[0] and n.x(0.0) > ego.x and abs(n.y - ego.y) < (n.width + ego.width) / 2
        if ahead_same:
            gap_now = n.x(0.0) - n.length / 2 - ego.x
            if gap_now < cfg.safety_x:
                sx = max(gap_now - 0.5, 0.0)
        vs.append(_vehicle(n, "rear-upper", cfg, sx))
    return Problem(boundary, tuple(vs)) if vs else None


def check_times(tf: float, dt: float) -> np.ndarray:
    """The sample times of :func:`limit_violations` on ``[0, tf]`` (every ``dt`` and both ends)."""
    return np.linspace(0.0, tf, max(int(np.ceil(tf / dt)), 1) + 1)


def limit_violations(trajectory: Any, tf: float, limits: PhysicalLimits, dt: float = 0.01,
                     tol: float = 1e-6) -> list[str]:
    """Names of the bounds (``ax``, ``ay``, ``a_total``, ``vx``) a trajectory breaks on ``[0, tf]``
    (sampled every ``dt`` and at both ends)."""
    t = check_times(tf, dt)
    X = np.asarray(trajectory.states(t))
    U = np.asarray(trajectory.inputs(t))
    return limit_violations_of(U[:, 0], U[:, 1], X[:, 1], limits, tol)


def _outside(low: Any, high: Any, rng: tuple[float, float], tol: float) -> Any:
    """``low`` below ``rng[0] - tol`` or ``high`` above ``rng[1] + tol`` (elementwise for arrays; ``nan``
    breaks nothing)."""
    return (low < rng[0] - tol) | (high > rng[1] + tol)


def limit_violations_of(ax: np.ndarray, ay: np.ndarray, vx: np.ndarray, limits: PhysicalLimits,
                        tol: float = 1e-6) -> list[str]:
    """Which of ``ax``, ``ay``, ``a_total``, ``vx`` the samples break."""
    bad = []
    for name, values in (("ax", ax), ("ay", ay), ("vx", vx)):
        rng = getattr(limits, name)
        if rng is not None and values.size and _outside(values.min(), values.max(), rng, tol):
            bad.append(name)
    if limits.a_total is not None and ax.size and float(np.max(np.hypot(ax, ay))) > limits.a_total + tol:
        bad.append("a_total")
    return bad


def limit_violation_samples(ax: np.ndarray, ay: np.ndarray, vx: np.ndarray, limits: PhysicalLimits,
                            tol: float = 1e-6) -> np.ndarray:
    """Per sample ``k`` (``ax``, ``ay``, ``vx`` of one length), whether it breaks a limit on its own:
    ``bool(limit_violations_of(ax[k:k+1], ay[k:k+1], vx[k:k+1], limits, tol))`` for every ``k`` in one
    pass (a sample's minimum and maximum are itself; the monitor counts the executed steps that break one).

    Returns
    -------
    numpy.ndarray
        Booleans, the shape of ``ax``.
    """
    bad = np.zeros(np.shape(ax), dtype=bool)
    for name, values in (("ax", ax), ("ay", ay), ("vx", vx)):
        rng = getattr(limits, name)
        if rng is not None:
            bad |= _outside(values, values, rng, tol)
    if limits.a_total is not None:
        bad |= np.hypot(ax, ay) > limits.a_total + tol
    return bad


#: ``verify(plan) -> "accepted" | "rss:<vehicle>"``: the body, RSS and fail-safe test of
#: :mod:`iamp.simulation.failsafe` (it replaces the §9 point check when given).
Verify = Callable[[Plan], str]


def judge(plan: Plan, check: Problem | None, cfg: DecisionConfig, verify: Verify | None = None,
          heading: float | None = None) -> str:
    """``"accepted"`` or the first failed test (``failed:``, ``limits:``, ``kinematics``, ``intrusion:``,
    ``rss:``); ``kinematics``: the path turns tighter than ``cfg.kappa_max``, starts off the
    ego's ``heading`` (its velocity's direction when it moves, else the heading it stopped with) or
    ends off its last velocity's direction (:func:`iamp.simulation.kinematics.sampled_turning` on
    the states the limits are checked on), or leaves the ego standing at more than
    ``cfg.stop_heading_max`` to the road (:func:`iamp.simulation.kinematics.stop_heading`).

    With ``verify`` the safety test is ``verify(plan)`` (the ego's body, RSS distances and a
    verified fail-safe, :mod:`iamp.simulation.failsafe`) instead of the §9 report of the ego's
    centre point against ``check``.
    """
    if plan.status not in SUCCESS or plan.trajectory is None:
        return f"failed:{plan.status}"
    tf = float(plan.problem.tf)
    # the limits and the path's turns on one sampling of the plan (every check_dt and both ends)
    t = check_times(tf, cfg.check_dt)
    X = np.asarray(plan.trajectory.states(t))
    U = np.asarray(plan.trajectory.inputs(t))
    bad = limit_violations_of(U[:, 0], U[:, 1], X[:, 1], cfg.limits)
    if bad:
        return "limits:" + ",".join(bad)
    if cfg.kappa_max is not None:
        # the path a car can drive: no sideways start, no turn tighter than its turning radius
        kappa = sampled_turning(X, heading)
        if kappa.size and float(kappa.max()) > cfg.kappa_max * (1.0 + TOL_REL):
            return "kinematics"
        if stop_heading(X) > cfg.stop_heading_max:  # standing across the road: it drives on along it
            return "kinematics"
    if verify is not None:
        return verify(plan)
    if check is not None:
        rep = safety_report(check, plan.trajectory)
        hit = [v.name for v in rep.vehicles if not v.intrusion_free]
        if hit:
            return "intrusion:" + ",".join(hit)
    return "accepted"


#: ``react(gap, plan, problem)``: the follower's cubic once it reacts to ``plan`` (the ego in the forecast).
React = Callable[[Gap, Plan, Problem | EgoBoundary], tuple[float, ...]]


def decide(ego: EgoNow, y_target: float, target_lane: int, origin_lane: int, neighbours: Sequence[Neighbour],
           planner: Callable[[Problem | EgoBoundary], Plan], cfg: DecisionConfig,
           on_plan: Callable[[Plan, Problem | EgoBoundary], None] | None = None, *,
           react: React | None = None, react_iter: int = 3, react_tol_m: float = 1.0,
           on_iterate: Callable[[dict[str, Any]], None] | None = None,
           verify: Verify | None = None,
           ends: Callable[[Gap], list[tuple[float, tuple[float, float]]]] | None = None,
           gaps: Sequence[Gap] | None = None, region: Region | None = None,
           heading: float | None = None) -> tuple[Verdict, list[Verdict]]:
    """Try the candidate gaps in order; the first accepted verdict (or the last rejection) and all.

    ``planner`` is called once per candidate (without ``react``); ``on_plan`` sees every plan
    (for counting).  With ``react`` a gap with a follower is planned by the iteration of the
    module docstring (at most ``1 + react_iter`` planner calls); ``on_iterate`` receives the
    iteration's record (``iterations``, ``converged``, ``changes_m``, ``plans``).

    ``verify`` replaces the §9 point check (:func:`judge`); ``ends(gap)`` gives the
    ``(T, (x_f, v_f))`` to plan for a gap, best first (:func:`iamp.simulation.tactical.horizons_for`;
    a gap without one is not planned, ``Verdict.reason`` ``"no-safe-end"``), instead of
    ``horizon_s`` and :func:`end_state`; ``gaps`` replaces :func:`candidate_gaps`; ``region``
    sizes the constrained regions (:func:`lane_change_problem`).
    """
    target = [n for n in neighbours if n.lane == target_lane]
    ahead = [n for n in neighbours if n.lane == origin_lane and n.x(0.0) > ego.x
             and n.x(0.0) - ego.x <= cfg.relevant_m]
    current_leader = min(ahead, key=lambda n: n.x(0.0)) if ahead else None
    verdicts: list[Verdict] = []
    for gap in (candidate_gaps(ego, target, cfg) if gaps is None else gaps):
        options: list[tuple[float, tuple[float, float] | None]] = \
            [(cfg.horizon_s, None)] if ends is None else list(ends(gap))
        if not options:
            verdicts.append(Verdict(False, "no-safe-end", None, gap))
        for T, end in options:
            nbs = neighbours
            if react is None or gap.follower is None:
                prob = lane_change_problem(ego, y_target, gap, current_leader, cfg, T, end, region)
                plan = planner(prob)
                if on_plan is not None:
                    on_plan(plan, prob)
            else:
                plan, gap, prob, nbs = _iterate(ego, y_target, gap, current_leader, neighbours, planner, cfg,
                                                on_plan, react, react_iter, react_tol_m, on_iterate)
            boundary = prob.ego if isinstance(prob, Problem) else prob
            check = None if verify is not None else check_problem(boundary, ego, nbs, (origin_lane, target_lane), cfg)
            v = Verdict(False, "", plan, gap, prob, check)
            v.reason = judge(plan, check, cfg, verify, heading)
            v.accepted = v.reason == "accepted"
            verdicts.append(v)
            if v.accepted:
                return v, verdicts
    return (verdicts[-1] if verdicts else Verdict(False, "no gap")), verdicts


def _iterate(ego: EgoNow, y_target: float, gap: Gap, current_leader: Neighbour | None,
             neighbours: Sequence[Neighbour], planner: Callable[[Problem | EgoBoundary], Plan], cfg: DecisionConfig,
             on_plan: Callable[[Plan, Problem | EgoBoundary], None] | None, react: React, max_iter: int,
             tol_m: float, on_iterate: Callable[[dict[str, Any]], None] | None
             ) -> tuple[Plan, Gap, Problem | EgoBoundary, list[Neighbour]]:
    """One gap planned with its follower reacting to the plan (``docs/prediction-interaction.md``)."""
    assert gap.follower is not None
    follower = gap.follower
    plans = 0

    def plan_fn(poly: tuple[float, ...]) -> tuple[Plan, Gap, Problem | EgoBoundary]:
        nonlocal plans
        g2 = replace(gap, follower=replace(follower, poly=poly))
        p2 = lane_change_problem(ego, y_target, g2, current_leader, cfg, cfg.horizon_s)
        p = planner(p2)
        plans += 1
        if on_plan is not None:
            on_plan(p, p2)
        return p, g2, p2

    def predict_fn(p: Plan, g2: Gap, p2: Problem | EgoBoundary) -> tuple[float, ...]:
        assert g2.follower is not None
        if p.trajectory is None:
            return g2.follower.poly
        return react(g2, p, p2)

    res = iterate_with_planner(plan_fn, predict_fn, follower.poly, max_iter=max_iter, tol_m=tol_m,
                               tf=cfg.horizon_s)
    plan, g2, prob = res["plan"]
    if on_iterate is not None:
        on_iterate({"iterations": res["iterations"], "converged": res["converged"],
                    "changes_m": list(res["changes_m"]), "plans": plans})
    assert g2.follower is not None
    new_f = g2.follower
    nbs = [new_f if n.name == follower.name else n for n in neighbours]
    return plan, g2, prob, nbs
