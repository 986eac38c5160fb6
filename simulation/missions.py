r"""The closed loop's missions (SPEC §15): what the ego must do, where, by when.

==================  ==========================================================================
mission             the task
==================  ==========================================================================
``merge``           the ego drives in the rightmost lane (0), which ends ``lane_end_m = 400`` m
                    after the warm-up (a lane drop, edge ``hw1`` → ``hw2``); it must reach lane 1
                    before the end.  SUMO's drivers in lane 0 must merge too.
``onramp``          the ego enters on a ramp (lane 0 upstream of ``ramp_x``, 60 km/h), then has
                    an acceleration lane of ``lane_end_m = 250`` m; no other traffic uses the ramp.
``slow-leader``     a truck at 60 km/h (``truck_lead``, no lane changes) 60 m ahead of the ego in
                    the middle lane; the ego must pass it on the left (reach lane 2) within
                    ``deadline_s``.
``discretionary``   the old pipeline check: middle ↔ left lane changes, one after another.
==================  ==========================================================================

**Warm-up and the mission clock.**  SUMO drives the ego in its lane for at least
``warmup_s`` and until its centre reaches ``start_x`` (for ``merge`` and ``onramp`` the point
``lane_end_m`` before the end of its lane), so the distance left when the clock starts at 0
is the mission's, whatever the traffic did during the warm-up (it is reported as
``distance_to_end_m``).

**Success.**  ``success`` = the ego's centre is in the target lane before the deadline (for
a lane end: before its front bumper passes the end, ``x + L/2 < drop_x``), and no contact in
the whole episode.  ``time_to_merge_s`` is the first time the centre is in the target lane.
``stopped_at_end``: the ego never merged and stood still (``v < 0.5`` m/s) within 30 m of
its lane's end.

**Cooperation of SUMO's drivers** (``--cooperation``, applied to every driver type):

===========  ================  ==============  ===============  ==========================
level        ``lcCooperative``  ``lcAssertive``  ``lcSpeedGain``  ``sigma`` (Krauss)
===========  ================  ==============  ===============  ==========================
``low``      0.0               1.5             2.0              0.7
``default``  the type's (1.0)  the type's      the type's        the type's (0.3..0.8)
``high``     1.0               0.7             0.5              0.2
===========  ================  ==============  ===============  ==========================

(``lcCooperative`` is LC2013's willingness to change lanes or adapt speed for others who must
change; ``lcAssertive`` how small a gap a driver accepts for itself; ``sigma`` the Krauss
driver's imperfection.)

**Courteous followers** (:data:`COURTESY`): with ``default`` and ``high`` cooperation the
target-lane vehicle nearest behind the signalling ego opens a gap for it
(:class:`iamp.simulation.simulator.Courtesy`: RSS's distance behind the ego, braking at most
2 m/s²), for every planner that drives the ego, the baselines included; with ``low``
(``lcCooperative = 0``) nobody yields.
"""

from __future__ import annotations

from dataclasses import dataclass

from iamp.core.errors import ScenarioError
from iamp.simulation.network import Highway
from iamp.simulation.simulator import Courtesy

#: Where the ego departs (front bumper, SUMO's ``departPos``) [m].
EGO_DEPART_M = 400.0


@dataclass(frozen=True)
class Mission:
    """One mission (see the module docstring).

    Parameters
    ----------
    name : str
    ego_lane, target_lane : int
        Global lane indices (0 = rightmost).
    lane_end_m : float or None
        Distance from the start of the mission clock to the end of the ego's lane.
    start_x : float
        The mission clock starts when the ego's centre reaches this ``x`` (and after the warm-up).
    deadline_s : float
        The target lane must be reached within this time.
    ramp : bool
        Lane 0 upstream of the acceleration lane is a ramp (no traffic but the ego).
    truck : bool
        A slow truck leads the ego.
    alternating : bool
        After each lane change the next is towards the other lane (``discretionary``).
    """

    name: str
    ego_lane: int
    target_lane: int
    lane_end_m: float | None
    start_x: float
    deadline_s: float
    ramp: bool = False
    truck: bool = False
    alternating: bool = False
    truck_speed: float = 16.67
    truck_ahead_m: float = 60.0

    def highway(self) -> Highway:
        """The road of this mission."""
        if self.lane_end_m is None:
            return Highway()
        drop = self.start_x + self.lane_end_m
        return Highway(drop_x=drop, ramp_x=self.start_x if self.ramp else None)

    @property
    def drop_x(self) -> float | None:
        return None if self.lane_end_m is None else self.start_x + self.lane_end_m


MISSIONS: dict[str, Mission] = {
    "merge": Mission("merge", 0, 1, 400.0, EGO_DEPART_M + 200.0, 40.0),
    "onramp": Mission("onramp", 0, 1, 250.0, EGO_DEPART_M + 150.0, 40.0, ramp=True),
    "slow-leader": Mission("slow-leader", 1, 2, None, 0.0, 30.0, truck=True),
    "discretionary": Mission("discretionary", 1, 2, None, 0.0, 60.0, alternating=True),
}

#: ``--cooperation`` levels: vType attributes set on every SUMO driver type (``None``: keep).
COOPERATION: dict[str, dict[str, float]] = {
    "low": {"lcCooperative": 0.0, "lcAssertive": 1.5, "lcSpeedGain": 2.0, "sigma": 0.7},
    "default": {},
    "high": {"lcCooperative": 1.0, "lcAssertive": 0.7, "lcSpeedGain": 0.5, "sigma": 0.2},
}


#: ``--cooperation`` levels: the courteous follower (module docstring; ``None``: nobody yields).
COURTESY: dict[str, Courtesy | None] = {"low": None, "default": Courtesy(), "high": Courtesy()}


def courtesy_of(name: str) -> Courtesy | None:
    """The courtesy of the target-lane followers at cooperation level ``name`` (:data:`COURTESY`).

    Raises
    ------
    ScenarioError
        An unknown level.
    """
    cooperation_of(name)
    return COURTESY[name]


def mission_of(name: str) -> Mission:
    try:
        return MISSIONS[name]
    except KeyError:
        raise ScenarioError(f"unknown mission {name!r}; choose from {', '.join(MISSIONS)}", "--mission") from None


def cooperation_of(name: str) -> dict[str, float]:
    try:
        return COOPERATION[name]
    except KeyError:
        raise ScenarioError(f"unknown cooperation {name!r}; choose from {', '.join(COOPERATION)}",
                            "--cooperation") from None
