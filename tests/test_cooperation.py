"""Courteous target-lane followers (issue 30; SPEC §17; :class:`iamp.simulation.simulator.Courtesy`).

The courtesy is a property of SUMO's traffic: while the ego signals, the target-lane vehicle nearest
behind its centre opens a gap (SUMO's ``vehicle.openGap``) with a bounded deceleration, unless the
drivers are uncooperative (``--cooperation low``).  These tests drive :meth:`Simulator.signal`
against a recording stand-in for ``libsumo`` (no SUMO needed).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from iamp.core.errors import ScenarioError
from iamp.simulation.missions import COURTESY, courtesy_of
from iamp.simulation.network import Highway
from iamp.simulation.rss import DEFAULT, safe_longitudinal_distance
from iamp.simulation.simulator import BLINKER_LEFT, EGO, Courtesy, EgoState, Observation, Simulator


class _Vehicle:
    def __init__(self, ids: tuple[str, ...], tau: float = 1.0) -> None:
        self.calls: list[tuple[str, tuple[Any, ...]]] = []
        self.ids = (EGO, *ids)
        self.tau = tau

    def getIDList(self) -> tuple[str, ...]:
        return self.ids

    def getTau(self, vid: str) -> float:
        return self.tau

    def __getattr__(self, name: str) -> Any:
        def record(*args: Any) -> None:
            self.calls.append((name, args))
        return record


class _Ls:
    def __init__(self, ids: tuple[str, ...], tau: float = 1.0) -> None:
        self.vehicle = _Vehicle(ids, tau)


HW = Highway()


def _world(cars: list[tuple[str, float, int, float]], courtesy: Courtesy | None, tau: float = 1.0
           ) -> tuple[Simulator, Observation, EgoState, _Vehicle]:
    """The ego in lane 0 at x = 500 m, 15 m/s; ``cars`` = (id, x, lane, v)."""
    sim = Simulator("dense", 1, highway=HW, courtesy=courtesy)
    ls = _Ls(tuple(c[0] for c in cars), tau)
    sim._ls = ls
    n = len(cars)
    obs = Observation(0.0, tuple(c[0] for c in cars), np.array([c[1] for c in cars], dtype=float),
                      np.array([HW.lane_centre(c[2]) for c in cars], dtype=float),
                      np.array([c[3] for c in cars], dtype=float), np.zeros(n),
                      np.array([c[2] for c in cars], dtype=int), np.full(n, 4.6), np.full(n, 1.8))
    return sim, obs, EgoState(500.0, 15.0, HW.lane_centre(0), 0.0), ls.vehicle


def _opened(v: _Vehicle) -> list[tuple[Any, ...]]:
    return [a for name, a in v.calls if name == "openGap"]


CARS = [("ahead", 520.0, 1, 15.0), ("near", 480.0, 1, 14.0), ("far", 450.0, 1, 16.0),
        ("other_lane", 495.0, 2, 15.0), ("own_lane", 490.0, 0, 15.0)]


def test_only_the_signalled_cooperative_follower_opens_a_gap_with_bounded_braking():
    sim, obs, ego, v = _world(CARS, Courtesy())
    assert sim.signal(1, obs, ego) == "near"
    (args,) = _opened(v)
    vid, tau, space, duration, rate, max_decel, ref = args
    assert vid == "near" and ref == EGO
    assert 0 < max_decel <= 2.0  # comfortable: Treiber's IDM b
    d = float(safe_longitudinal_distance(14.0, 14.0, DEFAULT))
    assert space == pytest.approx(d + 0.5)  # RSS's distance behind the ego at the follower's speed
    assert tau == pytest.approx(max(1.0, (d + 0.5) / 14.0)) and tau * 14.0 >= space - 1e-9
    assert duration > 0 and rate > 0
    assert ("setSignals", (EGO, BLINKER_LEFT)) in v.calls
    # asked once: the next periods keep the request (SUMO would restart the headway change)
    sim.signal(1, obs, ego)
    assert len(_opened(v)) == 1 and sim.courtesy_log == [(sim.t, "near", tau, space, max_decel)]


def test_the_indicator_off_gives_the_follower_its_own_headway_back():
    sim, obs, ego, v = _world(CARS, Courtesy())
    sim.signal(1, obs, ego)
    assert sim.signal(None, obs, ego) is None
    assert ("deactivateGapControl", ("near",)) in v.calls
    assert ("setSignals", (EGO, -1)) in v.calls  # SUMO's own signals again
    n = len(v.calls)
    sim.signal(None, obs, ego)
    assert len(v.calls) == n  # nothing more to say while off


def test_another_nearest_follower_takes_over_and_the_first_stops_yielding():
    sim, obs, ego, v = _world(CARS, Courtesy())
    sim.signal(1, obs, ego)
    ego2 = EgoState(470.0, 15.0, HW.lane_centre(0), 0.0)  # the ego dropped back: "far" is nearest behind
    assert sim.signal(1, obs, ego2) == "far"
    names = [c[0] for c in v.calls if c[0] in ("openGap", "deactivateGapControl")]
    assert names == ["openGap", "deactivateGapControl", "openGap"]
    assert [a[0] for a in _opened(v)] == ["near", "far"]


def test_uncooperative_drivers_never_yield_but_the_indicator_is_on():
    assert courtesy_of("low") is None and COURTESY["low"] is None
    sim, obs, ego, v = _world(CARS, courtesy_of("low"))
    assert sim.signal(1, obs, ego) is None
    assert _opened(v) == [] and ("setSignals", (EGO, BLINKER_LEFT)) in v.calls


@pytest.mark.parametrize("level", ["default", "high"])
def test_cooperative_levels_have_a_courtesy(level):
    c = courtesy_of(level)
    assert c is not None and c.max_decel <= 2.0


def test_an_unknown_level_is_a_scenario_error():
    with pytest.raises(ScenarioError, match="cooperation"):
        courtesy_of("polite")


def test_nobody_behind_within_reach_nobody_asked():
    """The reach is the follower's RSS distance behind the ego plus 60.5 m: at 15 m/s both, 1 m
    beyond it nobody is asked, 1 m inside it the follower is."""
    reach = Courtesy().reach(15.0, 15.0)
    sim, obs, ego, v = _world([("ahead", 520.0, 1, 15.0), ("far", 500.0 - reach - 1.0, 1, 15.0)], Courtesy())
    assert sim.signal(1, obs, ego) is None and _opened(v) == []
    sim, obs, ego, v = _world([("ahead", 520.0, 1, 15.0), ("far", 500.0 - reach + 1.0, 1, 15.0)], Courtesy())
    assert sim.signal(1, obs, ego) == "far"


@settings(max_examples=60, deadline=None, derandomize=True)
@given(st.lists(st.tuples(st.floats(380.0, 620.0), st.integers(0, 2), st.floats(0.0, 35.0)), max_size=8),
       st.floats(0.0, 4.0))
def test_the_request_goes_to_the_nearest_target_lane_vehicle_behind(cars, tau):
    """Property: exactly the nearest target-lane vehicle within its reach behind the ego's centre is
    asked, with a deceleration within the bound and headways not below its own or RSS's distance."""
    named = [(f"v{k}", x, lane, v) for k, (x, lane, v) in enumerate(cars)]
    c = Courtesy()
    sim, obs, ego, veh = _world(named, c, tau)
    got = sim.signal(1, obs, ego)
    behind = [(ego.x - x, n) for n, x, lane, w in named if lane == 1 and 0.0 <= ego.x - x <= c.reach(w, ego.vx)]
    want = min(behind)[1] if behind else None
    assert got == want
    opened = _opened(veh)
    assert len(opened) == (want is not None)
    for vid, t_h, space, _, _, max_decel, ref in opened:
        v = dict((n, s) for n, _, _, s in named)[vid]
        assert ref == EGO and max_decel <= 2.0
        assert t_h >= tau and space >= float(safe_longitudinal_distance(v, v, DEFAULT))


def test_the_campaign_manifest_records_the_courtesy():
    from iamp.simulation.campaign import manifest_of

    episode = {"duration_s": 60.0, "period_s": 0.1, "deadline_s": None, "warmup_s": 5.0, "settle_s": 8.0,
               "sublane": False, "ego_in_forecast": False}
    default = manifest_of(["merge"], ["free"], ["dense"], 1, {**episode, "cooperation": "default"})
    low = manifest_of(["merge"], ["free"], ["dense"], 1, {**episode, "cooperation": "low"})
    assert default["courtesy"]["max_decel"] == 2.0
    assert default["courtesy"]["rss"]["response_time_s"] == DEFAULT.response_time_s
    assert low["courtesy"] is None


def _onramp(monkeypatch: pytest.MonkeyPatch, courtesy: bool) -> tuple[dict[str, Any], list[tuple[Any, ...]]]:
    """Onramp, dense, seed 1, ``free``, 20 s in SUMO; the courtesy requests made."""
    pytest.importorskip("libsumo")
    from iamp.simulation import missions
    from iamp.simulation.episode import EpisodeSpec, run_episode

    if not courtesy:
        monkeypatch.setitem(missions.COURTESY, "default", None)
    requests: list[tuple[Any, ...]] = []
    close = Simulator.close

    def spy(self: Simulator) -> None:
        requests.extend(self.courtesy_log)
        close(self)

    monkeypatch.setattr(Simulator, "close", spy)
    r = run_episode(EpisodeSpec(mission="onramp", traffic="dense", seed=1, planner="free", duration_s=20.0))
    return r.summary, requests


def test_in_sumo_the_yielding_follower_lets_the_ramp_ego_merge_safely(monkeypatch):
    """Onramp dense seed 1: the target lane flows at ~16 m/s with gaps RSS's distances (33 m a side)
    do not fit; a courteous follower opens one and the ego merges with no RSS-dangerous time."""
    s, requests = _onramp(monkeypatch, courtesy=True)
    assert requests and all(r[4] <= 2.0 for r in requests)
    assert len({r[1] for r in requests}) == len(requests)  # one request per follower
    assert s["success"] is True and s["rss_dangerous_s"] == 0.0 and s["contacts"] == 0
    assert s["follower_emergency_brakes"] == 0


def test_in_sumo_without_courtesy_the_same_ramp_ego_does_not_merge(monkeypatch):
    """Without courtesy the ego finds no gap in the 20 s, and is never in an RSS-dangerous
    situation (before episode format 17.5 it stood at the ramp's end by then; now it drives the
    ramp at about 8 m/s seeking a gap and has not reached the end at 20 s)."""
    s, requests = _onramp(monkeypatch, courtesy=False)
    assert requests == []
    assert s["success"] is False and s["time_to_merge_s"] is None and s["rss_dangerous_s"] == 0.0
