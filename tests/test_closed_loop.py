"""Closed loop with a task (SPEC §15): statistics, the monitor, the decision layer, MOBIL, the
campaign manifest, and SUMO episodes (one short one in the normal suite, the rest marked slow)."""

from __future__ import annotations

import json
import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from iamp.core.physical import PASSENGER_CAR
from iamp.core.problem import EgoBoundary, Problem, SurroundingVehicle
from iamp.simulation.campaign import EPISODE_KEYS, ManifestMismatch, check_manifest, manifest_of
from iamp.simulation.decision import (
    MAX_CHECKED,
    DecisionConfig,
    EgoNow,
    Gap,
    Neighbour,
    candidate_gaps,
    check_problem,
    end_state,
    judge,
    lane_change_problem,
    limit_violations_of,
)
from iamp.simulation.metrics import StepLog
from iamp.simulation.mobil import IDM, MOBIL, Car, mobil_accepts
from iamp.simulation.monitor import MIN_GAP_M, executed_accel, monitor
from iamp.simulation.planning import free_plan
from iamp.simulation.stats import mcnemar_exact, paired, paired_bootstrap, wilson


# -- Wilson ------------------------------------------------------------------------------------------
@settings(max_examples=200, deadline=None)
@given(n=st.integers(1, 400), data=st.data(), z=st.sampled_from([1.0, 1.645, 1.96, 2.576]))
def test_wilson_bounds_are_the_roots_of_the_score_equation(n, data, z):
    """Independent form: the Wilson interval is {p : (p̂ - p)² <= z² p(1 - p)/n}, whose ends are the
    roots of (1 + z²/n) p² - (2p̂ + z²/n) p + p̂² = 0 (solved here with numpy's polynomial roots)."""
    k = data.draw(st.integers(0, n))
    ph = k / n
    roots = np.sort(np.roots([1 + z * z / n, -(2 * ph + z * z / n), ph * ph]).real)
    lo, hi = wilson(k, n, z)
    assert lo == pytest.approx(max(roots[0], 0.0), abs=1e-9)
    assert hi == pytest.approx(min(roots[1], 1.0), abs=1e-9)
    # the score statistic is exactly z at an interior end
    for p in (lo, hi):
        if 1e-9 < p < 1 - 1e-9:
            assert abs(ph - p) / math.sqrt(p * (1 - p) / n) == pytest.approx(z, rel=1e-6)


def test_wilson_of_no_trials_is_the_unit_interval():
    assert wilson(0, 0) == (0.0, 1.0)


def test_wilson_default_is_the_95_percent_score_interval():
    """Without ``z`` the interval is the 95 % one: z = Φ⁻¹(0.975) (scipy), and lo <= p̂ <= hi."""
    from scipy.stats import norm

    z95 = float(norm.ppf(0.975))
    for k, n in [(0, 5), (3, 10), (17, 18), (50, 100)]:
        lo, hi = wilson(k, n)
        ph = k / n
        roots = np.sort(np.roots([1 + z95 * z95 / n, -(2 * ph + z95 * z95 / n), ph * ph]).real)
        assert (lo, hi) == pytest.approx((max(roots[0], 0.0), min(roots[1], 1.0)), abs=2e-5)
        assert lo <= ph <= hi


# -- McNemar -----------------------------------------------------------------------------------------
def _mcnemar_by_enumeration(b: int, c: int) -> float:
    """Exact two-sided test by its definition: the probability, under Binomial(b + c, 1/2), of every
    outcome at most as likely as the observed one (rational arithmetic, no closed form)."""
    n = b + c
    if n == 0:
        return 1.0
    pmf = [Fraction(math.comb(n, i), 2**n) for i in range(n + 1)]
    return float(min(Fraction(1), sum(p for p in pmf if p <= pmf[b])))


@settings(max_examples=200, deadline=None)
@given(b=st.integers(0, 60), c=st.integers(0, 60))
def test_mcnemar_equals_the_enumerated_exact_test_and_is_symmetric(b, c):
    p = mcnemar_exact(b, c)
    assert p == pytest.approx(_mcnemar_by_enumeration(b, c), rel=1e-12, abs=1e-15)
    assert p == mcnemar_exact(c, b)
    assert 0.0 < p <= 1.0


def test_mcnemar_known_values():
    assert mcnemar_exact(0, 0) == 1.0
    assert mcnemar_exact(0, 5) == pytest.approx(2 / 32)  # 2 * (1/2)^5
    assert mcnemar_exact(1, 9) == pytest.approx(2 * 11 / 1024)


# -- paired bootstrap --------------------------------------------------------------------------------
@settings(max_examples=40, deadline=None)
@given(d=st.lists(st.floats(-10, 10, allow_nan=False), min_size=1, max_size=40), shift=st.floats(-5, 5))
def test_bootstrap_mean_is_exact_interval_within_data_and_shift_equivariant(d, shift):
    mean, lo, hi = paired_bootstrap(d)
    assert mean == pytest.approx(float(np.mean(d)), abs=1e-9)
    assert min(d) - 1e-9 <= lo <= hi <= max(d) + 1e-9
    m2, lo2, hi2 = paired_bootstrap([x + shift for x in d])  # same resamples: every mean moves by shift
    assert (m2, lo2, hi2) == pytest.approx((mean + shift, lo + shift, hi + shift), abs=1e-8)


def test_bootstrap_interval_matches_the_normal_interval_for_many_pairs():
    """For n = 400 normal differences the percentile interval is close to mean ± 1.96 s/√n."""
    rng = np.random.default_rng(7)
    d = rng.normal(0.3, 2.0, 400)
    mean, lo, hi = paired_bootstrap(d.tolist(), n_boot=4000)
    half = 1.96 * d.std() / math.sqrt(d.size)
    assert lo == pytest.approx(mean - half, abs=0.15 * half)
    assert hi == pytest.approx(mean + half, abs=0.15 * half)


def test_paired_comparison_counts_discordant_pairs():
    ref = {("m", s): {"success": "True" if s <= 6 else "False", "contacts": "0"} for s in range(1, 11)}
    oth = {("m", s): {"success": "True" if s >= 3 else "False", "contacts": "1" if s == 1 else "0"}
           for s in range(1, 11)}
    out = paired(ref, oth)
    assert out["pairs"] == 10
    # ref only: seeds 1, 2 (b = 2); other only: 7..10 (c = 4)
    assert (out["success"]["b"], out["success"]["c"]) == (2, 4)
    assert out["success"]["p"] == pytest.approx(_mcnemar_by_enumeration(2, 4))
    assert out["success"]["diff"] == pytest.approx(0.2)
    assert (out["contact"]["b"], out["contact"]["c"]) == (0, 1)


def _row(seed, success, decel, wall=1.0, simulated=60.0):
    return {"mission": "merge", "planner": "p", "traffic": "medium", "seed": seed, "success": str(success),
            "follower_max_decel": decel, "wall_total_s": wall, "simulated_s": simulated, "contacts": "0"}


def test_hard_brake_is_a_follower_deceleration_beyond_the_drivers_decel():
    """SPEC §15: the new follower braking harder than 4.5 m/s² (SUMO's default ``decel``) counts."""
    from iamp.simulation.stats import cell_summary

    rows = [_row(1, True, 4.4), _row(2, True, 4.6), _row(3, False, 9.0), _row(4, True, "")]
    out = cell_summary(rows)
    assert out["hard_brake_episodes"] == 2
    assert out["follower_max_decel_max"] == 9.0


def test_wall_time_per_simulated_minute_is_the_ratio_of_sums():
    from iamp.simulation.stats import cell_summary

    rows = [_row(1, True, 1.0, wall=3.0, simulated=60.0), _row(2, True, 1.0, wall=1.0, simulated=20.0)]
    assert cell_summary(rows)["wall_per_simulated_minute_s"] == pytest.approx(60.0 * 4.0 / 80.0)


def test_cell_counts_are_sums_and_a_missing_count_adds_nothing():
    from iamp.simulation.stats import cell_summary

    rows = [{**_row(1, True, 1.0), "fallbacks": "3", "plans": "10"}, {**_row(2, True, 1.0), "fallbacks": ""},
            {**_row(3, False, 1.0), "fallbacks": "None", "plans": "5"}]
    out = cell_summary(rows)
    assert (out["fallbacks"], out["plans"], out["aborts"]) == (3, 15, 0)


def test_campaign_report_orders_known_missions_and_densities_before_unknown_ones():
    from iamp.simulation.stats import campaign_report

    rows = []
    for m in ("zzz-custom", "onramp", "merge"):
        for t in ("custom-density", "dense", "medium"):
            for p in ("b", "a"):
                rows.append({**_row(1, True, 1.0), "mission": m, "traffic": t, "planner": p})
    out = campaign_report(rows, planners=["a", "b"], reference="a")
    cells = [(c["mission"], c["traffic"], c["planner"]) for c in out["cells"]]
    assert cells[:2] == [("merge", "medium", "a"), ("merge", "medium", "b")]
    assert [c[0] for c in cells[::6]] == ["merge", "onramp", "zzz-custom"]
    assert [c[1] for c in cells[:6:2]] == ["medium", "dense", "custom-density"]
    assert {c["planner"] for c in out["paired"]} == {"b"} and {c["reference"] for c in out["paired"]} == {"a"}
    scopes = [(c["mission"], c["traffic"]) for c in out["paired"]]
    assert scopes[:4] == [("merge", "all"), ("merge", "medium"), ("merge", "dense"), ("merge", "custom-density")]
    assert scopes[-1] == ("zzz-custom", "custom-density")


# -- the monitor -------------------------------------------------------------------------------------
def _one_step_log(ego, nb, dt=0.1, steps=3):
    """A log of ``steps`` identical steps (the ego and one neighbour standing)."""
    log = StepLog()
    for k in range(steps):
        log.t.append(k * dt)
        log.ego.append((ego[0], 0.0, ego[1], 0.0, 0.0, 0.0))
        log.mode.append("active")
        log.plan_time.append(math.nan)
        log.ids.append(("a",))
        log.nb.append(np.array([[nb[0], nb[1], 0.0, 0.0, 1, nb[2], nb[3]]]))
    return log


def _overlap_area(c1, s1, c2, s2):
    """Area of the intersection of two axis-aligned rectangles (centres c, sizes s = (length, width))."""
    area = 1.0
    for ax in (0, 1):
        lo = max(c1[ax] - s1[ax] / 2, c2[ax] - s2[ax] / 2)
        hi = min(c1[ax] + s1[ax] / 2, c2[ax] + s2[ax] / 2)
        area *= max(hi - lo, 0.0)
    return area


@settings(max_examples=200, deadline=None)
@given(dx=st.floats(-15, 15), dy=st.floats(-5, 5), L=st.floats(3.5, 16.0), W=st.floats(1.5, 2.6),
       Le=st.floats(4.0, 5.0), We=st.floats(1.7, 2.0))
def test_monitor_contact_is_a_body_overlap_of_positive_area(dx, dy, L, W, Le, We):
    area = _overlap_area((0.0, 0.0), (Le, We), (dx, dy), (L, W))
    # keep away from touching edges, where a positive area is a rounding question
    assume(area > 1e-6 or (abs(dx) - (Le + L) / 2 > 1e-6 or abs(dy) - (We + W) / 2 > 1e-6))
    m = monitor(_one_step_log((0.0, 0.0), (dx, dy, L, W)), 0.1, (Le, We), lambda y: 0, 1, 30.0, None, [])
    assert m["contacts"] == (1 if area > 0 else 0)
    gap = abs(dx) - (Le + L) / 2
    beside = abs(dy) < (We + W) / 2
    assert m["mingap_violations"] == (1 if (area == 0 and beside and gap < MIN_GAP_M) else 0)


def test_monitor_counts_sumo_contacts_once_per_vehicle_and_apart_from_mingap():
    log = _one_step_log((0.0, 0.0), (30.0, 0.0, 4.0, 1.8))
    m = monitor(log, 0.1, (4.8, 1.8), lambda y: 0, 1, 30.0, None, [(0.1, "b", "collision"), (0.2, "b", "x")])
    # SPEC §17: contacts are overlaps of the bodies; SUMO's report without one is listed apart
    assert m["contacts"] == 0 and m["sumo_contacts"] == 1 and m["overlap_contacts"] == 0
    assert m["sumo_only_contacts"] == 1 and m["contact_disagreements"] == 1
    assert m["mingap_violations"] == 0 and m["success"] is False


def _lane_change_log(dt=0.1, n=60, a=0.8, follower_acc=(-1.0, -5.2, -2.0)):
    """The ego accelerates at ``a`` from 20 m/s and moves from y = 0 (lane 0) to y = 3.5 (lane 1) at
    step 30; neighbour ``f`` follows 25 m behind in lane 1 and brakes as ``follower_acc`` says
    (before, during steps 30-34, after); ``g`` is 60 m behind in lane 1."""
    log = StepLog()
    for k in range(n):
        t = k * dt
        x, v = 20.0 * t + 0.5 * a * t * t, 20.0 + a * t
        y = 0.0 if k < 30 else 3.5
        log.t.append(t)
        log.ego.append((x, v, y, 0.0, a, 0.0))
        log.mode.append("active")
        log.plan_time.append(math.nan)
        log.ids.append(("f", "g"))
        fa = follower_acc[0] if k < 30 else follower_acc[1] if k < 35 else follower_acc[2]
        log.nb.append(np.array([[x - 25.0, 3.5, v, fa, 1, 4.5, 1.8], [x - 60.0, 3.5, v, -7.0, 1, 4.5, 1.8]]))
    return log


def test_monitor_mission_follower_and_executed_peaks():
    dt = 0.1
    log = _lane_change_log(dt)
    lane_of = lambda y: 0 if y < 1.75 else 1  # noqa: E731
    m = monitor(log, dt, (4.8, 1.8), lane_of, 1, 10.0, None, [], lookback_s=1.0)
    assert m["time_to_merge_s"] == pytest.approx(3.0) and m["success"] is True
    # the nearest vehicle behind in the target lane at the merge step, its hardest braking since 2 s
    assert m["new_follower"] == "f" and m["follower_max_decel"] == pytest.approx(5.2)
    # a quadratic x(t): second differences are exactly a
    ax, _ = executed_accel(np.asarray(log.ego), dt)
    np.testing.assert_allclose(ax, 0.8, atol=1e-9)
    # the lateral step of 3.5 m in one period executes 350 m/s²: two steps beyond every limit
    assert m["ego_ay_peak"] == pytest.approx(3.5 / dt**2)
    assert m["limit_violations"] == 2
    # a deadline before the merge: no success
    late = monitor(log, dt, (4.8, 1.8), lane_of, 1, 2.5, None, [])
    assert late["success"] is False and late["time_to_merge_s"] == pytest.approx(3.0)
    # a lane end the ego's front passes before the merge: no success
    x_merge = log.ego[30][0]
    assert monitor(log, dt, (4.8, 1.8), lane_of, 1, 10.0, x_merge, [])["success"] is False
    assert monitor(log, dt, (4.8, 1.8), lane_of, 1, 10.0, x_merge + 2.5, [])["success"] is True


@settings(max_examples=60, deadline=None)
@given(gap0=st.floats(5.0, 60.0), closing=st.floats(0.5, 8.0))
def test_monitor_ttc_is_gap_over_closing_speed(gap0, closing):
    """A leader in the ego's lane closing at constant speed: TTC_k = gap_k / closing, minimum at the
    last step; steps with TTC < 1.5 s counted."""
    dt, n, Le, L = 0.1, 20, 4.8, 4.0
    log = StepLog()
    for k in range(n):
        t = k * dt
        xe = 20.0 * t
        log.t.append(t)
        log.ego.append((xe, 20.0, 0.0, 0.0, 0.0, 0.0))
        log.mode.append("active")
        log.plan_time.append(math.nan)
        log.ids.append(("a",))
        log.nb.append(np.array([[xe + (Le + L) / 2 + gap0 - closing * t, 0.0, 20.0 - closing, 0.0, 0, L, 1.8]]))
    gaps = gap0 - closing * dt * np.arange(n)
    assume(gaps[-1] > 0.05 and np.all(np.abs(gaps / closing - 1.5) > 1e-6))
    m = monitor(log, dt, (Le, 1.8), lambda y: 0, 1, 30.0, None, [])
    assert m["min_ttc_s"] == pytest.approx(gaps[-1] / closing, rel=1e-9)
    assert m["ttc_below_1_5_s"] == pytest.approx(dt * int(np.sum(gaps / closing < 1.5)))


def test_limit_violations_name_the_broken_bounds():
    lim = PASSENGER_CAR
    assert lim.ax is not None and lim.ay is not None
    ok = limit_violations_of(np.array([0.0]), np.array([0.0]), np.array([20.0]), lim)
    assert ok == []
    bad = limit_violations_of(np.array([lim.ax[0] - 0.1]), np.array([0.0]), np.array([20.0]), lim)
    assert bad == ["ax"]
    bad = limit_violations_of(np.array([0.0]), np.array([lim.ay[1] + 0.1]), np.array([20.0]), lim)
    assert "ay" in bad


# -- the decision layer ------------------------------------------------------------------------------
def _nb(name, x, v, lane, y):
    return Neighbour(name, (x, v, 0.0, 0.0), y, 4.5, 1.8, lane)


def test_candidate_gaps_start_with_the_one_the_ego_drifts_into():
    cfg = DecisionConfig()
    ego = EgoNow(0.0, 25.0, 0.0, 0.0)
    # constant speed: the ego is at 125 m after 5 s; target-lane vehicles at constant 25 m/s
    target = [_nb("a", -40.0, 25.0, 1, 3.5), _nb("b", 10.0, 25.0, 1, 3.5), _nb("c", 50.0, 25.0, 1, 3.5)]
    gaps = candidate_gaps(ego, target, cfg)
    names = [(g.follower.name if g.follower else None, g.leader.name if g.leader else None) for g in gaps]
    assert names[0] == ("a", "b")  # ego at 125, a at 85, b at 135: inside (a, b) -> score 0
    assert len(gaps) == cfg.max_gaps


def test_lane_change_problem_corners_follow_the_paper_and_cover_the_target_leader():
    cfg = DecisionConfig()
    ego = EgoNow(0.0, 25.0, 0.0, 0.0)
    f, l_, c = _nb("f", -20.0, 25.0, 1, 3.5), _nb("l", 30.0, 25.0, 1, 3.5), _nb("c", 40.0, 22.0, 0, 0.0)
    prob = lane_change_problem(ego, 3.5, Gap(f, l_), c, cfg, 5.0)
    assert isinstance(prob, Problem)
    corners = {v.name: v.corner for v in prob.vehicles}
    assert corners == {"f": "front-lower", "l": "rear-lower", "c": "rear-upper"}
    assert prob.ego.yf == 3.5 and prob.ego.vyf == 0.0 and prob.ego.tf == 5.0
    # to the right (y decreasing) the corners mirror
    f, l_, c = _nb("f", -20.0, 25.0, 0, 0.0), _nb("l", 30.0, 25.0, 0, 0.0), _nb("c", 40.0, 22.0, 1, 3.5)
    prob = lane_change_problem(EgoNow(0.0, 25.0, 3.5, 0.0), 0.0, Gap(f, l_), c, cfg, 5.0)
    assert isinstance(prob, Problem)
    assert {v.name: v.corner for v in prob.vehicles} == {"f": "front-upper", "l": "rear-upper", "c": "rear-lower"}
    # a corner the ego has already passed laterally is met and left out
    prob = lane_change_problem(EgoNow(0.0, 25.0, 3.2, 0.0), 3.5, Gap(_nb("f", -20.0, 25.0, 1, 3.5), None), None,
                               cfg, 5.0)
    assert isinstance(prob, EgoBoundary)


def _gap_bounds(ego, gap, T):
    """Where the ego's centre may end in ``gap`` after ``T`` (bodies touching, no headway)."""
    lo = -np.inf if gap.follower is None else gap.follower.x(T) + (gap.follower.length + ego.length) / 2
    hi = np.inf if gap.leader is None else gap.leader.x(T) - (gap.leader.length + ego.length) / 2
    return lo, hi


@settings(max_examples=60, deadline=None)
@given(xf=st.floats(-60, 20), xl=st.floats(25, 80), vf=st.floats(15, 35), vl=st.floats(15, 35),
       Lf=st.floats(3.0, 18.0), Ll=st.floats(3.0, 18.0), v0=st.floats(15, 35))
def test_end_state_keeps_the_headway_to_both_bodies_or_takes_the_middle(xf, xl, vf, vl, Lf, Ll, v0):
    """Independent form: with lo/hi the centre positions where the bodies touch, the end point is
    the constant-acceleration point clipped into [lo + h, hi - h] (h = headway x end speed) when the
    gap holds both headways, else the middle of [lo, hi]."""
    cfg = DecisionConfig()
    ego = EgoNow(0.0, v0, 0.0, 0.0)
    f = Neighbour("f", (xf, vf, 0.0, 0.0), 3.5, Lf, 2.0, 1)
    l_ = Neighbour("l", (xl, vl, 0.0, 0.0), 3.5, Ll, 2.0, 1)
    T = cfg.horizon_s
    x, v = end_state(ego, Gap(f, l_), cfg, T)
    lo, hi = _gap_bounds(ego, Gap(f, l_), T)
    h = cfg.headway_s * v
    if hi - lo >= 2 * h:
        assert lo + h - 1e-9 <= x <= hi - h + 1e-9
        assert x == pytest.approx(min(max((v0 + v) * T / 2, lo + h), hi - h), abs=1e-9)
    else:
        assert x == pytest.approx((lo + hi) / 2, abs=1e-9)


def test_candidate_gaps_score_the_end_point_against_the_bodies():
    """A gap scores 0 when the ego's constant-speed end point lies between the touching positions
    of its vehicles' bodies; long bodies shrink a gap until the next one is nearer."""
    cfg = DecisionConfig(max_gaps=3)
    ego = EgoNow(0.0, 20.0, 0.0, 0.0)  # end point 100 m
    # a (short) ends at 100 - 10 = 90 and b at 100 + 8 = 108: with 4.8 m bodies (a, b) holds 100
    short = [Neighbour("a", (-10.0, 20.0), 3.5, 4.8, 1.8, 1), Neighbour("b", (8.0, 20.0), 3.5, 4.8, 1.8, 1)]
    g = candidate_gaps(ego, short, cfg)[0]
    assert (g.follower.name, g.leader.name) == ("a", "b")
    # the bodies set the other scores: (None, a) ends at a's rear 90 - La/2 - 2.4, (b, None) starts at
    # b's front 108 + Lb/2 + 2.4; a 14 m truck as b puts (None, a) second (14.8 < 17.4), as a it puts
    # (b, None) second (13.4 < 19.4)
    def order(La, Lb):
        cars = [Neighbour("a", (-10.0, 20.0), 3.5, La, 1.8, 1), Neighbour("b", (8.0, 20.0), 3.5, Lb, 1.8, 1)]
        return [(g.follower.name if g.follower else None, g.leader.name if g.leader else None)
                for g in candidate_gaps(ego, cars, cfg)]

    assert order(4.8, 14.0) == [("a", "b"), (None, "a"), ("b", None)]
    assert order(14.0, 4.8) == [("a", "b"), ("b", None), (None, "a")]
    # an 11 m b: (b, None) at 8 + 5.5 + 2.4 = 15.9 against (None, a) at 14.8; the ego's half length is
    # in both scores, dropping it from one side would swap them
    assert order(4.8, 11.0) == [("a", "b"), (None, "a"), ("b", None)]
    # vehicles beyond relevant_m are not gap bounds
    far = [*short, Neighbour("z", (cfg.relevant_m + 1.0, 20.0), 3.5, 4.8, 1.8, 1)]
    assert all(n is None or n.name != "z" for g in candidate_gaps(ego, far, cfg) for n in (g.follower, g.leader))


@pytest.mark.parametrize("x_leader, expected", [(7.0, 7.0 - 2.25 - 0.5), (2.6, 0.0), (30.0, None),
                                                (7.25, None)])  # a bumper gap of exactly safety_x keeps it
def test_a_close_current_leader_keeps_a_smaller_safety_distance_to_what_is_left(x_leader, expected):
    """The current-lane leader closer than ``safety_x`` (bumper gap ``x_l - L_l/2 - x_e``) gets the
    safety distance ``max(gap - 0.5, 0)``, in the plan's problem and in the §9 check, so that the
    start is not already inside its region; farther it keeps ``safety_x``."""
    cfg = DecisionConfig()
    ego = EgoNow(0.0, 25.0, 0.0, 0.0)
    c = Neighbour("c", (x_leader, 25.0, 0.0, 0.0), 0.0, 4.5, 1.8, 0)
    prob = lane_change_problem(ego, 3.5, Gap(None, None), c, cfg, 5.0)
    assert isinstance(prob, Problem)
    want = cfg.safety_x if expected is None else expected
    assert prob.vehicles[0].safety_x == pytest.approx(want)
    chk = check_problem(prob.ego, ego, [c], [0, 1], cfg)
    assert chk is not None and chk.vehicles[0].safety_x == pytest.approx(want)


def test_the_check_takes_the_neighbours_within_relevant_m_now():
    """The §9 check's neighbours are those within ``relevant_m`` of the ego *now* (t = 0), in the
    given lanes."""
    cfg = DecisionConfig()
    ego = EgoNow(0.0, 25.0, 0.0, 0.0)
    inside = Neighbour("in", (cfg.relevant_m - 0.5, 25.0, 0.0, 0.0), 3.5, 4.5, 1.8, 1)  # beyond it after 0.02 s
    outside = Neighbour("out", (-(cfg.relevant_m + 0.5), 30.0, 0.0, 0.0), 3.5, 4.5, 1.8, 1)
    other_lane = Neighbour("x", (10.0, 25.0, 0.0, 0.0), 7.0, 4.5, 1.8, 2)
    chk = check_problem(EgoBoundary(tf=5.0, x0=0.0, y0=0.0, vx0=25.0, vy0=0.0, xf=125.0, yf=3.5, vxf=25.0, vyf=0.0),
                        ego, [inside, outside, other_lane], [0, 1], cfg)
    assert chk is not None and [v.name for v in chk.vehicles] == ["in"]


def test_limit_samples_break_a_bound_only_beyond_its_tolerance():
    lim = PASSENGER_CAR
    assert lim.ax is not None
    z = np.zeros(3)
    for k, name in ((0, "ax"), (1, "ay")):
        rng = getattr(lim, name)
        for edge, sign in ((rng[0], -1.0), (rng[1], 1.0)):
            within, beyond = z.copy(), z.copy()
            within[1], beyond[1] = edge + sign * 0.5e-6, edge + sign * 2e-6
            args_in = [within, z, np.full(3, 20.0)] if k == 0 else [z, within, np.full(3, 20.0)]
            args_out = [beyond, z, np.full(3, 20.0)] if k == 0 else [z, beyond, np.full(3, 20.0)]
            assert name not in limit_violations_of(*args_in, lim)
            assert name in limit_violations_of(*args_out, lim)


def test_check_times_cover_the_horizon_every_dt_and_both_ends():
    from iamp.simulation.decision import check_times

    for tf, dt in [(5.0, 0.01), (3.3, 0.1), (0.004, 0.01), (7.0, 0.3)]:
        t = check_times(tf, dt)
        assert t[0] == 0.0 and t[-1] == tf
        assert np.max(np.diff(t)) <= dt + 1e-12
        assert len(t) == max(int(np.ceil(tf / dt)), 1) + 1 and len(t) >= 2


def test_end_speed_is_reachable_within_the_limits_and_the_check_holds_at_most_eight():
    cfg = DecisionConfig()
    ax = cfg.limits.ax
    assert ax is not None
    slow = EgoNow(0.0, 16.7, 0.0, 0.0)  # an on-ramp entry; the gap drives at 33 m/s
    gap = Gap(_nb("f", -30.0, 33.0, 1, 3.5), _nb("l", 30.0, 33.0, 1, 3.5))
    _, vxf = end_state(slow, gap, cfg, 5.0)
    assert vxf == pytest.approx(16.7 + 0.8 * ax[1] * 5.0)
    crowd = [_nb(f"v{k}", -50.0 + 10.0 * k, 25.0, k % 2, 3.5 * (k % 2)) for k in range(11)]
    boundary = EgoBoundary(tf=5.0, x0=0.0, y0=0.0, vx0=25.0, vy0=0.0, xf=125.0, yf=3.5, vxf=25.0, vyf=0.0)
    check = check_problem(boundary, EgoNow(0.0, 25.0, 0.0, 0.0), crowd, (0, 1), cfg)
    assert check is not None and check.m == MAX_CHECKED
    assert max(abs(v.position(np.array([0.0]))[0]) for v in check.vehicles) <= 40.0  # the nearest eight


def test_judge_accepts_a_bounded_intrusion_free_plan_and_rejects_beyond_the_limits():
    cfg = DecisionConfig()
    gentle = EgoBoundary(tf=5.0, x0=0.0, y0=0.0, vx0=25.0, vy0=0.0, xf=125.0, yf=3.5, vxf=25.0, vyf=0.0)
    assert judge(free_plan(gentle, "free"), None, cfg) == "accepted"
    # 200 m in 5 s from 25 m/s and back to 25 m/s: |a_x| peaks at 6 e / tf² = 18 m/s²
    harsh = EgoBoundary(tf=5.0, x0=0.0, y0=0.0, vx0=25.0, vy0=0.0, xf=200.0, yf=3.5, vxf=25.0, vyf=0.0)
    assert judge(free_plan(harsh, "free"), None, cfg).startswith("limits:ax")
    # a vehicle standing where the gentle plan passes: intrusion
    # a target-lane vehicle 5 m ahead of the gentle plan's end point at the same speed: the plan ends
    # inside its safety region (|dx| = 5 < 2.25 + 5, dy = 0): intrusion; 40 m ahead: none
    for ahead, verdict in ((5.0, "intrusion:x"), (40.0, "accepted")):
        blocker = Problem(gentle, (SurroundingVehicle((ahead, 25.0, 0.0, 0.0), "rear-lower", 3.5, 4.5, 1.8, 5.0,
                                                      0.5, name="x"),))
        assert judge(free_plan(gentle, "free"), blocker, cfg) == verdict


# -- IDM + MOBIL -------------------------------------------------------------------------------------
@settings(max_examples=60, deadline=None)
@given(v=st.floats(5.0, 35.0), dv=st.floats(-5.0, 5.0))
def test_idm_equilibrium_and_free_road(v, dv):
    idm = IDM(v0=33.33)
    assert idm.accel(idm.v0) == pytest.approx(0.0, abs=1e-12)
    # at the desired gap s* with an equal-speed leader: a = a_max[1 - (v/v0)^δ - 1]
    s_star = idm.s0 + v * idm.T
    assert idm.accel(v, s_star, v) == pytest.approx(-idm.a_max * (v / idm.v0) ** idm.delta, rel=1e-9)
    # a closer, slower leader never asks for more acceleration
    assert idm.accel(v, 20.0, v + dv) >= idm.accel(v, 10.0, v + dv - 1.0) - 1e-12


def test_mobil_safety_criterion_and_mandatory_change():
    idm, mob = IDM(v0=33.33), MOBIL()
    ego = Car(0.0, 25.0, 4.8)
    close_fast = Car(-8.0, 33.0, 4.5)  # 3.35 m behind, 8 m/s faster: it would brake far beyond b_safe
    ok, why = mobil_accepts(idm, mob, ego, None, None, None, close_fast, mandatory=True)
    assert not ok and why == "unsafe-follower"
    assert idm.accel(33.0, -8.0 + 0.0 - (-8.0) + 8.0 - (4.8 + 4.5) / 2, 25.0) < -mob.b_safe
    far = Car(-80.0, 25.0, 4.5)
    assert mobil_accepts(idm, mob, ego, None, None, None, far, mandatory=True) == (True, "accepted")
    assert mobil_accepts(idm, mob, ego, None, None, None, Car(1.0, 25.0, 4.5), mandatory=True)[1] == "overlap"


# -- the manifest ------------------------------------------------------------------------------------
EPISODE = {"duration_s": 60.0, "period_s": 0.1, "deadline_s": None, "warmup_s": 5.0, "settle_s": 8.0,
           "cooperation": "default", "sublane": False}


def _start(tmp_path, **changes):
    wanted = manifest_of(["merge"], ["pmp", "sumo"], ["medium"], 3, {**EPISODE, **changes})
    return check_manifest(tmp_path, wanted, force=False)


def test_appending_to_an_older_campaign_rewrites_its_header_and_keeps_every_value(tmp_path):
    """A resumed campaign whose episodes.csv has fewer (or other) columns: the file is rewritten
    under the new columns, old values stay under their names, no row is longer than the header."""
    import csv as _csv

    from iamp.simulation.campaign import _append

    path = tmp_path / "episodes.csv"
    path.write_text("planner,seed,legacy\npmp,1,x\nqp,2,y\n", encoding="utf-8")
    _append(path, ("planner", "seed", "ego_in_forecast"), {"planner": "free", "seed": 3, "ego_in_forecast": False})
    lines = path.read_text(encoding="utf-8").splitlines()
    assert lines[0] == "planner,seed,ego_in_forecast,legacy"
    rows = list(_csv.reader(lines))
    assert all(len(r) == len(rows[0]) for r in rows)
    recs = list(_csv.DictReader(lines))
    assert [(r["planner"], r["seed"], r["legacy"], r["ego_in_forecast"]) for r in recs] == [
        ("pmp", "1", "x", ""), ("qp", "2", "y", ""), ("free", "3", "", "False")]
    # same columns now: one more line, the earlier bytes untouched
    before = path.read_text(encoding="utf-8")
    _append(path, ("planner", "seed", "ego_in_forecast", "legacy"), {"planner": "sumo", "seed": 4, "legacy": None})
    after = path.read_text(encoding="utf-8")
    assert after.startswith(before) and after[len(before):] == "sumo,4,,\n"


def test_manifest_refuses_a_changed_episode_parameter_and_names_it(tmp_path):
    (tmp_path / "manifest.json").write_text(json.dumps(_start(tmp_path)))
    (tmp_path / "episodes.csv").write_text("mission,planner,traffic,seed\nmerge,pmp,medium,1\n")
    for key, value in (("duration_s", 20.0), ("cooperation", "low"), ("sublane", True), ("period_s", 0.2)):
        with pytest.raises(ManifestMismatch, match=f"{key} \\(was .*, now {value!r}\\)"):
            _start(tmp_path, **{key: value})
    assert (tmp_path / "episodes.csv").is_file()  # nothing discarded without force
    # the grid may grow: more seeds, another planner
    grown = check_manifest(tmp_path, manifest_of(["merge"], ["free"], ["medium"], 10, EPISODE), force=False)
    assert grown["planners"] == ["pmp", "sumo", "free"] and grown["seeds"] == 10
    # --force discards the old rows and takes the new parameters
    forced = check_manifest(tmp_path, manifest_of(["merge"], ["pmp"], ["medium"], 3, {**EPISODE, "duration_s": 20.0}),
                            force=True)
    assert forced["duration_s"] == 20.0 and not (tmp_path / "episodes.csv").exists()
    assert set(EPISODE) <= set(EPISODE_KEYS)


def test_rows_without_a_manifest_are_refused(tmp_path):
    (tmp_path / "episodes.csv").write_text("planner,traffic,seed\npmp,medium,1\n")
    with pytest.raises(ManifestMismatch, match="without a manifest"):
        _start(tmp_path)


def test_campaign_cli_refuses_a_changed_duration_with_exit_2(tmp_path, capsys):
    pytest.importorskip("distributed")
    from iamp.cli.main import main
    from iamp.core.outputs import write_marker

    write_marker(tmp_path, "campaign")  # a folder an earlier `iamp campaign` wrote
    (tmp_path / "manifest.json").write_text(json.dumps(manifest_of(["merge"], ["sumo"], ["light"], 1, EPISODE)))
    (tmp_path / "episodes.csv").write_text("mission,planner,traffic,seed\nmerge,sumo,light,1\n")
    code = main(["campaign", "--missions", "merge", "--planners", "sumo", "--traffic", "light", "--seeds", "1",
                 "--duration", "20", "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2 and "duration_s" in err and "Traceback" not in err and len(err.strip().splitlines()) == 1


# -- SUMO episodes -----------------------------------------------------------------------------------
def _episode(planner, mission="merge", traffic="light", seed=1, duration=20.0):
    pytest.importorskip("libsumo")
    from iamp.simulation.episode import EpisodeSpec, run_episode

    return run_episode(EpisodeSpec(traffic=traffic, seed=seed, planner=planner, mission=mission,
                                   duration_s=duration))


def _numbers(s):
    return {k: v for k, v in s.items() if k not in ("plan_time_s", "wall_s", "max_rss_mb")}


def test_a_short_merge_is_deterministic_and_the_monitor_agrees_with_the_log():
    a, b = _episode("free", duration=12.0), _episode("free", duration=12.0)
    assert _numbers(a.summary) == _numbers(b.summary)
    s = a.summary
    assert s["mission"] == "merge" and s["distance_to_end_m"] == pytest.approx(400.0, abs=30.0)
    E = np.asarray(a.log.ego)
    if s["time_to_merge_s"] is not None:
        k = int(round(s["time_to_merge_s"] / 0.1))
        from iamp.simulation.missions import mission_of

        hw = mission_of("merge").highway()
        assert hw.lane_of(E[k, 2]) == 1 and all(hw.lane_of(y) == 0 for y in E[:k, 2])
    # the executed peak is the largest second difference of the executed positions
    ax, ay = np.diff(E[:, 0], 2) / 0.01, np.diff(E[:, 2], 2) / 0.01
    assert s["ego_peak_accel"] == pytest.approx(float(np.hypot(ax, ay).max()))


@pytest.mark.slow
@pytest.mark.parametrize("planner", ["pmp", "qp", "pmp-active", "qp-avoid", "free", "mobil", "sumo"])
@pytest.mark.parametrize("mission", ["merge", "onramp", "slow-leader", "discretionary"])
def test_every_planner_on_every_mission_reports_finite_section_15_numbers(planner, mission):
    s = _episode(planner, mission=mission, traffic="medium", seed=2, duration=40.0).summary
    for key in ("success", "time_to_merge_s", "stopped_at_end", "contacts", "mingap_violations", "min_ttc_s",
                "ttc_below_1_5_s", "follower_max_decel", "ego_peak_accel", "limit_violations", "constrained_plans",
                "infeasible_plans", "fallbacks", "plan_time_s"):
        assert key in s
    assert math.isfinite(s["ego_peak_accel"])
    if planner in ("mobil", "sumo"):
        assert s["planner_calls"] == 0 and s["constrained_plans"] == 0


def test_campaign_rate_figure_accepts_wilson_ends_rounded_past_the_rate(tmp_path):
    """A Wilson interval of a 100 % (or 0 %) rate ends at 1 (0) only up to rounding; the rates
    figure's error bars must not become negative (a 6-seed campaign crashed on it)."""
    from iamp.simulation.figures import campaign_figures

    cell = {"mission": "merge", "planner": "pmp", "traffic": "medium"}
    for key in ("success", "contact", "hard_brake", "limit_violation", "stopped_at_end", "mingap", "ttc_alarm"):
        cell[f"{key}_rate"] = 1.0
        cell[f"{key}_ci"] = [0.6, 1.0 - 1e-16]
    paths = campaign_figures([cell], [], tmp_path)
    assert paths and all(p.exists() and p.stat().st_size > 0 for p in paths)


def test_a_follower_braking_at_its_decel_up_to_rounding_is_not_a_hard_brake():
    """SUMO reports a follower braking at exactly its ``decel`` as 4.5 ± 3e-14 m/s²: not harder
    (the campaign's summary and the README's and docs' tables share :func:`is_hard_brake`)."""
    from iamp.simulation.stats import cell_summary, is_hard_brake

    assert not is_hard_brake(4.500000000000028) and not is_hard_brake(None) and is_hard_brake(4.51)
    rows = [_row(1, True, 4.500000000000028), _row(2, True, 4.5 + 2e-6)]
    assert cell_summary(rows)["hard_brake_episodes"] == 1
