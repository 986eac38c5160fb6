"""SUMO as the closed loop's world: traffic, the ego as a SUMO vehicle, observations.

One :class:`Simulator` runs one episode in ``libsumo`` (SUMO linked into this process; one
simulation per process, which is why campaigns run episodes in worker processes).

The ego is the SUMO vehicle ``"ego"``.  Two modes:

* **SUMO drives** (:meth:`Simulator.release`): Krauss car following in its lane with the
  default safety checks (``speedMode 31``); its own lane changes are off
  (``laneChangeMode 0``) except a lane change requested with :meth:`request_lane_change`
  (``laneChangeMode 512``: a TraCI request that respects the other drivers' safe gaps — the
  ``sumo`` reference planner).
* **iamp drives** (:meth:`Simulator.command`): every step the ego's centre ``(x, y)``,
  speed and heading are set from the executed plan with ``moveToXY(..., keepRoute=2)`` (the
  exact position, mapped to the nearest lane, which is what the other drivers see) and
  ``setSpeed`` with ``speedMode 0`` (no SUMO check overrides the plan).  SUMO's drivers react
  to it: a follower whose lane the ego enters brakes, a leader does not yield.

**Courteous followers** (:class:`Courtesy`, :meth:`Simulator.signal`): while the ego wants to
change lanes its indicator is on, and the target-lane vehicle nearest behind its centre (within
:meth:`Courtesy.reach`: the RSS distance it must keep behind the ego plus 60.5 m) — if the
drivers are cooperative (``--cooperation`` not ``low``) — opens a gap to it with
SUMO's gap control (``vehicle.openGap`` with the ego as reference vehicle): its desired time and
space headway grow to what RSS asks behind the ego at its speed, braking for it at most
``max_decel``.  Only that follower, only while the indicator is on; the loop's verification does
not know of it (it keeps RSS's worst case: the follower may not yield).

SUMO's position is the front bumper; everything here is converted to vehicle **centres**
(``centre = front - L/2·(cos ψ, sin ψ)``).  Collisions are reported, not resolved
(``--collision.action warn``, ``--collision.check-junctions``): no teleport removes a
vehicle from the record.  SUMO's lane changes are continuous (``--lanechange.duration``),
so SUMO drivers and the ``sumo`` ego move laterally over seconds, not in one step.
"""

from __future__ import annotations

import itertools
import math
import re
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from iamp.simulation.network import Highway, build_network, require_sumo
from iamp.simulation.rss import DEFAULT as RSS_DEFAULT
from iamp.simulation.rss import RssParameters, safe_longitudinal_distance
from iamp.simulation.traffic import routes_xml

EGO = "ego"
TRUCK = "truck_lead"
#: laneChangeMode: no own lane changes / a TraCI request that respects others' safe gaps.
LC_NONE, LC_REQUEST_SAFE = 0, 512
#: speedMode: all SUMO checks / none (iamp sets the speed).
SPEED_CHECKED, SPEED_UNCHECKED = 31, 0
#: SUMO's signal bits (TraCI vehicle signalling): right and left indicator.
BLINKER_RIGHT, BLINKER_LEFT = 1, 2


@dataclass(frozen=True)
class Courtesy:
    """A cooperative target-lane follower opens a gap for the signalling ego (zipper merge).

    The follower's gap control (SUMO ``vehicle.openGap``, reference vehicle the ego) raises its
    desired time headway to ``max(τ, (d + m)/v)`` and its space headway to ``d + m``, with ``d``
    the RSS safe distance (:func:`iamp.simulation.rss.safe_longitudinal_distance`, ``rss``) of
    the follower at its speed ``v`` behind the ego at the same speed and ``m = margin_m``, both at
    the request; SUMO changes the headways at ``change_rate`` per second and brakes for them at
    most ``max_decel``, and keeps them ``duration_s`` after they are attained.

    Parameters
    ----------
    max_decel : float
        The largest deceleration the gap control may use [m/s²]: 2 m/s², the comfortable
        deceleration ``b`` of Treiber's highway IDM (:class:`iamp.simulation.mobil.IDM`).
    change_rate : float
        SUMO's ``changeRate`` [1/s] (1 reaches the new headway within 1 s).
    duration_s : float
        How long the headway is kept once attained [s] (ended earlier when the indicator goes off).
    range_m : float
        A follower is asked while its centre is at most its RSS distance behind the ego plus
        ``margin_m`` and this behind the ego's centre (:meth:`reach`) [m].
    rss : RssParameters
    margin_m : float
        Added to the RSS distance [m] (the verification's ``margin_x``).
    """

    max_decel: float = 2.0
    change_rate: float = 0.5
    duration_s: float = 10.0
    range_m: float = 60.0
    rss: RssParameters = RSS_DEFAULT
    margin_m: float = 0.5

    def reach(self, v: float, v_ego: float) -> float:
        """How far behind the ego's centre a follower at ``v`` is asked when the ego drives at ``v_ego``
        [m]: the RSS distance ``d(v, v_ego)`` it will have to keep behind the ego (``rss``) plus
        ``margin_m`` and ``range_m`` — a driver the merge will concern, seen in time to open the gap
        at ``max_decel``. (With ``range_m`` alone, 60 m, a follower 117 m behind at 31.8 m/s, which
        RSS keeps 130 m behind an ego at 18.9 m/s, was asked only 60 m behind, too late: the
        on-ramp in medium traffic, seeds 1, 2, 12, 25, 27, 30, 34, 40.)"""
        return float(safe_longitudinal_distance(max(v, 0.0), max(v_ego, 0.0), self.rss)) + self.margin_m + self.range_m

    def headways(self, v: float, tau: float) -> tuple[float, float]:
        """``(time headway [s], space headway [m])`` asked of a follower at ``v`` whose own is ``tau``."""
        space = float(safe_longitudinal_distance(max(v, 0.0), max(v, 0.0), self.rss)) + self.margin_m
        return max(tau, space / v if v > 0.1 else tau), space


#: Below this speed [m/s] the commanded velocity does not set the ego's heading (it keeps the last
#: one): at a standstill ``atan2(v_y, v_x)`` of a residual lateral speed turned the car by up to 90°
#: and put its centre half a length (2.4 m) sideways when iamp took the wheel back after an abort.
HEADING_MIN_SPEED = 0.5


@dataclass(frozen=True)
class Observation:
    """Surrounding vehicles at one step (centres; arrays indexed like ``ids``)."""

    t: float
    ids: tuple[str, ...]
    x: np.ndarray
    y: np.ndarray
    v: np.ndarray
    a: np.ndarray
    lane: np.ndarray
    length: np.ndarray
    width: np.ndarray
    #: SUMO's heading of each vehicle [rad, counter-clockwise from +x] (for the monitor's oriented bodies).
    heading: np.ndarray | None = None


@dataclass
class EgoState:
    """Ego centre state ``(x, v_x, y, v_y)`` and its last input ``(a_x, a_y)``."""

    x: float
    vx: float
    y: float
    vy: float
    ax: float = 0.0
    ay: float = 0.0


class TrackBuffer:
    """One vehicle's observed ``(t, x)`` samples, oldest first, in two growing arrays (the kept
    window is ``t[lo:hi]``, ``x[lo:hi]``; the arrays are compacted when full).

    The same samples as a queue of pairs, without building arrays from Python lists every
    period (:meth:`Simulator.history`).
    """

    __slots__ = ("hi", "last", "lo", "t", "x")

    def __init__(self, capacity: int = 64) -> None:
        self.t = np.empty(capacity)
        self.x = np.empty(capacity)
        self.lo = 0
        self.hi = 0
        #: The newest sample's time as the Python float stored (``t[hi - 1]`` when ``hi > lo``), so
        #: that :meth:`record` compares without reading a numpy scalar.
        self.last = 0.0

    def __len__(self) -> int:
        return self.hi - self.lo

    def record(self, t: float, x: float, oldest: float) -> None:
        """Append the sample ``(t, x)``, replacing the last one when it is not older than ``t - 1e-9``
        (observed twice in a step), and drop the samples before ``oldest``."""
        lo, hi, tt = self.lo, self.hi, self.t
        if hi > lo and self.last >= t - 1e-9:
            hi -= 1
        if hi == tt.size:
            n = hi - lo
            if 2 * n > tt.size:  # more than half full after compaction: grow
                self.t = np.concatenate([tt, np.empty(tt.size)])
                self.x = np.concatenate([self.x, np.empty(self.x.size)])
            self.t[:n] = tt[lo:hi].copy()
            self.x[:n] = self.x[lo:hi].copy()
            lo, hi, tt = 0, n, self.t
        tt[hi] = t
        self.x[hi] = x
        self.last = tt.item(hi)
        hi += 1
        while hi > lo and tt.item(lo) < oldest:
            lo += 1
        self.lo, self.hi = lo, hi


@dataclass
class Simulator:
    """One SUMO episode.

    Parameters
    ----------
    traffic : {"light", "medium", "dense"}
    seed : int
        SUMO's ``--seed`` and the seed of the initial platoon.
    step : float
        SUMO step = control period [s].
    highway : Highway
    ego_lane, ego_pos : int, float
        Where the ego departs (front bumper at ``ego_pos``).
    radius : float
        Neighbours within this distance of the ego are observed [m].
    history_s : float
        Length of the kept histories [s].
    """

    traffic: str
    seed: int
    step: float = 0.1
    highway: Highway = field(default_factory=Highway)
    ego_lane: int = 1
    ego_pos: float = 400.0
    radius: float = 150.0
    history_s: float = 3.0
    lanechange_duration: float = 3.0
    t: float = 0.0
    #: Each observed vehicle's kept history (:class:`TrackBuffer`: times and centre ``x``).
    histories: dict[str, TrackBuffer] = field(default_factory=dict)
    collisions: list[tuple[float, str, str]] = field(default_factory=list)
    ego_length: float = 4.8
    ego_width: float = 1.8
    empty_lanes: tuple[int, ...] = ()
    cooperation: dict[str, float] = field(default_factory=dict)
    truck: tuple[float, float] | None = None
    sublane: bool = False
    #: The initial platoon's vehicles SUMO could not insert at ``t = 0``, removed (:meth:`start`).
    not_inserted: tuple[str, ...] = ()
    _initial: frozenset[str] = frozenset()
    #: Courteous target-lane followers (None: drivers do not yield, ``--cooperation low``).
    courtesy: Courtesy | None = None
    #: Every courtesy request ``(t, follower, time headway, space headway, max_decel)`` (for the record).
    courtesy_log: list[tuple[float, str, float, float, float]] = field(default_factory=list)
    _yielding: str | None = None
    _signals: int = 0
    _lengths: dict[str, tuple[float, float]] = field(default_factory=dict)
    _tmp: Any = None
    _ls: Any = None
    #: The ego's last heading [rad]: SUMO's when it drives, the commanded velocity's direction when
    #: iamp drives above :data:`HEADING_MIN_SPEED`; kept below it (a standstill has no direction).
    _heading: float = 0.0

    def start(self) -> None:
        """Build the network, write the routes, start ``libsumo``."""
        require_sumo()
        import libsumo

        net = build_network(self.highway)
        self._tmp = tempfile.TemporaryDirectory(prefix="iamp-sim-")
        routes = Path(self._tmp.name) / "episode.rou.xml"
        xml = routes_xml(self.traffic, self.seed, lanes=self.highway.lanes, edge=self.highway.edge,
                         ego_pos=self.ego_pos, ego_lane=self.ego_lane, highway=self.highway,
                         empty_lanes=self.empty_lanes, cooperation=self.cooperation,
                         truck=self.truck, sublane=self.sublane)
        routes.write_text(xml)
        self._initial = frozenset(re.findall(r'<vehicle id="([^"]+)"', xml)) - {EGO, TRUCK}
        if libsumo.simulation.isLoaded():
            libsumo.close()
        libsumo.start(["sumo", "-n", str(net), "-r", str(routes), "--step-length", f"{self.step:g}",
                       "--seed", str(int(self.seed)), "--begin", "0", "--no-step-log", "--no-warnings",
                       "--collision.action", "warn", "--collision.check-junctions",
                       "--collision.mingap-factor", "0",
                       *(["--lateral-resolution", "0.8"] if self.sublane else
                         ["--lanechange.duration", f"{self.lanechange_duration:g}"]),
                       "--default.action-step-length", f"{self.step:g}",
                       # each vehicle of the initial platoon is inserted or refused on its own (by
                       # default one refused vehicle holds back every later one on its edge)
                       "--eager-insert"])
        self._ls = libsumo
        libsumo.simulationStep()  # t = step: the ego and the initial platoon are inserted
        self.t = float(libsumo.simulation.getTime())
        if EGO not in libsumo.vehicle.getIDList():
            raise RuntimeError("SUMO could not insert the ego")  # pragma: no cover
        # an initial vehicle that SUMO refused at t = 0 (its follower could not brake for it, e.g. a
        # slow truck just ahead of the ego) would wait and appear later at its departure position,
        # beside whatever is there then: out of nowhere, next to the ego (merge dense seed 3: 18
        # vehicles; slow-leader medium 55: one 33 m ahead of the ego in its lane, 8.7 s into the
        # mission).  Such vehicles are removed before they depart; the inflow's are not (they enter
        # at the road's start, far behind the ego, when there is room)
        self.not_inserted = tuple(v for v in libsumo.simulation.getPendingVehicles() if v in self._initial)
        for vid in self.not_inserted:
            libsumo.vehicle.remove(vid)
        if self.truck is not None and TRUCK not in libsumo.vehicle.getIDList():
            raise RuntimeError("SUMO could not insert the slow-leader truck")  # pragma: no cover
        libsumo.vehicle.setLaneChangeMode(EGO, LC_NONE)
        if self.truck is not None and TRUCK in libsumo.vehicle.getIDList():
            libsumo.vehicle.setLaneChangeMode(TRUCK, LC_NONE)
        libsumo.vehicle.subscribeContext(EGO, libsumo.CMD_GET_VEHICLE_VARIABLE, self.radius,
                                         [libsumo.VAR_POSITION, libsumo.VAR_SPEED, libsumo.VAR_LANE_INDEX,
                                          libsumo.VAR_ACCELERATION, libsumo.VAR_ANGLE])
        self.ego_length = float(libsumo.vehicle.getLength(EGO))
        self.ego_width = float(libsumo.vehicle.getWidth(EGO))
        libsumo.simulationStep()
        self.t = float(libsumo.simulation.getTime())

    def close(self) -> None:
        if self._ls is not None:
            self._ls.close()
            self._ls = None
        if self._tmp is not None:
            self._tmp.cleanup()
            self._tmp = None

    # -- stepping -------------------------------------------------------------------------
    def advance(self) -> None:
        """One SUMO step; records SUMO's collision reports involving the ego."""
        ls = self._ls
        ls.simulationStep()
        self.t = float(ls.simulation.getTime())
        for c in ls.simulation.getCollisions():
            if EGO in (c.collider, c.victim):
                other = c.victim if c.collider == EGO else c.collider
                self.collisions.append((self.t, other, str(c.type)))

    # -- observation ------------------------------------------------------------------------
    def _size(self, vid: str) -> tuple[float, float]:
        size = self._lengths.get(vid)
        if size is None:
            size = (float(self._ls.vehicle.getLength(vid)), float(self._ls.vehicle.getWidth(vid)))
            self._lengths[vid] = size
        return size

    @property
    def ego_heading(self) -> float:
        """The ego's heading as SUMO has it now [rad] (for the monitor's oriented bodies)."""
        return self._heading

    def ego(self) -> EgoState:
        """The ego's centre state as SUMO has it (used when SUMO drives)."""
        ls = self._ls
        fx, fy = ls.vehicle.getPosition(EGO)
        psi = math.radians(90.0 - float(ls.vehicle.getAngle(EGO)))
        self._heading = psi
        v = float(ls.vehicle.getSpeed(EGO))
        half = self.ego_length / 2
        vy = float(ls.vehicle.getLateralSpeed(EGO)) if hasattr(ls.vehicle, "getLateralSpeed") else 0.0
        return EgoState(x=fx - half * math.cos(psi), vx=v * math.cos(psi), y=fy - half * math.sin(psi), vy=vy,
                        ax=float(ls.vehicle.getAcceleration(EGO)))

    def observe(self) -> Observation:
        """Neighbours within ``radius`` (context subscription); updates the histories."""
        ls = self._ls
        res = ls.vehicle.getContextSubscriptionResults(EGO) or {}
        ids = tuple(sorted(k for k in res if k != EGO))
        P, S, A, ANG = ls.VAR_POSITION, ls.VAR_SPEED, ls.VAR_ACCELERATION, ls.VAR_ANGLE
        oldest = self.t - (self.history_s + 1e-6)
        cos, sin, radians = math.cos, math.sin, math.radians
        sizes, histories, t = self._lengths, self.histories, self.t
        rows: list[tuple[float, float, float, float, float, float, float]] = []
        for vid in ids:  # Python floats: the same IEEE operations as on array elements
            r = res[vid]
            size = sizes.get(vid)
            length, width = size if size is not None else self._size(vid)
            psi = radians(90.0 - float(r[ANG]))
            fx, fy = r[P]
            xk = fx - length / 2 * cos(psi)
            yk = fy - length / 2 * sin(psi)
            rows.append((xk, yk, r[S], r[A], length, width, psi))
            hist = histories.get(vid)
            if hist is None:
                hist = histories[vid] = TrackBuffer()
            hist.record(t, float(xk), oldest)
        if len(histories) > len(ids):
            for vid in [k for k in histories if k not in res]:
                del histories[vid]
        # one row per quantity: the rows' floats read in order into one array (np.array of the list of
        # tuples gives the same floats after discovering its shape element by element)
        cols = np.fromiter(itertools.chain.from_iterable(rows), dtype=np.float64,
                           count=7 * len(rows)).reshape(len(rows), 7).T.copy()
        x, y, v, a, L, W, H = cols
        # global lane indices (edges downstream of a drop have fewer): Highway.lane_of of each y at once
        return Observation(self.t, ids, x, y, v, a, self.highway.lanes_of(y), L, W, H)

    def history(self, vid: str) -> tuple[np.ndarray, np.ndarray]:
        """``(t - now, x)`` of the last ``history_s`` seconds of ``vid`` (may be shorter)."""
        h = self.histories.get(vid)
        if h is None:
            return np.array([]) - self.t, np.array([])
        t = h.t[h.lo:h.hi] - self.t
        x = h.x[h.lo:h.hi].copy()
        if t.size:
            t = np.round(t, 9)
            t[-1] = 0.0
        return t, x

    def histories_of(self, vids: Sequence[str]) -> list[tuple[np.ndarray, np.ndarray]]:
        """:meth:`history` of each of ``vids``, computing the times once per distinct window: vehicles
        observed at the same steps share one read-only time array (the same object), and the positions
        are read-only views of the kept samples.

        Parameters
        ----------
        vids : sequence of str

        Returns
        -------
        list of (numpy.ndarray, numpy.ndarray)
            ``(t - now, x)`` per vehicle, equal to :meth:`history`'s.
        """
        times: dict[bytes, np.ndarray] = {}
        out = []
        for vid in vids:
            h = self.histories.get(vid)
            if h is None or h.hi == h.lo:
                t, x = self.history(vid)
            else:
                raw = h.t[h.lo:h.hi]
                key = raw.tobytes()
                t = times.get(key)  # type: ignore[assignment]
                if t is None:
                    t = np.round(raw - self.t, 9)
                    t[-1] = 0.0
                    t.setflags(write=False)
                    times[key] = t
                x = h.x[h.lo:h.hi]
                x.setflags(write=False)
            out.append((t, x))
        return out

    # -- ego control -------------------------------------------------------------------------
    def command(self, state: EgoState) -> None:
        """Place the ego's centre at ``state`` for the next step (iamp drives)."""
        ls = self._ls
        if math.hypot(state.vx, state.vy) >= HEADING_MIN_SPEED:
            self._heading = math.atan2(state.vy, max(state.vx, 1e-6))
        psi = self._heading  # at a standstill the last heading: the velocity's direction is noise there
        half = self.ego_length / 2
        fx, fy = state.x + half * math.cos(psi), state.y + half * math.sin(psi)
        eid, _, first = self.highway.edge_at(fx)
        lane = max(self.highway.lane_of(state.y), first)
        ls.vehicle.setSpeedMode(EGO, SPEED_UNCHECKED)
        ls.vehicle.moveToXY(EGO, eid, lane, fx, fy, 90.0 - math.degrees(psi), 2)
        ls.vehicle.setSpeed(EGO, max(math.hypot(state.vx, state.vy), 0.0))

    def release(self) -> None:
        """Hand the ego back to SUMO's driver model (no own lane changes)."""
        ls = self._ls
        ls.vehicle.setSpeed(EGO, -1.0)
        ls.vehicle.setSpeedMode(EGO, SPEED_CHECKED)
        ls.vehicle.setLaneChangeMode(EGO, LC_NONE)

    def request_lane_change(self, lane: int, duration: float) -> None:
        """The ``sumo`` reference: ask LC2013 to change to ``lane`` when it judges it safe."""
        ls = self._ls
        ls.vehicle.setLaneChangeMode(EGO, LC_REQUEST_SAFE)
        _, _, first = self.highway.edge_at(self.ego().x)
        ls.vehicle.changeLane(EGO, max(int(lane), first), float(duration))

    def signal(self, target_lane: int | None, obs: Observation, ego: EgoState) -> str | None:
        """The ego's indicator toward ``target_lane`` (``None``: off) and the courtesy it asks
        (:class:`Courtesy`): the target-lane vehicle nearest behind the ego's centre within
        :meth:`Courtesy.reach` opens a gap while the indicator is on; a follower no longer asked (the
        indicator off, or another follower nearest) gets its own headways back.

        Returns
        -------
        str or None
            The follower yielding now.
        """
        ls = self._ls
        lane = self.highway.lane_of(ego.y)
        bits = 0 if target_lane is None or target_lane == lane else \
            (BLINKER_LEFT if target_lane > lane else BLINKER_RIGHT)
        if bits or self._signals:  # SUMO resets a vehicle's signals every step: set them every step
            ls.vehicle.setSignals(EGO, bits if bits else -1)  # -1: SUMO's own signals again
            self._signals = bits
        want: str | None = None
        if bits and self.courtesy is not None:
            asked = self.courtesy
            behind = [(ego.x - float(x), vid) for vid, x, v, ln in zip(obs.ids, obs.x, obs.v, obs.lane)
                      if int(ln) == target_lane and 0.0 <= ego.x - float(x) <= asked.reach(float(v), ego.vx)]
            want = min(behind)[1] if behind else None
        if want != self._yielding:
            if self._yielding is not None and self._yielding in ls.vehicle.getIDList():
                ls.vehicle.deactivateGapControl(self._yielding)
            if want is not None:
                c = self.courtesy
                assert c is not None
                k = obs.ids.index(want)
                tau, space = c.headways(float(obs.v[k]), float(ls.vehicle.getTau(want)))
                ls.vehicle.openGap(want, tau, space, c.duration_s, c.change_rate, c.max_decel, EGO)
                self.courtesy_log.append((self.t, want, tau, space, c.max_decel))
            self._yielding = want
        return want

    def ego_lane_index(self) -> int:
        """The ego's global lane index (from its centre's ``y``)."""
        return self.highway.lane_of(self.ego().y)

    def ego_lateral_offset(self) -> float:
        return float(self._ls.vehicle.getLateralLanePosition(EGO))
