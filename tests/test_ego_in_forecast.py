"""``simulate --ego-in-forecast`` (issue 23 item 3): the decision layer plans each gap with its
follower reacting to the plan, and the option off leaves an episode exactly as before."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from iamp.core.problem import EgoBoundary, Problem
from iamp.prediction.leader.ego import follower_poly_for_plan
from iamp.prediction.leader.model import LeaderPredictor, default_leader_model
from iamp.simulation.decision import DecisionConfig, EgoNow, Gap, Neighbour, decide
from iamp.simulation.planning import free_plan, make_planner

LP = LeaderPredictor(default_leader_model())
T_HIST = np.linspace(-3.0, 0.0, 31)
Y_TARGET = 3.5
P = np.polynomial.polynomial


def _follower_poly(problem: Problem | EgoBoundary) -> tuple[float, ...]:
    assert isinstance(problem, Problem)
    (f,) = [v for v in problem.vehicles if v.name == "f"]
    return tuple(float(c) for c in f.x_poly)


@pytest.mark.parametrize("planner_name", ["pmp-active", "qp"])
@pytest.mark.parametrize(("xf", "vf", "ve"), [(-20.0, 22.0, 20.0), (-30.0, 24.0, 20.0), (-15.0, 19.0, 21.0)])
def test_each_replan_sees_the_follower_reacting_to_the_previous_plan(planner_name: str, xf: float, vf: float,
                                                                     ve: float) -> None:
    """Call k+1 of the planner gets the follower's cubic that ``follower_poly_for_plan`` computes from
    plan k (recomputed here); the iteration stops at 3 re-plans or when that cubic moved < 1 m
    (recomputed); the §9 check carries the cubic the accepted plan was made against; without
    ``react`` the planner is called once per gap with the follower's own cubic."""
    ego = EgoNow(0.0, ve, 0.0, 0.0)
    f_hist = (T_HIST, xf + vf * T_HIST)
    l_hist = (T_HIST, 45.0 + 20.0 * T_HIST)
    f = Neighbour("f", (xf, vf, 0.0, 0.0), Y_TARGET, 4.6, 1.8, 1)
    ldr = Neighbour("l", (45.0, 20.0, 0.0, 0.0), Y_TARGET, 4.4, 1.8, 1)
    cfg = DecisionConfig(max_gaps=1)
    plan_fn = make_planner(planner_name)
    calls: list[tuple[Any, Any]] = []

    def planner(prob: Problem | EgoBoundary) -> Any:
        plan = free_plan(prob, planner_name) if isinstance(prob, EgoBoundary) else plan_fn(prob)
        calls.append((prob, plan))
        return plan

    def react(gap: Gap, plan: Any, prob: Problem | EgoBoundary) -> tuple[float, ...]:
        assert gap.follower is not None and gap.leader is not None
        return follower_poly_for_plan(LP, f_hist, plan.require_trajectory().states, float(prob.tf),
                                      target_y=Y_TARGET, ego_length=ego.length, ego_width=ego.width,
                                      follower_length=gap.follower.length, leader_hist=l_hist,
                                      leader_length=gap.leader.length)

    records: list[dict[str, Any]] = []
    verdict, _ = decide(ego, Y_TARGET, 1, 0, [f, ldr], planner, cfg, react=react, react_iter=3, react_tol_m=1.0,
                        on_iterate=records.append)
    (rec,) = records
    assert 1 <= len(calls) <= 4 and rec["plans"] == len(calls)
    assert _follower_poly(calls[0][0]) == f.poly
    tt = np.linspace(0.0, cfg.horizon_s, 51)
    reacted = []
    for k, (prob, plan) in enumerate(calls):
        if plan.trajectory is None:
            reacted.append(_follower_poly(prob))
            continue
        mine = follower_poly_for_plan(LP, f_hist, plan.trajectory.states, cfg.horizon_s, target_y=Y_TARGET,
                                      ego_length=ego.length, ego_width=ego.width, follower_length=4.6,
                                      leader_hist=l_hist, leader_length=4.4)
        reacted.append(mine)
        if k + 1 < len(calls):  # the next call plans against exactly this reaction (no damping)
            np.testing.assert_allclose(_follower_poly(calls[k + 1][0]), mine, rtol=0, atol=1e-12)
    moved = [float(np.max(np.abs(P.polyval(tt, r) - P.polyval(tt, _follower_poly(p)))))
             for (p, _), r in zip(calls, reacted, strict=True)]
    np.testing.assert_allclose(rec["changes_m"], moved[: len(rec["changes_m"])], rtol=0, atol=1e-9)
    if rec["converged"]:
        assert moved[-1] < 1.0 and all(m >= 1.0 for m in moved[:-1])
    else:
        assert len(calls) == 4 and all(m >= 1.0 for m in moved[:3])
    # the verdict is the last plan, judged with the follower on the cubic it was planned against
    assert verdict.plan is calls[-1][1]
    assert verdict.gap is not None and verdict.gap.follower is not None
    assert verdict.gap.follower.poly == _follower_poly(calls[-1][0])
    if verdict.check is not None:
        (fc,) = [v for v in verdict.check.vehicles if v.name == "f"]
        assert tuple(fc.x_poly) == _follower_poly(calls[-1][0])
    # an ego cutting in ahead of a follower that is not slower than it: the reaction is behind the own forecast
    if vf >= ve and calls[0][1].trajectory is not None:
        assert P.polyval(cfg.horizon_s, reacted[0]) < P.polyval(cfg.horizon_s, f.poly)
    # off: one call, the follower's own cubic
    calls.clear()
    decide(ego, Y_TARGET, 1, 0, [f, ldr], planner, cfg)
    assert len(calls) == 1 and _follower_poly(calls[0][0]) == f.poly


# -- SUMO: the option off is the loop as it was --------------------------------------------------------
def _decide_before(ego, y_target, target_lane, origin_lane, neighbours, planner, cfg, on_plan=None, **kw):  # type: ignore[no-untyped-def]
    """``decide`` as it was before the option (copied from main 87f7981), for the identity test."""
    from iamp.simulation.decision import Verdict, candidate_gaps, check_problem, judge, lane_change_problem

    assert not kw, "the option off passes no keyword to decide"
    target = [n for n in neighbours if n.lane == target_lane]
    ahead = [n for n in neighbours if n.lane == origin_lane and n.x(0.0) > ego.x
             and n.x(0.0) - ego.x <= cfg.relevant_m]
    current_leader = min(ahead, key=lambda n: n.x(0.0)) if ahead else None
    verdicts = []
    for gap in candidate_gaps(ego, target, cfg):
        prob = lane_change_problem(ego, y_target, gap, current_leader, cfg, cfg.horizon_s)
        boundary = prob.ego if isinstance(prob, Problem) else prob
        check = check_problem(boundary, ego, neighbours, (origin_lane, target_lane), cfg)
        plan = planner(prob)
        if on_plan is not None:
            on_plan(plan, prob)
        v = Verdict(False, "", plan, gap, prob, check)
        v.reason = judge(plan, check, cfg)
        v.accepted = v.reason == "accepted"
        verdicts.append(v)
        if v.accepted:
            return v, verdicts
    return (verdicts[-1] if verdicts else Verdict(False, "no gap")), verdicts


NEW_KEYS = ("ego_in_forecast", "ego_iterations", "ego_converged", "ego_replans")


def _numbers(s: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in s.items() if k not in ("plan_time_s", "wall_s", "max_rss_mb", *NEW_KEYS)}


def test_the_option_off_gives_the_episode_of_before_bit_for_bit(monkeypatch: pytest.MonkeyPatch) -> None:
    pytest.importorskip("libsumo")
    import iamp.simulation.controller as controller
    import iamp.simulation.decision as decision
    from iamp.simulation.controller import ControllerConfig
    from iamp.simulation.episode import EpisodeSpec, run_episode

    # the loop of before SPEC §17's verification (ControllerConfig(safe=False)), where ``decide`` was
    # called without keywords: the option off must leave its episode exactly as it was
    old_loop = ControllerConfig(safe=False)
    spec = EpisodeSpec(traffic="medium", seed=1, planner="pmp-active", mission="merge", duration_s=10.0)
    now = run_episode(spec, config=old_loop)

    def never(*a: Any, **k: Any) -> Any:
        raise AssertionError("the iteration ran with the option off")

    monkeypatch.setattr(decision, "iterate_with_planner", never)
    monkeypatch.setattr(controller, "decide", _decide_before)
    before = run_episode(spec, config=old_loop)
    assert now.summary["ego_in_forecast"] is False
    assert [now.summary[k] for k in NEW_KEYS[1:]] == [0, 0, 0]
    assert now.summary["planner_calls"] > 0  # the episode planned (the comparison is not vacuous)
    assert _numbers(now.summary) == _numbers(before.summary)
    assert now.log.t == before.log.t and now.log.ego == before.log.ego and now.log.mode == before.log.mode
    for a, b in zip(now.log.nb, before.log.nb, strict=True):
        assert np.array_equal(a, b)


def test_the_option_on_plans_each_replan_against_the_controllers_reaction(monkeypatch: pytest.MonkeyPatch) -> None:
    """In a SUMO merge with the option on, every re-plan's problem carries, for the gap's follower,
    exactly the cubic ``follower_poly_for_plan`` returned for the plan before it, and the episode's
    ``ego_replans`` counts exactly those re-plans."""
    pytest.importorskip("libsumo")
    import iamp.prediction.leader.ego as ego_mod
    from iamp.simulation.controller import Controller
    from iamp.simulation.episode import EpisodeSpec, run_episode

    original, plan_orig = ego_mod.follower_poly_for_plan, Controller._plan
    events: list[tuple[str, Any]] = []

    def recording(*a: Any, **k: Any) -> tuple[float, ...]:
        out = original(*a, **k)
        events.append(("react", out))
        return out

    def plan(self: Controller, prob: Problem | EgoBoundary) -> Any:
        events.append(("plan", prob))
        return plan_orig(self, prob)

    monkeypatch.setattr(ego_mod, "follower_poly_for_plan", recording)
    monkeypatch.setattr(Controller, "_plan", plan)
    from iamp.simulation.controller import ControllerConfig

    # the loop without SPEC §17's verification, which plans within these 10 s (the verified loop
    # seeks a safe gap first)
    s = run_episode(EpisodeSpec(traffic="medium", seed=1, planner="pmp-active", mission="merge", duration_s=10.0,
                                ego_in_forecast=True), config=ControllerConfig(safe=False)).summary
    assert s["ego_in_forecast"] is True and s["ego_iterations"] > 0
    replans = 0
    for (kind, out), (kind2, prob) in zip(events, events[1:]):
        if kind == "react" and kind2 == "plan" and isinstance(prob, Problem):
            if any(tuple(v.x_poly) == tuple(out) for v in prob.vehicles):
                replans += 1
    assert replans == s["ego_replans"] > 0
