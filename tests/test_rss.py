"""RSS (simulation/rss.py): the published formulas against hand-computed cases and, when the
reference implementation ``ad-rss`` is installed, against it on generated situations; the
dangerous threshold time, proper response and blame on constructed pairs."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from iamp.core.errors import ScenarioError
from iamp.simulation.rss import (
    DEFAULT,
    Motion,
    RssParameters,
    body_extents,
    judge_pair,
    lateral_reach,
    safe_lateral_distance,
    safe_longitudinal_distance,
    safe_longitudinal_float,
    within_rss_reach,
)

# -- hand-computed cases (the paper's formulas, worked by hand) -------------------------------------
#: ad-rss's own defaults (response time 1 s); iamp's DEFAULT differs only in the response time (0.5 s).
AD_RSS = RssParameters(response_time_s=1.0)


def judge_ad(ego: Motion, other: Motion, dt: float) -> object:
    """The constructed pairs below were timed for ad-rss's 1 s response time."""
    return judge_pair(ego, other, dt, AD_RSS)


def test_longitudinal_distance_by_hand():
    # v_r = 30, v_f = 20, rho = 1, a = 3.5, b_min = 4, b_max = 8:
    # 30 + 1.75 + 33.5^2/8 - 400/16 = 31.75 + 140.28125 - 25 = 147.03125
    assert float(safe_longitudinal_distance(30.0, 20.0, AD_RSS)) == pytest.approx(147.03125, abs=1e-12)
    # both standing: only the rear car's acceleration during rho: 1.75 + 3.5^2/8 = 3.28125
    assert float(safe_longitudinal_distance(0.0, 0.0, AD_RSS)) == pytest.approx(3.28125, abs=1e-12)
    # a fast front car: the positive part is 0
    assert float(safe_longitudinal_distance(10.0, 30.0)) == 0.0
    # iamp's DEFAULT (rho = 0.5): 15 + 0.4375 + 31.75^2/8 - 25 = 116.4453125
    assert float(safe_longitudinal_distance(30.0, 20.0)) == pytest.approx(116.4453125, abs=1e-12)


def test_lateral_distance_by_hand():
    # u1 = 1 toward, u2 = 0.5 toward, alpha 0.2, beta 0.8, rho 1, mu 0.1:
    # o(1) = 1 + 0.1 + 1.2^2/1.6 = 2.0 ; o(0.5) = 0.5 + 0.1 + 0.7^2/1.6 = 0.90625
    assert float(lateral_reach(1.0, AD_RSS)) == pytest.approx(2.0)
    assert float(lateral_reach(0.5, AD_RSS)) == pytest.approx(0.90625)
    assert float(safe_lateral_distance(1.0, 0.5, AD_RSS)) == pytest.approx(0.1 + 2.90625)
    # both moving apart fast: only the margin mu remains (touching is never laterally safe)
    assert float(safe_lateral_distance(-2.0, -1.0, AD_RSS)) == pytest.approx(0.1)
    # moving away slower than alpha rho brings back: the reach is u rho + 1/2 alpha rho^2, nothing after it
    assert float(lateral_reach(-0.5, AD_RSS)) == pytest.approx(-0.5 + 0.1)
    # standing: each may drift 1/2 alpha rho^2 + (alpha rho)^2 / (2 beta) = 0.1 + 0.025
    assert float(safe_lateral_distance(0.0, 0.0, AD_RSS)) == pytest.approx(0.1 + 0.25)


def test_parameters_are_validated_and_state_their_source():
    with pytest.raises(ScenarioError, match="brake_max"):
        RssParameters(brake_min=5.0, brake_max=4.0)
    with pytest.raises(ScenarioError, match="response_time_s"):
        RssParameters(response_time_s=0.0)
    with pytest.raises(ScenarioError, match="lat_margin_m"):
        RssParameters(lat_margin_m=-0.1)
    d = DEFAULT.as_dict()
    assert d["response_time_s"] == 0.5 and d["brake_max"] == 8.0 and d["accel_max"] == 3.5
    assert "arXiv:1708.06374" in d["source"]
    with pytest.raises(AttributeError):
        DEFAULT.brake_min = 1.0  # type: ignore[misc]


@given(st.floats(0.5, 10), st.floats(0.5, 3), st.floats(-math.pi, math.pi))
def test_body_extents_of_a_turned_rectangle(L, W, psi):
    hx, hy = body_extents(L, W, psi)
    c, s = math.cos(psi), math.sin(psi)
    corners = [(sx * L / 2 * c - sy * W / 2 * s, sx * L / 2 * s + sy * W / 2 * c) for sx in (-1, 1) for sy in (-1, 1)]
    assert float(hx) == pytest.approx(max(abs(p[0]) for p in corners), abs=1e-9)
    assert float(hy) == pytest.approx(max(abs(p[1]) for p in corners), abs=1e-9)


@settings(max_examples=60, deadline=None)
@given(st.floats(0, 40), st.floats(0, 40), st.floats(0.1, 2.0), st.floats(0.5, 5), st.floats(1, 6), st.floats(0, 5))
def test_longitudinal_distance_is_the_stopping_point_difference(vr, vf, rho, a, bmin, extra):
    """Integrating the worst case (rear: +a for rho, then -b_min to rest; front: -b_max to rest)
    gives the formula: the rear car's stopping point minus the front car's."""
    p = RssParameters(response_time_s=rho, accel_max=a, brake_min=bmin, brake_max=bmin + extra)
    rear = vr * rho + a * rho**2 / 2 + (vr + a * rho) ** 2 / (2 * bmin)
    front = vf**2 / (2 * (bmin + extra))
    assert float(safe_longitudinal_distance(vr, vf, p)) == pytest.approx(max(rear - front, 0.0), rel=1e-12, abs=1e-9)


# -- the reference implementation -----------------------------------------------------------------

def _adrss():  # type: ignore[no-untyped-def]
    return pytest.importorskip("ad_rss", reason="ad-rss (the RSS reference implementation) is not installed")


def _state(a, v_lon, v_lat, p):  # type: ignore[no-untyped-def]
    c, w, ph = a.rss.core, a.rss.world, a.physics
    r = c.RelativeObjectState()
    r.object_type = w.ObjectType.OtherVehicle
    v = r.structured_object_state.velocity
    v.speed_lon_min = v.speed_lon_max = ph.Speed(v_lon)
    v.speed_lat_min = v.speed_lat_max = ph.Speed(v_lat)
    r.structured_object_state.is_in_correct_lane = True
    r.structured_object_state.distance_to_enter_intersection = ph.Distance(1000.0)
    r.structured_object_state.distance_to_leave_intersection = ph.Distance(1000.0)
    d = r.dynamics  # ad-rss writes braking as a negative acceleration
    d.alpha_lon.accel_max = ph.Acceleration(p.accel_max)
    d.alpha_lon.brake_max = ph.Acceleration(-p.brake_max)
    d.alpha_lon.brake_min = ph.Acceleration(-p.brake_min)
    d.alpha_lon.brake_min_correct = ph.Acceleration(-p.brake_min)
    d.alpha_lat.accel_max = ph.Acceleration(p.lat_accel_max)
    d.alpha_lat.brake_min = ph.Acceleration(-p.lat_brake_min)
    d.lateral_fluctuation_margin = ph.Distance(p.lat_margin_m)
    d.response_time = ph.Duration(p.response_time_s)
    d.max_speed_on_acceleration = ph.Speed(100.0)
    u = d.unstructured_settings  # unused by the structured checks but validated
    u.pedestrian_turning_radius = ph.Distance(2.0)
    u.drive_away_max_angle = ph.Angle(2.4)
    u.vehicle_yaw_rate_change = ph.AngularAcceleration(0.3)
    u.vehicle_min_radius = ph.Distance(3.5)
    u.vehicle_trajectory_calculation_step = ph.Duration(0.2)
    for name in dir(u):
        if name.endswith("_steps"):
            setattr(u, name, 1)
    o = r.unstructured_object_state
    o.yaw, o.yaw_rate, o.steering_angle = ph.Angle(0.0), ph.AngularVelocity(0.0), ph.Angle(0.0)
    o.dimension.length, o.dimension.width = ph.Distance(4.8), ph.Distance(1.8)
    o.center_point.x, o.center_point.y = ph.Distance(0.0), ph.Distance(0.0)
    o.speed_range.minimum, o.speed_range.maximum = ph.Speed(0.0), ph.Speed(50.0)
    return r


def _r(v: float) -> float:
    """ad-rss refuses values below its resolution (e.g. subnormal speeds): 4 decimals."""
    return round(v, 4)


_params = st.builds(RssParameters, response_time_s=st.floats(0.2, 2.0).map(_r), accel_max=st.floats(0.5, 5.0).map(_r),
                    brake_min=st.floats(2.0, 5.0).map(_r), brake_max=st.just(8.0),
                    lat_accel_max=st.floats(0.1, 1.0).map(_r), lat_brake_min=st.floats(0.5, 2.0).map(_r),
                    lat_margin_m=st.floats(0.0, 0.5, allow_subnormal=False).map(_r))


@settings(max_examples=150, deadline=None)
@given(st.floats(0, 45, allow_subnormal=False).map(_r), st.floats(0, 45, allow_subnormal=False).map(_r), _params)
def test_longitudinal_distance_equals_ad_rss(vr, vf, p):
    a = _adrss()
    d = a.physics.Distance(0.0)
    lead, rear = _state(a, vf, 0.0, p), _state(a, vr, 0.0, p)
    assert a.rss.structured.calculateSafeLongitudinalDistanceSameDirection(lead, rear, d)
    assert float(safe_longitudinal_distance(vr, vf, p)) == pytest.approx(d.mDistance, rel=1e-9, abs=1e-6)


@settings(max_examples=150, deadline=None)
@given(st.floats(-3, 3, allow_subnormal=False).map(_r), st.floats(-3, 3, allow_subnormal=False).map(_r), _params)
def test_lateral_distance_equals_ad_rss_where_the_bracket_is_not_negative(u1, u2, p):
    """ad-rss's left object has its lateral speed positive to the right (toward the right
    object); its right object positive to the right too (away from the left one).  ad-rss adds
    mu inside the positive part, the paper outside: equal when the bracket is >= 0."""
    a = _adrss()
    d = a.physics.Distance(0.0)
    assert a.rss.structured.calculateSafeLateralDistance(_state(a, 0.0, u1, p), _state(a, 0.0, -u2, p), d)
    bracket = float(lateral_reach(u1, p) + lateral_reach(u2, p))
    ours = float(safe_lateral_distance(u1, u2, p))
    if bracket >= 0:
        assert ours == pytest.approx(d.mDistance, rel=1e-9, abs=1e-6)
    else:
        assert d.mDistance == pytest.approx(max(0.0, p.lat_margin_m + bracket), abs=1e-6)
        assert ours == pytest.approx(p.lat_margin_m)


# -- dangerous situation, threshold time, proper response, blame ------------------------------------

def _motion(x, y, vx, vy, L=4.8, W=1.8):  # type: ignore[no-untyped-def]
    x, y, vx, vy = (np.asarray(a, dtype=float) for a in (x, y, vx, vy))
    hx, hy = body_extents(np.full(x.size, L), np.full(x.size, W), np.zeros(x.size))
    return Motion(x, y, vx, vy, hx, hy)


def _integrate(x0, v0, acc, dt):  # type: ignore[no-untyped-def]
    v = v0 + np.concatenate([[0.0], np.cumsum(acc[:-1])]) * dt
    x = x0 + np.concatenate([[0.0], np.cumsum(v[:-1])]) * dt
    return x, v


def test_a_cut_in_is_the_fault_of_the_car_that_keeps_moving_sideways():
    """The ego changes lanes in front of a follower at the same speed, 12 m bumper to bumper
    (longitudinally unsafe all along); the danger starts when the lateral distance becomes
    unsafe, the required response is lateral, the ego keeps moving sideways: the ego is
    responsible, the follower (no lateral motion) is not."""
    dt, n = 0.1, 60
    t = np.arange(n) * dt
    vy = np.where((t >= 1.0) & (t < 4.0), -1.0, 0.0)  # the ego moves right from y = 3.2 to 0.2
    y = 3.2 + np.concatenate([[0.0], np.cumsum(vy[:-1])]) * dt
    ego = _motion(100 + 25 * t, y, np.full(n, 25.0), vy)
    follower = _motion(100 - 4.8 - 12 + 25 * t, np.zeros(n), np.full(n, 25.0), np.zeros(n))
    j = judge_ad(ego, follower, dt)
    assert not j.dangerous[:10].any() and j.dangerous[-1]
    k0 = int(np.argmax(j.dangerous))
    assert j.blame_k[k0] == k0 - 1 and j.response[k0] == "lateral"
    assert j.ego_responsible[-1] and not j.other_responsible.any()


def test_a_follower_that_does_not_brake_is_responsible_and_the_braking_ego_is_not():
    """Same lane; the follower closes in from a safe distance; the ego in front brakes at
    3 m/s^2 (below b_max): the response is longitudinal, the follower must brake with b_min
    after rho and does not."""
    dt, n = 0.1, 80
    acc_e = np.full(n, -3.0)
    xe, ve = _integrate(200.0, 25.0, acc_e, dt)
    xf, vf = _integrate(200.0 - 4.8 - 150.0, 30.0, np.zeros(n), dt)  # d_lon(30, 25) = 133 m: safe at first
    ego, fol = _motion(xe, np.zeros(n), ve, np.zeros(n)), _motion(xf, np.zeros(n), vf, np.zeros(n))
    j = judge_ad(ego, fol, dt)
    assert j.dangerous.any()
    k0 = int(np.argmax(j.dangerous))
    assert j.response[k0] == "longitudinal" and j.blame_k[k0] == k0 - 1
    assert not j.ego_responsible.any()
    assert j.other_responsible[-1] and not j.other_responsible[k0]  # within rho it may still accelerate


def test_a_front_car_braking_beyond_b_max_is_responsible_and_a_proper_follower_is_not():
    dt, n = 0.1, 60
    acc_f = np.where(np.arange(n) * dt >= 0.5, -4.5, 0.0)  # the follower (ego) brakes with more than b_min
    xo, vo = _integrate(200.0, 25.0, np.full(n, -9.5), dt)  # the front car brakes beyond b_max = 8
    vo = np.maximum(vo, 0.0)
    xe, ve = _integrate(200.0 - 4.8 - 90.0, 25.0, acc_f, dt)
    ve = np.maximum(ve, 0.0)
    j = judge_ad(_motion(xe, np.zeros(n), ve, np.zeros(n)), _motion(xo, np.zeros(n), vo, np.zeros(n)), dt)
    assert j.dangerous[2] and j.response[2] == "longitudinal"
    assert j.other_responsible[j.dangerous].any() and not j.ego_responsible.any()
    braking_late = np.where(np.arange(n) * dt >= 1.5, -4.5, 0.0)  # starts after rho: the ego is responsible too
    xe, ve = _integrate(200.0 - 4.8 - 90.0, 25.0, braking_late, dt)
    j = judge_ad(_motion(xe, np.zeros(n), np.maximum(ve, 0), np.zeros(n)), _motion(xo, np.zeros(n), vo, np.zeros(n)),
                   dt)
    assert j.ego_responsible.any() and j.other_responsible.any()


def test_a_danger_present_from_the_first_step_has_no_threshold_time_and_both_responses():
    dt, n = 0.1, 20
    t = np.arange(n) * dt
    ego = _motion(100 + 20 * t, np.zeros(n), np.full(n, 20.0), np.zeros(n))
    lead = _motion(100 + 4.8 + 5 + 20 * t, np.zeros(n), np.full(n, 20.0), np.zeros(n))
    j = judge_ad(ego, lead, dt)
    assert j.dangerous.all() and (j.blame_k == -1).all() and set(j.response) == {"both"}
    assert j.ego_responsible[-1]  # the rear ego does not brake
    assert not j.other_responsible.any()


@pytest.mark.parametrize("side", [1.0, -1.0])
def test_a_level_pair_takes_the_side_it_separates_to(side: float) -> None:
    """Ego and a too-close follower on one lane's centre (``dy == 0``: left and right undefined);
    the ego, which keeps its speed (a proper front car), moves sideways to either side: it moves
    *away* from the follower, so it is not responsible (before, a level pair made the ego the
    right car and a move to the left counted as moving toward the other).  The follower, which
    does not brake, is."""
    dt, n = 0.1, 40
    t = np.arange(n) * dt
    vy = np.where(t >= 0.5, side * 1.0, 0.0)
    y = np.concatenate([[0.0], np.cumsum(vy[:-1])]) * dt
    ego = _motion(100 + 20 * t, y, np.full(n, 20.0), vy)
    fol = _motion(100 - 4.8 - 8 + 20 * t, np.zeros(n), np.full(n, 20.0), np.zeros(n))
    j = judge_ad(ego, fol, dt)
    assert j.dangerous[0] and set(r for r in j.response if r) == {"both"}
    assert not j.ego_responsible.any()
    assert j.other_responsible.any()
    swapped = judge_ad(fol, ego, dt)  # the same pair from the follower's side: the same blame
    assert np.array_equal(swapped.other_responsible, j.ego_responsible)
    assert np.array_equal(swapped.ego_responsible, j.other_responsible)


@pytest.mark.parametrize("side", [1.0, -1.0])
@pytest.mark.parametrize("drift", [5e-5, 5e-3, -5e-3, 0.09])
def test_a_pair_a_few_millimetres_apart_is_level_and_takes_the_side_it_separates_to(side: float,
                                                                                     drift: float) -> None:
    """As above, with the lane keeping's drift: the follower ``drift`` metres beside the ego (within
    RSS's lateral fluctuation margin μ = 0.1 m) until the ego moves sideways either way.  The pair
    is level there, so the ego moving away is not responsible.  Before, the sign of a 0.05 mm
    offset decided the roles, and a lane change away from the follower counted as a move toward
    it (slow-leader LOS E seed 69: 12.6 s at fault)."""
    dt, n = 0.1, 40
    t = np.arange(n) * dt
    vy = np.where(t >= 0.5, side * 1.0, 0.0)
    y = np.concatenate([[0.0], np.cumsum(vy[:-1])]) * dt
    ego = _motion(100 + 20 * t, y, np.full(n, 20.0), vy)
    fol = _motion(100 - 4.8 - 8 + 20 * t, np.full(n, drift), np.full(n, 20.0), np.zeros(n))
    j = judge_pair(ego, fol, dt)  # DEFAULT: μ = 0.1 m
    assert j.dangerous[0] and set(r for r in j.response if r) == {"both"}
    assert not j.ego_responsible.any() and j.other_responsible.any()
    swapped = judge_pair(fol, ego, dt)
    assert np.array_equal(swapped.other_responsible, j.ego_responsible)
    # a pair that was apart by more than μ keeps its roles: the ego 0.5 m to the right of the
    # follower and moving left is moving toward it
    apart = _motion(100 - 4.8 - 8 + 20 * t, np.full(n, 0.5), np.full(n, 20.0), np.zeros(n))
    moving_left = _motion(100 + 20 * t, np.concatenate([[0.0], np.cumsum(np.where(t >= 0.5, 1.0, 0.0)[:-1])]) * dt,
                          np.full(n, 20.0), np.where(t >= 0.5, 1.0, 0.0))
    assert judge_pair(moving_left, apart, dt).ego_responsible.any()


def test_a_rear_car_creeping_toward_a_standing_car_is_responsible() -> None:
    """The rear car's bound after the response time is ``max(0, v - (b_min - tol) dt)``: a rear ego
    creeping at 0.6 m/s 1 m behind a standing car does not brake and is responsible (a floor above
    its speed, e.g. 1 m/s, would excuse it)."""
    dt, n = 0.1, 15
    t = np.arange(n) * dt
    ego = _motion(100 + 0.6 * t, np.zeros(n), np.full(n, 0.6), np.zeros(n))
    stand = _motion(np.full(n, 100 + 4.8 + 1.0), np.zeros(n), np.zeros(n), np.zeros(n))  # RSS: 1.43 m
    j = judge_pair(ego, stand, dt)
    assert j.dangerous.all() and j.ego_responsible[-1] and not j.other_responsible.any()


def test_unseen_steps_do_not_give_a_level_pair_its_side() -> None:
    """The level pair above (ego moving left from 0.5 s, the follower on the lane's centre), the
    follower unseen for two steps while the pair is still level: the roles come from the steps where
    the two are seen more than μ apart (the ego left of the follower), not from the unseen ones."""
    dt, n = 0.1, 40
    t = np.arange(n) * dt
    vy = np.where(t >= 0.5, 1.0, 0.0)
    ego = _motion(100 + 20 * t, np.concatenate([[0.0], np.cumsum(vy[:-1])]) * dt, np.full(n, 20.0), vy)
    y = np.zeros(n)
    y[7:9] = np.nan
    fol = _motion(100 - 4.8 - 8 + 20 * t, y, np.full(n, 20.0), np.zeros(n))
    j = judge_pair(ego, fol, dt)
    assert j.dangerous[:7].all() and not j.ego_responsible.any()


def test_a_pair_never_apart_takes_the_ego_as_the_right_car() -> None:
    """Both cars on one lane's centre, moving left in step (``dy == 0`` throughout, the follower too
    close): left and right are never decided by the motion, and the ego is the right car, so its
    move to the left is toward the other and it is responsible (as the front car keeping its speed
    it keeps its longitudinal response: the lateral one is what it breaks)."""
    dt, n = 0.1, 30
    t = np.arange(n) * dt
    vy = np.where(t >= 0.5, 1.0, 0.0)
    y = np.concatenate([[0.0], np.cumsum(vy[:-1])]) * dt
    ego = _motion(100 + 20 * t, y, np.full(n, 20.0), vy)
    fol = _motion(100 - 4.8 - 8 + 20 * t, y, np.full(n, 20.0), vy)
    j = judge_pair(ego, fol, dt)
    assert j.ego_responsible.any()


@settings(max_examples=200, deadline=None)
@given(st.floats(-300.0, 300.0), st.floats(0.0, 45.0), st.floats(0.0, 45.0), st.floats(3.0, 18.0))
def test_rss_reach_is_the_rss_distance_of_the_pair_s_rear_car_plus_the_margin(dx, v_other, v_ego, length):
    """``within_rss_reach``: the bumper gap at most the RSS distance (the rear car's speed first)
    plus 20 m; ahead the ego is the rear car, behind the other."""
    gap = abs(dx) - (length + 4.8) / 2
    d = safe_longitudinal_float(v_ego, v_other) if dx > 0 else safe_longitudinal_float(v_other, v_ego)
    assert within_rss_reach(dx, length, v_other, v_ego, 4.8) == (gap <= d + 20.0)


def test_rss_reach_follows_a_fast_car_beyond_a_fixed_range() -> None:
    """A car 137 m behind at 34 m/s closing on the ego at 20 m/s (slow-leader medium seed 29's):
    its RSS distance is about 150 m, so it is within reach; at the ego's speed it is not."""
    assert within_rss_reach(-137.0, 4.8, 34.0, 20.0, 4.8)
    assert not within_rss_reach(-137.0, 4.8, 20.0, 20.0, 4.8)
    assert within_rss_reach(144.9, 4.8, 21.5, 37.9, 4.8)  # a slow car ahead of a fast ego (merge medium 9)


def test_a_car_accelerating_sideways_beyond_alpha_within_rho_is_responsible() -> None:
    """Side by side (longitudinally unsafe throughout); the ego drifts toward the other at 0.4 m/s.
    From t_b on the other moves toward the ego with 3 alpha (0.6 m/s^2, above alpha = 0.2 plus the
    tolerance) during rho: it is responsible within rho; with alpha itself it is not (the previous
    test's case)."""
    dt, n = 0.1, 50
    t = np.arange(n) * dt
    ego = _motion(100 + 20 * t, 0.4 * t, np.full(n, 20.0), np.full(n, 0.4))
    still = _motion(100 + 20 * t, np.full(n, 3.5), np.full(n, 20.0), np.zeros(n))
    k0 = int(np.argmax(judge_pair(ego, still, dt).dangerous))
    assert k0 > 0
    tau = (np.arange(n) - (k0 - 1)) * dt
    rho = DEFAULT.response_time_s
    u = np.where(tau <= 0, 0.0, np.where(tau <= rho, 3 * DEFAULT.lat_accel_max * tau, 3 * DEFAULT.lat_accel_max * rho))
    vy_o = -u  # toward the ego (the other is the left car)
    y_o = 3.5 + np.concatenate([[0.0], np.cumsum(vy_o[:-1])]) * dt
    j = judge_pair(ego, _motion(100 + 20 * t, y_o, np.full(n, 20.0), vy_o), dt)
    k_rho = k0 + int(round(rho / dt))
    assert j.other_responsible[k0 + 1:k_rho].any()


@pytest.mark.parametrize("side", [1.0, -1.0])
def test_a_car_already_moving_sideways_may_accelerate_with_alpha_then_must_brake_with_beta(side: float) -> None:
    """Side by side (longitudinally unsafe throughout); the other already moves toward the ego at 0.3 m/s
    (above the fluctuation speed mu/rho = 0.2 m/s). From t_b on it accelerates toward the ego with exactly
    alpha for rho, then brakes with exactly beta to a stop: a proper lateral response (the tolerance lies on
    the allowed side), never responsible; braking only with beta / 2 after rho is not."""
    dt, n = 0.1, 60
    t = np.arange(n) * dt
    ego = _motion(100 + 20 * t, np.zeros(n), np.full(n, 20.0), np.zeros(n))

    def other(u: np.ndarray) -> Motion:
        vy = -side * u  # toward the ego
        y = side * 2.6 + np.concatenate([[0.0], np.cumsum(vy[:-1])]) * dt
        return _motion(100 + 20 * t, y, np.full(n, 20.0), vy)

    k0 = int(np.argmax(judge_pair(ego, other(np.full(n, 0.3)), dt).dangerous))
    assert k0 > 0
    tau = (np.arange(n) - (k0 - 1)) * dt
    rho, a, b = DEFAULT.response_time_s, DEFAULT.lat_accel_max, DEFAULT.lat_brake_min
    for brake, responsible in ((b, False), (b / 2, True)):
        u = np.where(tau <= 0, 0.3, np.where(tau <= rho, 0.3 + a * tau,
                                              np.maximum(0.3 + a * rho - brake * (tau - rho), 0.0)))
        j = judge_pair(ego, other(u), dt)
        assert int(np.argmax(j.dangerous)) == k0
        assert bool(j.other_responsible.any()) == responsible


def test_unseen_steps_are_never_dangerous_and_end_a_run():
    dt, n = 0.1, 10
    t = np.arange(n) * dt
    ego = _motion(100 + 20 * t, np.zeros(n), np.full(n, 20.0), np.zeros(n))
    x = 100 + 4.8 + 5 + 20 * t
    x[4] = np.nan
    j = judge_ad(ego, _motion(x, np.zeros(n), np.full(n, 20.0), np.zeros(n)), dt)
    assert not j.dangerous[4] and j.dangerous[5] and j.blame_k[5] == -1


# -- added by mutation testing (scripts/mutation_score.py simulation/rss.py --seed 3): each test pins a
#    part of the module docstring that a surviving mutant changed ----------------------------------

@settings(max_examples=60, deadline=None)
@example(dy=0.5, vy_e=0.8, vy_o=0.0)
@example(dy=-0.5, vy_e=-0.8, vy_o=0.3)
@given(st.floats(-4.0, 4.0).filter(lambda v: abs(v) > 1e-6), st.floats(-1.5, 1.5), st.floats(-1.5, 1.5))
def test_the_safe_lateral_distance_counts_each_car_s_speed_toward_the_other(dy, vy_e, vy_o):
    """d_lat of a pair is mu + [o(u_ego) + o(u_other)]_+ with u each car's lateral speed *toward
    the other* (whatever the offset, however small), and it does not depend on which car is the ego."""
    ego = _motion([0.0], [0.0], [20.0], [vy_e])
    other = _motion([1.0], [dy], [20.0], [vy_o])
    s = math.copysign(1.0, dy)  # the other is to the left (+y) of the ego when dy > 0
    j = judge_pair(ego, other, 0.1)
    assert float(j.d_lat[0]) == pytest.approx(float(safe_lateral_distance(s * vy_e, -s * vy_o)), abs=1e-12)
    swapped = judge_pair(other, ego, 0.1)
    assert float(swapped.d_lat[0]) == pytest.approx(float(j.d_lat[0]), abs=1e-12)
    assert float(swapped.d_lon[0]) == pytest.approx(float(j.d_lon[0]), abs=1e-12)


def test_a_danger_from_the_second_step_judges_the_first_period():
    """Safe at step 0 (gap 66 m >= d_lon(20, 20) = 65.78125 m), dangerous from step 1 because the
    front car brakes at 20 m/s^2 > b_max: t_b is step 0 and the period (0, 1] is judged, so the front
    car is responsible at step 1 already; the rear ego at constant speed (within rho) is not."""
    dt, n = 0.1, 10
    assert float(safe_longitudinal_distance(20.0, 20.0, AD_RSS)) == pytest.approx(65.78125)
    xe, ve = _integrate(100.0, 20.0, np.zeros(n), dt)
    xo, vo = _integrate(100.0 + 4.8 + 66.0, 20.0, np.full(n, -20.0), dt)
    j = judge_ad(_motion(xe, np.zeros(n), ve, np.zeros(n)), _motion(xo, np.zeros(n), np.maximum(vo, 0), np.zeros(n)),
                   dt)
    assert not j.dangerous[0] and j.dangerous[1]
    assert j.blame_k[1] == 0 and j.response[1] == "longitudinal"
    assert j.other_responsible[1] and not j.ego_responsible.any()


def test_a_run_after_an_unseen_step_is_judged_from_its_first_time_and_its_rho_starts_there():
    """Dangerous throughout, the other unseen at step 14: the run from step 15 has no t_b (strict
    reading: judged from its first time).  The ego's jump in speed over (14, 15] is not judged; the
    rear ego may keep its speed during rho = 1 s counted, as for a run from step 0, from the step
    before the first time (periods with (k - 1 - 14) dt < rho: steps 16..24) and must brake after
    it: responsible from step 25 on.  (Counted from the step after an unseen one, not from -1: the
    run at step 25 is 1 s old, not 2.6 s.)"""
    dt, n = 0.1, 40
    ve = np.where(np.arange(n) >= 15, 21.0, 20.0)  # +1 m/s over one period (10 m/s^2) into step 15
    xe = 100.0 + np.concatenate([[0.0], np.cumsum(ve[:-1])]) * dt
    xo = 100.0 + 4.8 + 5.0 + 20.0 * np.arange(n) * dt
    xo[14] = np.nan
    j = judge_ad(_motion(xe, np.zeros(n), ve, np.zeros(n)), _motion(xo, np.zeros(n), np.full(n, 20.0), np.zeros(n)),
                   dt)
    assert j.dangerous[:14].all() and not j.dangerous[14] and j.dangerous[15:].all()
    assert (j.blame_k[15:] == -1).all()
    assert not j.ego_responsible[14:25].any()
    assert j.ego_responsible[25:].all()
    assert not j.other_responsible.any()


@settings(max_examples=40, deadline=None)
@given(st.one_of(st.floats(0.0, 3.4), st.floats(3.7, 8.0)))
@example(3.5)  # exactly a_acc: allowed (the tolerance is on the allowed side)
def test_a_follower_is_responsible_within_rho_exactly_when_it_accelerates_beyond_a_acc(acc):
    """During rho after t_b the rear car may accelerate with at most a_acc (+ ACCEL_TOL = 3.55 m/s^2):
    a follower accelerating harder is responsible at the first dangerous step, one within it is not
    responsible before t_b + rho."""
    dt, n = 0.1, 80
    xe, ve = _integrate(200.0, 25.0, np.full(n, -3.0), dt)
    xf, vf = _integrate(200.0 - 4.8 - 150.0, 30.0, np.full(n, acc), dt)
    j = judge_ad(_motion(xe, np.zeros(n), ve, np.zeros(n)), _motion(xf, np.zeros(n), vf, np.zeros(n)), dt)
    k0 = int(np.argmax(j.dangerous))
    assert j.dangerous[k0] and k0 > 0 and j.response[k0] == "longitudinal"
    if acc > DEFAULT.accel_max:
        assert j.other_responsible[k0]
    else:
        assert not j.other_responsible[k0:k0 + 10].any()
    assert not j.ego_responsible.any()


@settings(max_examples=30, deadline=None)
@given(st.floats(0.3, 0.5), st.floats(0.05, 0.2), st.floats(0.8, 1.6), st.sampled_from([-1.0, 1.0]))
@example(0.4, 0.2, 0.8, 1.0)  # exactly alpha, then exactly beta: a proper response (tolerance on the allowed side)
def test_a_car_that_responds_laterally_as_rss_says_is_never_responsible(drift, a, b, side):
    """Side by side (longitudinally unsafe throughout); the ego drifts toward the other at a constant
    lateral speed. The other, from t_b on, moves toward the ego with a <= alpha for rho and then
    brakes with b >= beta to a stop: the ego is responsible, the other never, on either side (the
    other is the left car when side = +1, the right car when side = -1)."""
    dt, n = 0.1, 50
    t = np.arange(n) * dt
    vy_e = np.full(n, side * drift)
    y_e = side * drift * t
    still = _motion(100 + 20 * t, np.full(n, side * 3.5), np.full(n, 20.0), np.zeros(n))
    ego = _motion(100 + 20 * t, y_e, np.full(n, 20.0), vy_e)
    k0 = int(np.argmax(judge_pair(ego, still, dt).dangerous))
    assert k0 > 0
    tau = (np.arange(n) - (k0 - 1)) * dt  # time since t_b
    rho = DEFAULT.response_time_s
    u = np.where(tau <= 0, 0.0, np.where(tau <= rho, a * tau, np.maximum(a * rho - b * (tau - rho), 0.0)))
    vy_o = -side * u  # toward the ego
    y_o = side * 3.5 + np.concatenate([[0.0], np.cumsum(vy_o[:-1])]) * dt
    j = judge_pair(ego, _motion(100 + 20 * t, y_o, np.full(n, 20.0), vy_o), dt)
    assert int(np.argmax(j.dangerous)) == k0 and j.dangerous[k0:].all() and j.response[k0] == "lateral"
    assert not j.other_responsible.any()
    assert j.ego_responsible[-1]
