r"""``iamp simulate --commonroad FOLDER``: an interactive CommonRoad scenario in closed loop.

The folder holds a CommonRoad scenario (``*.cr.xml``: lanelets, the recorded vehicles, one
planning problem) and its SUMO configuration (``*.sumo.cfg`` with the network and the routes
of the other vehicles).  SUMO drives the other vehicles (they react to the ego); iamp drives
the ego:

1. The ego is inserted at the planning problem's initial state (position, heading, speed) and
   moved by iamp every SUMO step (``moveToXY``, SUMO's speed and lane-change logic off).  SUMO
   gets the routes with an edge repeated right after itself collapsed (:func:`repaired_routes`):
   it refuses such a route and would stop the vehicle at the end of that edge for good.
2. Every ``replan_s`` the ego observes every vehicle (SUMO's positions, the body from SUMO's
   vehicle type), turns each one's observed longitudinal history (at most the last 3 s, in the
   road frame of :mod:`iamp.commonroad.convert`) into a cubic with the §7 predictor (constant
   speed while fewer than ``min_history_s`` have been observed), keeps its lateral box (lane
   kept; a vehicle observed at most :data:`STANDING_MPS` fast may turn its nose in, its box
   grows across the road by :data:`TURN_IN_MPS` per second, at most :data:`TURN_IN_MAX_M`), and
   plans to the goal with the road planner of :mod:`iamp.commonroad.planning`
   over the goal's remaining time window (:func:`~iamp.commonroad.convert.final_candidates`).
   A replan that finds no safe plan within the limits chooses (:func:`choose`) among the new
   plan, the previous plan's remainder (a fallback) and the fail-safe braking in the lane
   (:func:`failsafe`): the first that keeps clear of every predicted vehicle -- a follower that
   keeps RSS's distance behind the ego is not counted while the option brakes at most RSS's
   ``brake_max`` (:func:`rss_followers`: the rear car is responsible) -- and, among those, the
   one that enters the static road-edge boxes least; the fail-safe itself must also, continued
   to a stop, keep RSS's distance to the vehicle ahead (:func:`rss_stops_behind`).  After a
   fail-safe brake the ego replans at the next step (not after ``replan_s``), toward the goal's
   whole remaining window; when no final state of the window can be reached any more it keeps
   braking safely until the window ends.  The fail-safe that only lets the lateral speed fall
   to zero may instead bring the ego back to its lane's centre (``lane_d``: a car SUMO inserts
   beside a lateral move).  With ``tactical`` (off by default) a goal several lanes over is
   approached one lane at a time (with ``sequences``: first by lane changes planned together
   into a gap of its lane, ``lane_change_sequences``), and a lane change toward the goal's lane is
   also offered where the fail-safe would otherwise brake (:mod:`iamp.commonroad.tactical`: into a
   gap with RSS's stopping distance ahead and a comfortable braking gap behind, finished while it
   still holds; ``lane_changes``).  The predictions always reach at least
   :data:`FAILSAFE_HORIZON_S` ahead.  Every choice is counted
   in time order (``decisions``).
3. The episode ends when CommonRoad's goal test (with the point-mass orientation corrected,
   :mod:`iamp.commonroad.check`) passes for the executed state, or when the goal's time window
   has passed.  :func:`goal_occupancy` then says, from the observed traffic, at which steps of
   the window the goal region had room for the ego's body (and RSS's stopping distance): a goal
   with none could not have been reached without a contact.

Metrics (SPEC §15, measured on what was executed, :func:`iamp.simulation.metrics.episode_metrics`
in the road frame): ``goal_reached`` and ``time_to_goal_s``, collisions (body overlap or SUMO's
report with ``collision.mingap-factor`` 0), ``min_ttc_s``, ``min_gap_m``, the follower's
braking, the ego's peak acceleration, ``limit_violations`` (executed steps above the vehicle's
``a_max``), ``infeasible_plans``, ``fallbacks``, ``failsafe_brakes``, ``edge_grazing_plans`` (new
plans executed though they graze a road-edge box), ``out_of_reach_replans``, ``decisions``,
``road_edge_depth_m`` (the deepest the executed body entered a road-edge box), ``goal_occupancy``
and the planner's time per call (the only wall-clock number: no decision depends on it).

**How SUMO's traffic differs from the recording** (reported as ``sumo_vs_recording``): SUMO
starts each recorded vehicle with its recorded lane, position and speed, then drives it with
its own car-following (Krauss) and lane-change (LC2013) models, which react to the ego; the
recording is what NGSIM's drivers did with the original (absent) ego.  The report gives, per
vehicle present in both, the longitudinal and lateral deviation of SUMO's position from the
recorded one at the same time, and how many vehicles changed lanes in each (a centre moving
more than ``LANE_CHANGE_M`` = 1 m laterally, the recording's definition; the recording over its
goal horizon, SUMO over the episode).
"""

from __future__ import annotations

import dataclasses
import math
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from iamp.commonroad.convert import (
    LANE_CHANGE_M,
    CommonRoadProblem,
    Obstacle,
    _corners,
    ego_margins,
    final_candidates,
    load,
)
from iamp.commonroad.planning import DEFAULT_PLANNER, Intrusion, body_overlap, intrusions, off_road_poses, plan
from iamp.commonroad.tactical import EARLY_MIN_S, LaneMap, Stages, lane_change, sequence, still_holds
from iamp.core.errors import MissingDependencyError, ScenarioError
from iamp.core.plan import Trajectory
from iamp.prediction.predictor import Predictor

#: History kept per observed vehicle [s].
HISTORY_S = 3.0
#: Observed vehicles farther than this along the road are ignored [m].
RANGE_M = 120.0
#: Growth of a predicted vehicle's box along the road, both ways, with the time ahead [m/s]:
#: SUMO's drivers (Krauss, sigma 0.5) wander about the predicted speed.
SPREAD_MPS = 0.5
#: Largest growth of a predicted box [m].
SPREAD_MAX_M = 3.0
#: A vehicle observed at most this fast is "standing" for :data:`TURN_IN_MPS` [m/s].
STANDING_MPS = 2.0
#: Growth of a standing vehicle's box across the road, both sides, with the time ahead [m/s]:
#: SUMO's lane-change model turns a standing car's nose toward the next lane (USA_US101-24_2 with
#: seed 2: vehicle 31, 0 m/s, turned from -0.04 to -0.16 rad in 2.5 s while the ego passed it at
#: 18 m/s 0.16 m away, and the contact followed); the ego passes such a car with this margin
#: (:data:`TURN_IN_MAX_M` after 1 s) or does not pass it.
TURN_IN_MPS = 0.5
#: Largest growth of a standing vehicle's box across the road [m] (a 5 m car turning its nose by
#: a further 0.2 rad).
TURN_IN_MAX_M = 1.0


def _files(folder: Path) -> tuple[Path, Path]:
    if not folder.is_dir():
        raise ScenarioError("not a folder", "--commonroad", str(folder))
    crs = sorted(folder.glob("*.cr.xml"))
    cfgs = sorted(folder.glob("*.sumo.cfg"))
    if not crs:
        raise ScenarioError("holds no CommonRoad scenario (*.cr.xml)", "--commonroad", str(folder))
    if not cfgs:
        raise ScenarioError("holds no SUMO configuration (*.sumo.cfg)", "--commonroad", str(folder))
    return crs[0], cfgs[0]


def repaired_routes(cfg: Path, out_dir: Path) -> tuple[list[Path], int]:
    """The route files of the SUMO configuration ``cfg``, each route with an edge repeated right
    after itself collapsed to one (``edges="92 92 29"`` -> ``"92 29"``), and how many routes
    changed; a file with no such route is returned as it is, a changed one is written to
    ``out_dir``.

    The converter of the interactive US-101 scenes lists an edge twice where two of a vehicle's
    lanelets lie on the same SUMO edge.  SUMO refuses such a route (there is no connection from an
    edge to itself); with ``--ignore-route-errors`` it drives the vehicle to the end of the
    repeated edge and stops it there for the rest of the run (``time-to-teleport`` -1): in
    USA_US101-24_1 vehicles 31 and 44 (``92 92 29``) stand at the end of edge 92 (lane position
    212.3 of 212.34 m) from 8 s on, 10 m past the goal, and the cars behind them stop in a row
    across four lanes, where the recorded drivers drove on.
    """
    import xml.etree.ElementTree as ET

    def parsed(path: Path) -> ET.ElementTree[ET.Element[str]]:
        try:
            return ET.parse(path)
        except (OSError, ET.ParseError) as exc:
            raise ScenarioError(f"cannot be read as SUMO XML ({type(exc).__name__}: {exc})", "--commonroad",
                                str(path)) from None

    root = parsed(cfg).getroot()
    files = [cfg.parent / f.strip() for el in root.iter("route-files") for f in el.get("value", "").split(",")
             if f.strip()]
    out: list[Path] = []
    changed = 0
    for f in files:
        tree = parsed(f)
        n = 0
        for el in tree.getroot().iter():
            edges = el.get("edges")
            if edges is None:
                continue
            e = edges.split()
            kept = [a for i, a in enumerate(e) if i == 0 or a != e[i - 1]]
            if kept != e:
                el.set("edges", " ".join(kept))
                n += 1
        if n:
            f = out_dir / f.name
            tree.write(f, encoding="utf-8", xml_declaration=True)
        changed += n
        out.append(f)
    return out, changed


def _sumo() -> tuple[ModuleType, ModuleType]:
    try:
        import libsumo as traci
        import sumolib
    except ImportError:
        try:
            import sumolib
            import traci
        except ImportError as exc:
            raise MissingDependencyError("the CommonRoad closed loop needs SUMO: pip install 'iamp[sim,commonroad]'") \
                from exc
    return traci, sumolib


def _box(cr: CommonRoadProblem, centre: ArrayLike, length: float, width: float, heading: float) -> tuple[float, ...]:
    sd = cr.frame.to_road(_corners(np.asarray(centre, dtype=float), length, width, heading))
    return float(sd[:, 0].min()), float(sd[:, 0].max()), float(sd[:, 1].min()), float(sd[:, 1].max())


def _road_heading(cr: CommonRoadProblem, centre: ArrayLike, length: float, width: float, heading: float) -> float:
    """A body's heading relative to the road frame: the direction from its rear to its front in
    road coordinates (for the monitor's oriented bodies)."""
    sd = cr.frame.to_road(_corners(np.asarray(centre, dtype=float), length, width, heading))
    front, rear = sd[:2].mean(axis=0), sd[2:].mean(axis=0)
    return float(math.atan2(front[1] - rear[1], front[0] - rear[0]))


def _observed_obstacle(cr: CommonRoadProblem, oid: int, hist_t: list[float], hist_s: list[float],
                       box: tuple[float, ...], speed: float, t: np.ndarray, predictor: Predictor) -> Obstacle:
    """An obstacle over ``t`` (from now) predicted from its observed history (module doc, step 2)."""
    from iamp.core.scenario import History

    s_lo, s_hi, d_lo, d_hi = box
    half = 0.5 * (s_hi - s_lo)
    s0 = 0.5 * (s_lo + s_hi)
    T = max(float(t[-1]), 0.1)
    ht = np.asarray(hist_t, dtype=float)
    if ht.size >= 3 and ht[-1] - ht[0] >= predictor.min_history_s - 1e-9:
        p = predictor.predict(History(ht - ht[-1], np.asarray(hist_s, dtype=float) - hist_s[-1] + s0), T)
        centre = np.interp(t, p.t, p.x)
    else:
        centre = s0 + speed * t
    deg = int(min(3, t.size - 1))
    coeffs = np.polynomial.polynomial.polyfit(t, centre, deg) if deg > 0 else np.array([centre[0]])
    resid = float(np.max(np.abs(np.polynomial.polynomial.polyval(t, coeffs) - centre)))
    n = t.size
    grow = np.minimum(SPREAD_MPS * t, SPREAD_MAX_M)  # the prediction's spread along the road
    # a standing vehicle may turn its nose toward either neighbouring lane (TURN_IN_MPS)
    side = np.minimum(TURN_IN_MPS * t, TURN_IN_MAX_M) if speed <= STANDING_MPS else np.zeros(n)
    return Obstacle(oid, t, centre - half - grow, centre + half + grow, d_lo - side, d_hi + side, 2 * half,
                    d_hi - d_lo, tuple(float(c) for c in coeffs), half + resid + float(grow[-1]), resid, 0, False)


#: Decelerations of the fail-safe, gentlest first [m/s^2] (then 0.9 a_max).
FAILSAFE_DECEL = (2.0, 4.0, 6.0)
#: Speeds the fail-safe slows to, as fractions of the current speed, least braking first.
FAILSAFE_SPEEDS = (0.75, 0.5, 0.25, 0.0)
#: Horizon over which a fail-safe that keeps moving must stay clear [s] (replans come every 0.5 s).
FAILSAFE_HORIZON_S = 3.0
#: Shortest horizon of a fail-safe plan [s].
FAILSAFE_MIN_S = 1.0


class Shifted:
    """A plan's remainder from ``offset`` on: ``states(t)`` of the plan at ``t + offset``."""

    def __init__(self, trajectory: Trajectory, offset: float) -> None:
        self.trajectory, self.offset = trajectory, offset

    def states(self, t: ArrayLike) -> np.ndarray:
        return self.trajectory.states(np.asarray(t, dtype=float) + self.offset)

    def inputs(self, t: ArrayLike) -> np.ndarray:
        return self.trajectory.inputs(np.asarray(t, dtype=float) + self.offset)


class Braking:
    """Braking in the lane: the speed along the road falls at ``decel`` from ``x0``'s to ``v_end``
    and stays there; the lateral speed falls linearly to zero over ``t_lat`` (the same
    trajectory interface as a plan: ``states(t)`` rows ``(s, v_s, d, v_d)``, ``inputs(t)``).

    With ``d_end``, the lateral motion instead ends at rest at ``d_end`` after ``t_lat`` (the cubic
    from ``x0``'s offset and lateral speed: back to a lane's centre when a car appears beside a
    lane change, :func:`failsafe`)."""

    def __init__(self, x0: tuple[float, float, float, float], decel: float, v_end: float, t_lat: float,
                 d_end: float | None = None) -> None:
        self.x0, self.decel, self.v_end, self.t_lat, self.d_end = x0, decel, v_end, max(t_lat, 1e-6), d_end
        self.t_b = max(0.0, x0[1] - v_end) / decel
        T, d0, vd0 = self.t_lat, x0[2], x0[3]
        # with d_end: the cubic d0 + vd0 t + c2 t^2 + c3 t^3 with d(T) = d_end, d'(T) = 0
        self.c2 = 0.0 if d_end is None else (3.0 * (d_end - d0) - 2.0 * vd0 * T) / T**2
        self.c3 = 0.0 if d_end is None else (-2.0 * (d_end - d0) + vd0 * T) / T**3

    def states(self, t: ArrayLike) -> np.ndarray:
        s0, v0, d0, vd0 = self.x0
        tt = np.atleast_1d(np.asarray(t, dtype=float))
        tb = np.minimum(tt, self.t_b)
        s = s0 + v0 * tb - 0.5 * self.decel * tb**2 + self.v_end * (tt - tb)
        v = v0 - self.decel * tb
        tl = np.minimum(tt, self.t_lat)
        if self.d_end is None:
            d = d0 + vd0 * tl - 0.5 * vd0 / self.t_lat * tl**2
            vd = vd0 * (1.0 - tl / self.t_lat)
        else:
            d = d0 + vd0 * tl + self.c2 * tl**2 + self.c3 * tl**3
            vd = np.where(tt < self.t_lat, vd0 + 2.0 * self.c2 * tl + 3.0 * self.c3 * tl**2, 0.0)
        return np.stack([s, v, d, vd], axis=1)

    def inputs(self, t: ArrayLike) -> np.ndarray:
        tt = np.atleast_1d(np.asarray(t, dtype=float))
        lat = (-self.x0[3] / self.t_lat if self.d_end is None else 2.0 * self.c2 + 6.0 * self.c3 * tt)
        return np.stack([np.where(tt < self.t_b, -self.decel, 0.0),
                         np.where(tt < self.t_lat, lat, 0.0)], axis=1)


def vehicle_hits(hits: list[Intrusion]) -> list[Intrusion]:
    """The intrusions into vehicles (the road-edge boxes left out)."""
    return [h for h in hits if not h.obstacle.road_edge]


def edge_depth(hits: list[Intrusion]) -> float:
    """The deepest intrusion into a road-edge box [m] (0 when none)."""
    return max((h.depth_m for h in hits if h.obstacle.road_edge), default=0.0)


def _behind(cr: CommonRoadProblem) -> list[tuple[Obstacle, float]]:
    """The vehicles behind the ego in its path now and their gaps: a vehicle is in the path when
    its box now overlaps the ego's body across the road grown by RSS's lateral margin ``μ``, and
    behind when its front is behind the ego's rear (gap > 0, bumper to bumper)."""
    from iamp.simulation.rss import DEFAULT

    s0, _, d0, _ = cr.x0
    half_w = 0.5 * cr.ego_width + DEFAULT.lat_margin_m
    out = []
    for ob in cr.obstacles:
        if ob.road_edge or ob.d_lo[0] >= d0 + half_w or ob.d_hi[0] <= d0 - half_w:
            continue
        gap = (s0 - 0.5 * cr.ego_length) - float(ob.s_hi[0])
        if gap > 0:
            out.append((ob, gap))
    return out


def rss_followers(cr: CommonRoadProblem) -> set[int]:
    """The vehicles behind the ego in its path that keep RSS's safe distance to it now.

    A vehicle is in the path when its box now overlaps the ego's body across the road grown by
    RSS's lateral margin ``μ``, and behind when its front is behind the ego's rear.  It keeps RSS's
    distance when the gap is at least :func:`iamp.simulation.rss.safe_longitudinal_distance` with
    it as the rear car (its speed the predicted cubic's slope now).  Such a follower is responsible
    for what follows while the ego, ahead of it, brakes at most RSS's ``brake_max`` (RSS's rule
    of the rear car), so its predicted box running into the ego's rear is no reason to brake.

    Parameters
    ----------
    cr : CommonRoadProblem
        The live problem (``x0`` now, ``obstacles`` the predicted vehicles).

    Returns
    -------
    set of int
        Their obstacle ids.
    """
    from iamp.simulation.rss import safe_longitudinal_distance

    v0 = cr.x0[1]
    return {ob.obstacle_id for ob, gap in _behind(cr)
            if gap >= float(safe_longitudinal_distance(float(ob.cubic[1]) if len(ob.cubic) > 1 else 0.0, v0))}


def rear_vehicles(cr: CommonRoadProblem) -> set[int]:
    """The vehicles behind the ego in its path now, whatever their gap (those of
    :func:`rss_followers` and those closing in nearer than RSS's distance).

    When no option keeps clear of the predictions but these (:func:`choose`, :func:`failsafe`),
    braking harder than RSS's ``brake_max`` in front of them is RSS's improper response of the
    front car, and braking at all brings the car closing in from behind sooner: USA_US101-5_2
    (searched final states, seed 1) braked to a stop at 4 then 10.35 m/s^2 in front of vehicle
    554 closing in at 9-12 m/s, which ran into the standing ego (a contact RSS blames on both).

    Parameters
    ----------
    cr : CommonRoadProblem
        The live problem (``x0`` now, ``obstacles`` the predicted vehicles).

    Returns
    -------
    set of int
        Their obstacle ids.
    """
    return {ob.obstacle_id for ob, _ in _behind(cr)}


def harmless(option: tuple[str, Any, float, list[Intrusion]], followers: set[int]) -> bool:
    """Does the option keep clear of every predicted vehicle but the RSS-keeping followers
    (:func:`rss_followers`) ahead of which it brakes at most RSS's ``brake_max``?"""
    from iamp.simulation.rss import DEFAULT

    _, trajectory, T, hits = option
    rest = [h for h in vehicle_hits(hits) if h.obstacle.obstacle_id not in followers]
    if rest:
        return False
    if not vehicle_hits(hits):
        return True
    u = trajectory.inputs(np.linspace(0.0, T, max(2, int(T / 0.05) + 1)))[:, 0]
    return bool(np.min(u) >= -DEFAULT.brake_max - 1e-9)


def choose(options: list[tuple[str, Any, float, list[Intrusion]]], followers: set[int] | None = None,
           rear: set[int] | None = None) -> int:
    """Which option the loop executes when the replan found no safe plan (module doc, step 2).

    Every option is ``(name, trajectory, horizon, intrusions)``, in order of preference (the new
    plan toward the goal, the kept plan, the fail-safe).  Among those that keep clear of every
    predicted vehicle (but ``followers`` that keep RSS's distance behind the ego, while the option
    brakes at most RSS's ``brake_max``: :func:`harmless`), the one that enters the road-edge boxes
    least (to 1 cm; ties: the first) is taken: a road edge does not move, so a plan that grazes it
    by a few centimetres is no reason to
    brake (braking in the lane may run deeper into an edge that narrows ahead).  When none keeps
    clear of the vehicles, the same choice is made among the options that keep clear of every
    vehicle but those ``rear`` (behind the ego in its path now, :func:`rear_vehicles`) while braking
    at most ``brake_max``: the rear car is responsible for what follows, and braking more only
    brings it closer; when none does either, the last option (the fail-safe) is taken.

    Parameters
    ----------
    options : list of tuple
        ``(name, trajectory, horizon [s], intrusions)``; the last is the fail-safe.
    followers : set of int, optional
        The vehicles of :func:`rss_followers` (none by default).
    rear : set of int, optional
        The vehicles of :func:`rear_vehicles` (none by default).

    Returns
    -------
    int
        The index of the option to execute.
    """
    clear = [i for i, o in enumerate(options) if harmless(o, followers or set())]
    if not clear and rear:
        clear = [i for i, o in enumerate(options) if harmless(o, (followers or set()) | rear)]
    if not clear:
        return len(options) - 1
    return min(clear, key=lambda i: (round(edge_depth(options[i][3]), 2), i))


def rss_stops_behind(cr: CommonRoadProblem, decel: float) -> bool:
    """Does braking at ``decel`` to a stop keep RSS's safe longitudinal distance to every vehicle
    ahead in the ego's path now?

    A vehicle is in the path when its box (now, without the prediction's spread) overlaps the
    ego's body across the road grown by RSS's lateral margin ``μ``; its speed is its predicted
    cubic's slope now.  The gap (bumper to bumper) must be at least
    :func:`iamp.simulation.rss.rss_distance` with the ego already braking (response time 0) at
    ``decel`` and the vehicle ahead braking at RSS's ``brake_max``: whatever it does within that
    bound, the ego stops behind it.

    Parameters
    ----------
    cr : CommonRoadProblem
        The live problem (``x0`` now, ``obstacles`` the predicted vehicles).
    decel : float
        The ego's braking [m/s^2, > 0].

    Returns
    -------
    bool
        True when every vehicle ahead in the path is far enough.
    """
    from iamp.simulation.rss import DEFAULT, rss_distance

    s0, v0, d0, _ = cr.x0
    half_w = 0.5 * cr.ego_width + DEFAULT.lat_margin_m
    for ob in cr.obstacles:
        if ob.road_edge or ob.s_hi[0] <= s0 or ob.d_lo[0] >= d0 + half_w or ob.d_hi[0] <= d0 - half_w:
            continue
        gap = float(ob.s_lo[0]) - (s0 + 0.5 * cr.ego_length)
        v_f = float(ob.cubic[1]) if len(ob.cubic) > 1 else 0.0
        if gap < float(rss_distance(v0, v_f, 0.0, 0.0, decel, DEFAULT.brake_max)):
            return False
    return True


def failsafe(cr: CommonRoadProblem, a_max: float, followers: set[int] | None = None,
             rear: set[int] | None = None, lane_d: float | None = None) -> tuple[Braking, float]:
    """The fail-safe when no plan keeps clear: braking in the lane (:class:`Braking`, the lateral
    speed brought to zero over 1 s) at the gentlest of :data:`FAILSAFE_DECEL` and 0.9 ``a_max``,
    and at that deceleration to the highest of :data:`FAILSAFE_SPEEDS` (fractions of the current
    speed), whose body stays off every predicted vehicle over :data:`FAILSAFE_HORIZON_S` (or until
    it stands, if later; a braking to a stop is checked standing on to that horizon: a stop is
    not the end of what is executed, and a car closing in from behind reaches a standing ego
    after it; road edges are not counted: braking in the lane cannot move away from one) and which,
    continued to a stop, keeps RSS's distance to the vehicle ahead (:func:`rss_stops_behind`);
    else the gentlest such braking that keeps clear of every vehicle but those ``rear`` while
    braking at most RSS's ``brake_max`` (:func:`choose`); else the hardest braking to a stop.
    Returns the plan (from ``cr.x0``, time 0 = now) and the horizon it was checked over.

    Parameters
    ----------
    cr : CommonRoadProblem
        The live problem: ``x0`` the ego's state now, ``obstacles`` the predicted vehicles.
    a_max : float
        The vehicle type's acceleration limit [m/s^2].
    followers : set of int, optional
        Vehicles behind whose predicted boxes do not count (:func:`rss_followers`, :func:`harmless`).
    rear : set of int, optional
        The vehicles behind the ego in its path (:func:`rear_vehicles`), for the second choice.
    lane_d : float, optional
        The centre of the lane the ego's centre is in: where a braking whose lateral speed merely
        falls to zero is not clear, the same braking that brings the ego back to rest at that
        centre over :data:`FAILSAFE_RETURN_S` is tried next (a car SUMO inserted beside a lane
        change under way: USA_US101-23_1, vehicle 75 at 3.3 s, 0.5 m beside the ego's body).

    Returns
    -------
    tuple of Braking and float
        The braking plan and its checked horizon [s] (at least :data:`FAILSAFE_HORIZON_S`).
    """
    v0 = max(cr.x0[1], 0.0)
    decels = (*[b for b in FAILSAFE_DECEL if b < 0.9 * a_max], 0.9 * a_max)
    last: tuple[Braking, float] | None = None
    second: tuple[Braking, float] | None = None
    excused = (followers or set()) | (rear or set())
    for b in decels:
        for frac in FAILSAFE_SPEEDS:
            plans = [Braking((cr.x0[0], v0, cr.x0[2], cr.x0[3]), b, frac * v0, FAILSAFE_MIN_S)]
            if lane_d is not None and abs(cr.x0[2] - lane_d) > FAILSAFE_RETURN_M:
                plans.append(Braking((cr.x0[0], v0, cr.x0[2], cr.x0[3]), b, frac * v0, FAILSAFE_RETURN_S, lane_d))
            for brake in plans:
                T = max(FAILSAFE_HORIZON_S, brake.t_b)
                if brake.d_end is None:
                    last = (brake, T)
                option = ("fail-safe", brake, T, intrusions(cr, brake, T))
                if not rss_stops_behind(cr, b):
                    continue
                if brake.d_end is not None and float(np.max(np.hypot(*brake.inputs(
                        np.linspace(0.0, brake.t_lat * (1.0 - 1e-9), 16)).T))) > a_max + 1e-9:
                    continue  # the return to the lane's centre leaves the friction circle
                if harmless(option, followers or set()):
                    return brake, T
                if second is None and rear and harmless(option, excused):
                    second = (brake, T)
    if second is not None:
        return second
    assert last is not None
    return last


#: The time over which a fail-safe brings the ego back to its lane's centre (:func:`failsafe`'s ``lane_d``) [s].
FAILSAFE_RETURN_S = 1.5
#: A fail-safe returns to the lane's centre only when the ego is farther from it than this [m].
FAILSAFE_RETURN_M = 0.3

#: The ego's braking in :func:`goal_occupancy`'s RSS test, as a fraction of ``a_max`` (the fail-safe's hardest).
STOP_DECEL_FRACTION = 0.9
#: Grid of the goal positions tested by :func:`goal_occupancy` [m] (with the positions where the
#: ego's body just touches an observed vehicle, so a free sliver narrower than the grid is found).
GOAL_GRID_M = 0.25
#: How far from a goal position piece's centre the vehicles :func:`goal_occupancy` lists for each
#: window step lie at most, along and across the road [m].
GOAL_NEAR_M = (40.0, 8.0)


def _goal_positions(A: np.ndarray, b: np.ndarray, grid: np.ndarray, rows: np.ndarray, half_l: float,
                    half_w: float) -> np.ndarray:
    """The ego positions :func:`goal_occupancy` tests in one position piece (``A z <= b``) at one
    step: the grid points inside it and the points where the ego's body (parallel to the road)
    just touches one of the vehicles ``rows`` ahead, behind or beside, crossed with the grid's
    and the other touch points' coordinates (a free sliver between two vehicles, or between a
    vehicle and the piece's edge, narrower than the grid is found)."""
    from iamp.simulation.rss import body_extents

    eps = 1e-3
    ss, dd = [np.unique(grid[:, 0])], [np.unique(grid[:, 1])]
    if rows.size:
        hx, hy = body_extents(rows[:, 5], rows[:, 6], rows[:, 7])
        ss += [rows[:, 0] - hx - half_l - eps, rows[:, 0] + hx + half_l + eps]
        dd += [rows[:, 1] - hy - half_w - eps, rows[:, 1] + hy + half_w + eps]
    S, D = np.meshgrid(np.concatenate(ss), np.concatenate(dd))
    P = np.stack([S.ravel(), D.ravel()], axis=1)
    P = P[np.all(P @ A.T <= b + 1e-9, axis=1)]
    return np.unique(np.concatenate([grid, P]), axis=0) if P.size else grid


def goal_occupancy(cr: CommonRoadProblem, log: Any) -> dict[str, Any]:
    """Could the ego have stood in the goal region without touching a vehicle, step by step?

    For every logged time step inside the goal's time window, the ego's reference point (its
    centre, which CommonRoad's goal test places inside the goal's shape) is tried at the positions
    of a goal state's position pieces (a grid of :data:`GOAL_GRID_M` and the positions where the
    body just touches a vehicle, :func:`_goal_positions`): the ego's body there, parallel to the
    road, against the body of every vehicle the ego observed at that step (SUMO's positions,
    bodies at their headings as their bounding boxes in the road frame, no buffer).  A step is
    *free* when at least one goal position keeps the body off every vehicle.  When no step of the
    window is free, reaching the goal in this traffic means a contact, whatever the plan.

    A free position is *clear after* when the ego, there at the goal state's lowest speed, can
    avoid every vehicle ahead of it in its path (bodies overlapping across the road) at all:
    braking at ``a_max`` while that vehicle accelerates from its observed speed at RSS's
    ``accel_max`` (the kindest it can do), the gap ``g`` must not close,
    ``g >= max(v - v_f, 0)^2 / (2 (a_max + accel_max))`` (a lateral escape is not counted).  A goal
    reached with no such position is reached on a course that ends in a contact just after.  It is
    also *RSS-free* when every such gap is at least the distance in which the ego, braking at
    :data:`STOP_DECEL_FRACTION` ``a_max``, stops behind the vehicle whatever it does within RSS's
    ``brake_max`` (:func:`iamp.simulation.rss.rss_distance`, no response time).

    Parameters
    ----------
    cr : CommonRoadProblem
        The scene (its goal region and road frame).
    log : iamp.simulation.metrics.StepLog
        The executed episode (neighbour rows ``s, d, v, a, lane, length, width, heading``).

    Returns
    -------
    dict
        ``window_steps_logged`` (steps of the window the episode logged), ``free_steps`` and
        ``first_free_s`` / ``last_free_s`` (the times of the first and last free step, or None),
        ``clear_after_steps``, ``rss_free_steps``; ``occupied_whole_window`` (every step of the
        window logged and none free), ``occupants`` (the vehicles on a goal position at the steps
        without a free one), ``occupants_always_ahead`` (the window occupied whole and each
        occupant's centre ahead of the ego's at every step it was observed: the ego never drove in
        front of it, so SUMO's car following never had it react to the ego; :func:`miss_reason`
        words it), ``blocked_whole_window`` (every step logged and none clear after),
        ``blockers`` (the vehicles on a goal position or, ahead of a free one, too close to avoid, at
        the steps without a position clear after) and ``blockers_always_ahead``; ``vehicles``:
        per logged window step ``[t, [[id, s, d, v, length, width, heading], ...]]`` for the
        vehicles within :data:`GOAL_NEAR_M` of a position piece's centre, so the verdict can be
        recomputed from the episode alone.
    """
    from iamp.simulation.rss import DEFAULT, body_extents, rss_distance

    pieces = []
    for e in cr.goal.elements:
        for pc in e.pieces or []:
            cs, cd = pc.centre
            ss, dd = np.meshgrid(np.arange(cs - 40.0, cs + 40.0, GOAL_GRID_M),
                                 np.arange(cd - 8.0, cd + 8.0, GOAL_GRID_M))
            P = np.stack([ss.ravel(), dd.ravel()], axis=1)
            inside = np.all(P @ pc.A.T <= pc.b + 1e-9, axis=1)
            pieces.append((e.steps, pc, P[inside], 0.0 if e.speed is None else max(e.speed[0], 0.0)))
    logged = free = rss_free = clear_after = 0
    first = last = None
    occupants: set[str] = set()
    blockers: set[str] = set()
    near_rows: list[list[Any]] = []
    half_l, half_w = 0.5 * cr.ego_length, 0.5 * cr.ego_width
    for i, t in enumerate(log.t):
        k = int(round(t / cr.dt))
        here = [(pc, P, v) for steps, pc, P, v in pieces if steps[0] <= k <= steps[1] and P.size]
        if not here:
            continue
        nb = np.asarray(log.nb[i], dtype=float).reshape(-1, 8)
        ids = list(log.ids[i])
        near = np.zeros(len(nb), dtype=bool)
        for pc, _, _ in here:
            near |= ((np.abs(nb[:, 0] - pc.centre[0]) <= GOAL_NEAR_M[0])
                     & (np.abs(nb[:, 1] - pc.centre[1]) <= GOAL_NEAR_M[1]))
        near_rows.append([round(float(t), 3), [[str(ids[j]), *(round(float(x), 4) for x in nb[j, [0, 1, 2, 5, 6, 7]])]
                                               for j in np.flatnonzero(near)]])
        tested = [(_goal_positions(pc.A, pc.b, P, nb[near], half_l, half_w), v) for pc, P, v in here]
        P = np.concatenate([h[0] for h in tested])
        v_goal = np.concatenate([np.full(len(h[0]), h[1]) for h in tested])
        logged += 1
        ok = np.ones(len(P), dtype=bool)
        stops = np.ones(len(P), dtype=bool)
        avoids = np.ones(len(P), dtype=bool)
        on_goal, too_close = [], []
        for vid, row in zip(ids, nb):
            hx, hy = body_extents(row[5], row[6], row[7])
            depth = body_overlap(P[:, 0], P[:, 1], np.zeros(len(P)), row[0] - hx, row[0] + hx, row[1] - hy,
                                 row[1] + hy, half_l, half_w, 0.0)
            ok &= depth <= 0
            if bool(np.any(depth > 0)):
                on_goal.append(str(vid))
            ahead = (np.abs(row[1] - P[:, 1]) < hy + half_w + DEFAULT.lat_margin_m) & (row[0] > P[:, 0])
            in_path = (np.abs(row[1] - P[:, 1]) < hy + half_w) & (row[0] > P[:, 0])
            gap = row[0] - hx - (P[:, 0] + half_l)
            need = rss_distance(v_goal, row[2], 0.0, 0.0, STOP_DECEL_FRACTION * cr.a_max, DEFAULT.brake_max)
            stops &= ~ahead | (gap >= need)
            closing = np.maximum(v_goal - row[2], 0.0)
            unavoidable = in_path & (gap < closing**2 / (2.0 * (cr.a_max + DEFAULT.accel_max)))
            avoids &= ~unavoidable
            if bool(np.any(unavoidable & (depth <= 0))):
                too_close.append(str(vid))
        if ok.any():
            free += 1
            first = t if first is None else first
            last = t
        else:
            occupants.update(on_goal)
        if (ok & avoids).any():
            clear_after += 1
        else:
            blockers.update(on_goal if not ok.any() else too_close)
        rss_free += bool((ok & stops).any())
    window = cr.goal.steps[1] - cr.goal.steps[0] + 1

    def always_ahead(who: set[str]) -> bool:
        return all(float(log.nb[i][list(log.ids[i]).index(vid)][0]) > float(log.ego[i][0])
                   for vid in who for i in range(len(log.t)) if vid in log.ids[i])

    whole = logged >= window and free == 0
    blocked = logged >= window and clear_after == 0
    return {"window_steps_logged": logged, "free_steps": free, "first_free_s": first, "last_free_s": last,
            "clear_after_steps": clear_after, "rss_free_steps": rss_free, "occupied_whole_window": whole,
            "occupants": sorted(occupants), "occupants_always_ahead": whole and always_ahead(occupants),
            "blocked_whole_window": blocked, "blockers": sorted(blockers),
            "blockers_always_ahead": blocked and always_ahead(blockers), "vehicles": near_rows}


def miss_reason(occupancy: dict[str, Any]) -> str | None:
    """Why the goal could not be reached whatever the plan, from :func:`goal_occupancy` (None when
    some step of the goal's window had a goal position clear of every vehicle from which a contact
    could still be avoided, or the window was not logged whole).

    Parameters
    ----------
    occupancy : dict
        The result of :func:`goal_occupancy`.

    Returns
    -------
    str or None
        The reason in words.
    """
    never = ("; each of them was ahead of the ego all episode, so the ego never drove in front of them "
             "and no course of the ego could have freed the region")
    if occupancy.get("occupied_whole_window"):
        who = ", ".join(occupancy.get("occupants", [])) or "observed vehicles"
        text = (f"the goal region was occupied for its whole window (vehicles {who}): at no step of the window did "
                "any goal position keep the ego's body off every observed vehicle")
        return text + (never if occupancy.get("occupants_always_ahead") else "")
    if occupancy.get("blocked_whole_window"):
        who = ", ".join(occupancy.get("blockers", [])) or "observed vehicles"
        text = (f"the goal region had room for the ego's body at {occupancy.get('free_steps')} step(s) of its window "
                f"only where, at the goal's lowest speed, the ego could not have avoided the vehicle ahead (vehicles "
                f"{who}) even braking at a_max with that vehicle accelerating at RSS's accel_max: reaching the goal "
                "meant a contact just after")
        return text + (never if occupancy.get("blockers_always_ahead") else "")
    return None


def road_edge_depth(cr: CommonRoadProblem, log: Any) -> float:
    """The deepest the executed body entered a road-edge box of the scene (no buffer) [m].

    The boxes cover the narrowest bound over up to :data:`~iamp.commonroad.convert.EDGE_CHUNK_M`
    of road, so they overstate an edge that narrows steeply (a ramp's taper): a positive depth is
    not by itself off the road; :func:`off_road` is CommonRoad's own verdict."""
    if not log.t or not cr.road_edges:
        return 0.0
    E = np.asarray(log.ego, dtype=float)
    heading = np.arctan2(E[:, 3], np.maximum(E[:, 1], 1e-6))
    worst = 0.0
    for ob in cr.road_edges:
        depth = body_overlap(E[:, 0], E[:, 2], heading, ob.s_lo[:1], ob.s_hi[:1], ob.d_lo[:1], ob.d_hi[:1],
                             cr.ego_length / 2, cr.ego_width / 2, 0.0)
        worst = max(worst, float(np.max(depth)))
    return worst


def off_road(cr: CommonRoadProblem, log: Any) -> dict[str, Any]:
    """CommonRoad's road-boundary verdict on the executed bodies (the independent judge of the
    road edges, where :func:`road_edge_depth` measures iamp's own boxes): the executed steps whose
    body -- the ego's rectangle at the executed centre, in the world, at the heading of its
    executed velocity -- collides with the road boundary that the solution checker builds from the
    lanelets (:func:`~iamp.commonroad.planning.off_road_poses`).

    Returns
    -------
    dict
        ``off_road_steps`` (how many executed steps) and ``off_road_times_s`` (the first and last
        such time, or None).
    """
    if not log.t:
        return {"off_road_steps": 0, "off_road_times_s": None}
    E = np.asarray(log.ego, dtype=float).reshape(-1, 6)
    P = np.atleast_2d(cr.frame.to_world(E[:, 0], E[:, 2]))
    V = np.atleast_2d(cr.frame.velocity_to_world(E[:, 0], E[:, 2], E[:, 1], E[:, 3]))
    off = off_road_poses(cr, P, np.arctan2(V[:, 1], V[:, 0]))
    t = np.asarray(log.t, dtype=float)
    return {"off_road_steps": int(off.sum()),
            "off_road_times_s": [float(t[off][0]), float(t[off][-1])] if off.any() else None}


def succeeded(goal_reached: bool, collisions: int, off_road_steps: int) -> bool:
    """An interactive episode's ``success``: the goal reached, no contact, and no executed body off
    CommonRoad's road (:func:`off_road`: its solution checker rejects a solution with one; DEU_A9-1_2,
    a public scene, reached its goal with five steps off the road and had been called a success)."""
    return bool(goal_reached) and collisions == 0 and off_road_steps == 0


def simulate(folder: str | Path, planner: str = DEFAULT_PLANNER, *, replan_s: float = 0.5,
             recording: str | Path | None = None,
             progress: Callable[[str], None] | None = None, seed: int = 1, tactical: bool = False,
             sequences: bool = False, search: bool = False, repair_routes: bool = True) -> dict[str, Any]:
    """Run the closed loop of the module docstring; returns the metrics (JSON-ready).

    The same as :func:`simulate_with_log` without the step log.
    """
    return simulate_with_log(folder, planner, replan_s=replan_s, recording=recording, progress=progress,
                             seed=seed, tactical=tactical, sequences=sequences, search=search,
                             repair_routes=repair_routes)[0]


def simulate_with_log(folder: str | Path, planner: str = DEFAULT_PLANNER, *, replan_s: float = 0.5,
                      recording: str | Path | None = None, progress: Callable[[str], None] | None = None,
                      seed: int = 1, tactical: bool = False, sequences: bool = False,
                      search: bool = False, repair_routes: bool = True) -> tuple[dict[str, Any], Any]:
    """Run the closed loop of the module docstring; returns the metrics (JSON-ready) and the
    executed step log (:class:`iamp.simulation.metrics.StepLog`, in the road frame).

    ``seed``: SUMO's ``--seed`` (its drivers' imperfection ``sigma`` draws from it).
    ``tactical``: approach a goal two or more lanes over (at least ``EARLY_MIN_S`` ahead) one lane
    at a time before its own plan is tried, and when the replan toward the goal finds no safe plan,
    also offer a safe lane change one lane toward the goal's lane
    (:func:`iamp.commonroad.tactical.lane_change`, executed before a kept plan or the fail-safe;
    counted in ``lane_changes``); off by default: on the 57 US-101 scenes (seed 1) it changed only
    2_1, 23_1 and 24_1 and reached none of their goals, and in USA_US101-23_1 (seed 1) its lane
    change at 3.0 s fell in behind vehicle 91 while 96 went on to the goal region ahead of the ego;
    without it the road planner's own plans pass 91 and 96 at up to 21 m/s and reach the goal at
    13.2 s without contact (seed 2: 13.7 s).
    ``sequences``: approach a goal two or more lanes over first by lane changes planned together
    (:func:`iamp.commonroad.tactical.sequence`, counted in ``lane_change_sequences``); off by
    default: on the 57 US-101 scenes (seed 1) it changed only 2_1, 23_1 and 24_1 and reached none of
    their goals, and with SUMO seed 2 it brought 23_1's ego beside vehicle 96, against which the
    one-lane change that followed made a contact at fault (9.8 s); since a lane change no longer
    starts beside a car of the lane it enters (:func:`iamp.commonroad.tactical.beside`) those three
    scenes with seeds 1 and 2 have no contact with it either, and still miss their goals.
    ``search``: plan toward the goal with the road planner's final-state search
    (:func:`iamp.commonroad.planning.plan`'s ``search``); off by default: over the 57 scenes it
    reached the same 53 goals (seed 1) without contact, but with seed 2 USA_US101-24_2 ended in a
    contact (not at fault) with vehicle 31, a standing car SUMO turned toward the ego's lane.
    ``repair_routes``: give SUMO the routes with an edge repeated right after itself collapsed
    (:func:`repaired_routes`; counted in ``sumo_routes_repaired``); on by default: SUMO refuses
    such a route and stops the vehicle at the end of the repeated edge for the rest of the run
    (USA_US101-24_1: a row of standing and stopping cars across four lanes just past the goal).
    The metrics include SPEC §17's responsibility measures
    (:func:`iamp.simulation.monitor.responsibility`, in the road frame: centres and bodies at
    their headings relative to the road; lane numbers are SUMO's, so a vehicle is in the ego's
    path only when their bodies overlap sideways).

    ``recording``: a CommonRoad scenario holding the recorded trajectories of the same vehicles
    (the interactive ``.cr.xml`` holds only their initial states; for US-101 the benchmark
    ``USA_US101-<n>_1_T-1.xml`` of the same scene), for ``sumo_vs_recording``.

    Raises
    ------
    iamp.ScenarioError
        The folder lacks the scenario or the SUMO configuration, or the ego cannot be placed.
    iamp.core.errors.MissingDependencyError
        SUMO is not installed.
    """
    from commonroad.scenario.state import CustomState

    from iamp.simulation.metrics import StepLog, episode_metrics

    folder = Path(folder)
    cr_path, cfg = _files(folder)
    traci, sumolib = _sumo()
    cr = load(cr_path)
    pp = cr.planning_problem
    dt = cr.dt
    predictor = Predictor.default()
    L, W = cr.ego_length, cr.ego_width
    sx, sy = ego_margins(L, W, 0.06)
    replan_steps = max(1, round(replan_s / dt))
    k_end = cr.goal.steps[1]
    recorded: dict[int, Any] = {}
    rec_obstacles: list[Obstacle] = []
    if recording is not None:
        rec = load(recording)
        recorded = {int(o.obstacle_id): o for o in rec.scenario.dynamic_obstacles}
        rec_obstacles = rec.obstacles

    tmp = tempfile.TemporaryDirectory(prefix="iamp-cr-sumo-")
    cmd = [sumolib.checkBinary("sumo"), "-c", str(cfg), "--ignore-route-errors", "true",
           "--collision.action", "warn", "--collision.mingap-factor", "0", "--collision.check-junctions", "true",
           "--step-length", str(dt), "--lanechange-output", str(Path(tmp.name) / "lanechange.xml"),
           "--no-warnings", "true", "--no-step-log", "true", "--verbose", "false", "--seed", str(int(seed))]
    routes_repaired = 0
    if repair_routes:
        route_files, routes_repaired = repaired_routes(cfg, Path(tmp.name))
        if routes_repaired:
            cmd += ["--route-files", ",".join(str(f.resolve()) for f in route_files)]
    try:
        traci.start(cmd)
    except Exception as exc:  # SUMO refused the scene's files (its message names the file and line)
        raise ScenarioError(f"SUMO cannot load this scene ({type(exc).__name__}: {exc})", "--commonroad",
                            str(cfg)) from None
    log = StepLog()
    hist: dict[str, tuple[list[float], list[float]]] = {}
    sumo_collisions: list[tuple[float, str, str]] = []
    dev: dict[int, list[tuple[float, float]]] = {}
    lanes_seen: dict[str, tuple[float, float]] = {}  # lateral range of each vehicle's centre [m]
    plan_times: list[float] = []
    infeasible = fallbacks = failsafes = limit_violations = out_of_reach = edge_plans = lane_changes = 0
    sequences_on = bool(sequences)
    n_sequences = 0  # lane changes of them planned together toward a goal two or more lanes over
    decisions: list[dict[str, Any]] = []
    next_replan = 0
    peak_accel = 0.0
    goal_step: int | None = None
    status = "goal missed"
    try:
        x0w = np.asarray(pp.initial_state.position, dtype=float)
        h0 = float(pp.initial_state.orientation)
        v0 = float(pp.initial_state.velocity)
        front = x0w + 0.5 * L * np.array([math.cos(h0), math.sin(h0)])
        try:
            edge, pos, lane = traci.simulation.convertRoad(float(front[0]), float(front[1]))
        except Exception as exc:  # SUMO raises its own error types
            raise ScenarioError(f"the ego's initial position is on no SUMO edge ({exc})", "planningProblem",
                                str(cr_path)) from None
        try:
            traci.route.add("iamp_ego_route", [edge])
            traci.vehicle.add("ego", "iamp_ego_route", depart="now", departPos=str(max(pos, 0.0)),
                              departLane=str(lane), departSpeed=str(v0))
        except Exception as exc:  # SUMO refuses the ego (its message says why: the public
            # RUS_Bicycle-11_1's default vehicle type is a bicycle slower than the ego's initial speed)
            raise ScenarioError(f"SUMO refuses to insert the ego ({type(exc).__name__}: {exc})",
                                "planningProblem.initialState", str(cr_path)) from None
        traci.vehicle.setLength("ego", L)
        traci.vehicle.setWidth("ego", W)
        traci.vehicle.setSpeedMode("ego", 0)
        traci.vehicle.setLaneChangeMode("ego", 0)
        x = cr.x0
        traj: Trajectory | Braking | Shifted | Stages | None = None
        t_plan = traj_T = 0.0
        changing = False  # the plan executed is a lane change of iamp.commonroad.tactical
        lane_map = LaneMap(cr)

        def record(t: float, x: tuple[float, float, float, float], u: Any, ids: list[str],
                   rows: list[list[float]]) -> None:
            # one step of the log: the ego's state at t and the vehicles observed at t (the same
            # instant: logging the state after the step with the rows observed before it put every
            # vehicle one step (1.7 m at 17 m/s) behind where it was next to the ego)
            log.t.append(t)
            log.ego.append((x[0], x[1], x[2], x[3], float(u[0]), float(u[1])))
            log.mode.append("plan")
            log.plan_time.append(plan_times[-1] if plan_times else 0.0)
            log.ids.append(tuple(ids))
            log.nb.append(np.asarray(rows, dtype=float).reshape(-1, 8))

        for k in range(k_end + 1):
            now = k * dt
            # -- observe ------------------------------------------------------------------------
            ids, rows, boxes, speeds = [], [], {}, {}
            for vid in traci.vehicle.getIDList():
                if vid == "ego":
                    continue
                fx, fy = traci.vehicle.getPosition(vid)
                ang = math.radians(90.0 - traci.vehicle.getAngle(vid))
                vl, vw = traci.vehicle.getLength(vid), traci.vehicle.getWidth(vid)
                c = np.array([fx, fy]) - 0.5 * vl * np.array([math.cos(ang), math.sin(ang)])
                b = _box(cr, c, vl, vw, ang)
                sc = 0.5 * (b[0] + b[1])
                if abs(sc - x[0]) > RANGE_M:
                    continue
                spd = traci.vehicle.getSpeed(vid)
                ht, hs = hist.setdefault(vid, ([], []))
                ht.append(now)
                hs.append(sc)
                while ht and ht[0] < now - HISTORY_S - 1e-9:
                    ht.pop(0)
                    hs.pop(0)
                boxes[vid], speeds[vid] = b, spd
                ids.append(vid)
                rows.append([sc, 0.5 * (b[2] + b[3]), spd, traci.vehicle.getAcceleration(vid),
                             traci.vehicle.getLaneIndex(vid), vl, vw, _road_heading(cr, c, vl, vw, ang)])
                d_c = 0.5 * (b[2] + b[3])
                lo_hi = lanes_seen.get(vid, (d_c, d_c))
                lanes_seen[vid] = (min(lo_hi[0], d_c), max(lo_hi[1], d_c))
                if vid.isdigit() and int(vid) in recorded:
                    st = recorded[int(vid)].state_at_time(k)
                    if st is not None:
                        dx, dy = (float(v) for v in np.asarray(c) - np.asarray(st.position, dtype=float))
                        dev.setdefault(int(vid), []).append((dx, dy))
            # -- goal -----------------------------------------------------------------------------
            if traj is not None:
                X = traj.states(now - t_plan)[0]
                pos_w = cr.frame.to_world(X[0], X[2]).reshape(-1)
                vel_w = cr.frame.velocity_to_world(X[0], X[2], X[1], X[3]).reshape(-1)
                probe = CustomState(time_step=k, position=pos_w, velocity=float(np.hypot(*vel_w)),
                                    orientation=float(math.atan2(vel_w[1], vel_w[0])))
                if pp.goal.is_reached(probe):
                    goal_step, status = k, "goal reached"
                    record(now, x, traj.inputs(now - t_plan)[0], ids, rows)
                    break
            # -- plan -----------------------------------------------------------------------------
            if k >= next_replan and k < k_end:
                # the predictions reach past the window's end: a kept or fail-safe plan is checked
                # over FAILSAFE_HORIZON_S even when the window closes sooner
                horizon = np.arange(0, max(k_end - k, math.ceil(FAILSAFE_HORIZON_S / dt - 1e-9)) + 1) * dt
                obstacles = [_observed_obstacle(cr, int(v) if v.isdigit() else 10**6 + i, *hist[v], boxes[v],
                                                speeds[v], horizon, predictor) for i, v in enumerate(ids)]
                cands = final_candidates(x, cr.goal, dt, elapsed_steps=k)
                live = dataclasses.replace(cr, x0=x, candidates=cands, obstacles=obstacles)
                rp = None
                # a goal two or more lanes over: toward its lane first, the lane changes into a gap of
                # its lane planned together (sequence), else one lane at a time (lane_change)
                early: tuple[Any, float, str] | None = None
                # a lane change under way is finished while it keeps clear of every predicted vehicle
                rest_lc = traj_T - (now - t_plan)
                keep_lc = (changing and traj is not None and rest_lc > dt
                           and still_holds(live, Shifted(traj, now - t_plan), rest_lc,
                                           [e - (now - t_plan) for e in traj.ends if dt < e - (now - t_plan) < rest_lc]
                                           if isinstance(traj, Stages) else ()))
                if keep_lc:
                    cands = []
                n_lanes = lane_map.toward(x[0], x[2], cands[0].s, cands[0].d)[0] if cands else 0
                if cands and tactical and cands[0].tf >= EARLY_MIN_S and n_lanes >= 2:
                    start = time.perf_counter()
                    seq = (sequence(live, planner, cands[0].d, now, cands[0].s, now + cands[0].tf, lane_map)
                           if sequences_on else None)
                    if seq is not None:
                        early = (seq, seq.horizon, f"goal {n_lanes} lanes over: {len(seq.parts)} lane changes "
                                                   "into a gap of its lane")
                    else:
                        one = lane_change(live, planner, cands[0].d, now, cands[0].s, now + cands[0].tf, lane_map)
                        if one is not None and one.candidate is not None:
                            early = (one.trajectory, one.candidate.tf, "goal two or more lanes over")
                    plan_times.append(time.perf_counter() - start)
                if cands and early is None:
                    start = time.perf_counter()
                    rp = plan(live, planner, max_candidates=4, search=search)
                    plan_times.append(time.perf_counter() - start)
                action = "plan"
                within = rp is not None and rp.within_limits(live)  # read once: three choices below use it
                if keep_lc:
                    action = "lane change"
                elif early is not None:
                    traj, traj_T, why = early
                    t_plan = now
                    lane_changes += 1
                    n_sequences += isinstance(traj, Stages)
                    action = "lane change"
                    decisions.append({"t": round(now, 3), "action": action, "why": why,
                                      "vehicles": [], "road_edge_depth_m": 0.0})
                elif rp is not None and rp.candidate is not None and rp.safe and within:
                    traj, t_plan, traj_T = rp.trajectory, now, rp.candidate.tf
                else:
                    infeasible += rp is not None
                    out_of_reach += rp is None
                    options: list[tuple[str, Any, float, list[Intrusion]]] = []
                    if rp is not None and rp.trajectory is not None and rp.candidate is not None and within:
                        options.append(("new plan", rp.trajectory, rp.candidate.tf, rp.intrusions))
                    rest = traj_T - (now - t_plan)
                    if isinstance(traj, Braking):  # it runs on past its horizon: checked over the fail-safe's
                        rest = max(rest, FAILSAFE_HORIZON_S)
                    if traj is not None and rest > dt and not changing:  # a lane change that fails is given up
                        kept = Shifted(traj, now - t_plan)
                        options.append(("kept", kept, rest, intrusions(live, kept, rest)))
                    followers, rear = rss_followers(live), rear_vehicles(live)
                    if rp is not None and tactical and not any(harmless(o, followers) for o in options):
                        # instead of a new fail-safe brake: one lane toward the goal's (iamp.commonroad.tactical)
                        start = time.perf_counter()
                        tac = lane_change(live, planner, cands[0].d, now, cands[0].s, now + cands[0].tf, lane_map)
                        plan_times.append(time.perf_counter() - start)
                        if tac is not None and tac.trajectory is not None and tac.candidate is not None:
                            options.append(("lane change", tac.trajectory, tac.candidate.tf, tac.intrusions))
                    lid = lane_map.at(x[0], x[2])
                    fs, fs_T = failsafe(live, cr.a_max, followers, rear,
                                        None if lid is None else lane_map.centre(lid, x[0]))
                    options.append(("fail-safe", fs, fs_T, intrusions(live, fs, fs_T)))
                    action, chosen, chosen_T, hits = options[choose(options, followers, rear)]
                    if action == "new plan":
                        traj, t_plan, traj_T = chosen, now, chosen_T
                        edge_plans += 1
                    elif action == "lane change":
                        traj, t_plan, traj_T = chosen, now, chosen_T
                        lane_changes += 1
                    elif action == "kept":
                        fallbacks += 1  # the previous plan still keeps clear of every vehicle
                    else:  # fail-safe: brake in the lane, the gentlest braking that keeps clear
                        traj, t_plan, traj_T = fs, now, fs_T
                        failsafes += 1
                    decisions.append({
                        "t": round(now, 3), "action": action,
                        "why": "goal out of reach" if rp is None else (rp.status if rp.trajectory is None else
                                                                       "exceeds limits" if not within
                                                                       else "in the way of the new plan"),
                        "vehicles": sorted({h.obstacle.obstacle_id for h in vehicle_hits(rp.intrusions)})
                        if rp is not None else [],
                        "road_edge_depth_m": round(edge_depth(hits), 3)})
                changing = action == "lane change"
                # after a fail-safe brake, replan at the next step (the window does not wait)
                next_replan = k + (1 if action == "fail-safe" else replan_steps)
                if progress is not None:
                    progress(f"t = {now:.1f} s, {len(ids)} vehicles, plans {len(plan_times)}, {action}")
            if traj is None or (not isinstance(traj, Braking) and now + dt - t_plan > traj_T + 1e-9):
                status = "no plan"
                record(now, x, (0.0, 0.0), ids, rows)
                break
            # -- execute one step -------------------------------------------------------------------
            record(now, x, traj.inputs(now - t_plan)[0], ids, rows)
            Xn = traj.states(now + dt - t_plan)[0]
            U = traj.inputs(now + dt - t_plan)[0]
            acc = float(np.hypot(U[0], U[1]))
            peak_accel = max(peak_accel, acc)
            limit_violations += acc > cr.a_max + 1e-6
            x = (float(Xn[0]), float(Xn[1]), float(Xn[2]), float(Xn[3]))
            pos_w = cr.frame.to_world(Xn[0], Xn[2]).reshape(-1)
            vel_w = cr.frame.velocity_to_world(Xn[0], Xn[2], Xn[1], Xn[3]).reshape(-1)
            head = math.atan2(vel_w[1], vel_w[0])
            fr = pos_w + 0.5 * L * np.array([math.cos(head), math.sin(head)])
            traci.vehicle.moveToXY("ego", "", -1, float(fr[0]), float(fr[1]), 90.0 - math.degrees(head), 2)
            traci.vehicle.setSpeed("ego", float(np.hypot(*vel_w)))
            traci.simulationStep()
            for col in traci.simulation.getCollisions():
                if "ego" in (col.collider, col.victim):
                    other = col.victim if col.collider == "ego" else col.collider
                    sumo_collisions.append((now + dt, other, col.type))
    finally:
        traci.close()
        tmp.cleanup()
    metrics = episode_metrics(log, dt, (L, W), (sx, sy), sumo_collisions)
    occupancy = goal_occupancy(cr, log)
    from iamp.simulation.monitor import responsibility

    judged = responsibility(log, dt, (L, W), sumo_collisions)
    road = off_road(cr, log)
    devs = {i: np.asarray(v) for i, v in dev.items() if v}
    compared = {str(i) for i in devs}
    rec_changes = sum(1 for o in rec_obstacles if o.lane_change and str(o.obstacle_id) in compared)
    sumo_changes = sum(1 for v, (a, b) in lanes_seen.items() if b - a > LANE_CHANGE_M and v in compared)
    return {
        "scenario": cr.name, "planner": planner, "seed": int(seed), "status": status,
        "goal_reached": goal_step is not None,
        "time_to_goal_s": None if goal_step is None else goal_step * dt,
        "goal_window_s": [cr.goal.steps[0] * dt, cr.goal.steps[1] * dt],
        "success": succeeded(goal_step is not None, int(metrics["collisions"]), int(road["off_road_steps"])),
        **metrics,
        **{k: v for k, v in judged.items() if k not in ("contacts",)},
        "ego_peak_accel": peak_accel, "a_max": cr.a_max, "limit_violations": int(limit_violations),
        "infeasible_plans": infeasible, "fallbacks": fallbacks, "failsafe_brakes": failsafes,
        "edge_grazing_plans": edge_plans, "out_of_reach_replans": out_of_reach, "lane_changes": lane_changes,
        "lane_change_sequences": n_sequences, "sumo_routes_repaired": routes_repaired,
        "decisions": decisions,
        "road_edge_depth_m": road_edge_depth(cr, log), **road, "goal_occupancy": occupancy,
        "goal_missed_reason": None if goal_step is not None else miss_reason(occupancy),
        "plan_time_s": {"calls": len(plan_times),
                        "median": float(np.median(plan_times)) if plan_times else None,
                        "max": float(np.max(plan_times)) if plan_times else None},
        "sumo_vs_recording": None if recording is None else {
            "recording": str(recording), "vehicles_compared": len(devs),
            "median_abs_deviation_m": (float(np.median([np.max(np.linalg.norm(d, axis=1)) for d in devs.values()]))
                                       if devs else None),
            "max_abs_deviation_m": (float(max(np.max(np.linalg.norm(d, axis=1)) for d in devs.values()))
                                    if devs else None),
            "lane_changes_recorded": rec_changes, "lane_changes_sumo": sumo_changes,
        },
    }, log
