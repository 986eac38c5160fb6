"""Closed loop in SUMO (SPEC §11): geometry, metrics, intervals, determinism, resumable campaigns."""

from __future__ import annotations

import builtins
import importlib.util
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from iamp.core.errors import MissingDependencyError
from iamp.core.problem import EgoBoundary
from iamp.simulation.campaign import _append, flatten, read_rows, run_campaign, summarise, wilson
from iamp.simulation.metrics import StepLog, episode_metrics
from iamp.simulation.network import Highway
from iamp.simulation.planning import FreeTrajectory, free_plan

finite = st.floats(-50, 50, allow_nan=False)


# -- the unconstrained plan ---------------------------------------------------------------------
@settings(max_examples=40, deadline=None)
@given(x0=finite, vx0=st.floats(0, 40), dx=st.floats(20, 200), vxf=st.floats(0, 40), y0=finite, dy=finite,
       vy0=st.floats(-2, 2), tf=st.floats(1, 8))
def test_free_plan_meets_its_boundary_and_its_cost_is_the_closed_form(x0, vx0, dx, vxf, y0, dy, vy0, tf):
    ego = EgoBoundary(tf=tf, x0=x0, y0=y0, vx0=vx0, vy0=vy0, xf=x0 + dx, yf=y0 + dy, vxf=vxf, vyf=0.0)
    traj = FreeTrajectory.of(ego)
    X = traj.states(np.array([0.0, tf]))
    np.testing.assert_allclose(X[0], ego.initial, atol=1e-9)
    np.testing.assert_allclose(X[1], ego.final, rtol=1e-9, atol=1e-7)
    # J = Σ 6e²/tf³ − 6eg/tf² + 2g²/tf per axis, e = sf − s0 − v0 tf, g = vf − v0
    J = 0.0
    for s0, v0, sf, vf in ((x0, vx0, x0 + dx, vxf), (y0, vy0, y0 + dy, 0.0)):
        e, g = sf - s0 - v0 * tf, vf - v0
        J += 6 * e**2 / tf**3 - 6 * e * g / tf**2 + 2 * g**2 / tf
    plan = free_plan(ego, "pmp")
    assert plan.cost == pytest.approx(J, rel=1e-9, abs=1e-9)
    # the input is linear in t: the cubic's second derivative
    U = traj.inputs(np.linspace(0, tf, 7))
    np.testing.assert_allclose(np.diff(U, 2, axis=0), 0.0, atol=1e-7 * (1 + float(np.abs(U).max())))


# -- Wilson intervals ---------------------------------------------------------------------------
def test_wilson_known_values():
    lo, hi = wilson(0, 20)
    assert lo == 0.0 and hi == pytest.approx(0.1611, abs=1e-4)
    lo, hi = wilson(10, 20)
    assert (lo, hi) == pytest.approx((0.2993, 0.7007), abs=1e-4)


@given(n=st.integers(1, 500), data=st.data())
def test_wilson_contains_the_estimate_and_stays_in_unit_interval(n, data):
    k = data.draw(st.integers(0, n))
    lo, hi = wilson(k, n)
    assert 0.0 <= lo <= k / n + 1e-12 and k / n - 1e-12 <= hi <= 1.0
    # four times the data (same proportion): the interval shrinks
    lo4, hi4 = wilson(4 * k, 4 * n)
    assert hi4 - lo4 < hi - lo


# -- geometry -------------------------------------------------------------------------------------
@given(lane=st.integers(0, 2), off=st.floats(-1.8, 1.8))
def test_lane_of_inverts_lane_centre(lane, off):
    hw = Highway()
    assert hw.lane_of(hw.lane_centre(lane) + off) == lane


# -- metrics on a synthetic log ---------------------------------------------------------------------
def _log(dx_of_t, dy=0.0, v_ego=20.0, v_nb=20.0, n=50, dt=0.1):
    log = StepLog()
    for k in range(n):
        t = k * dt
        xe = v_ego * t
        log.t.append(t)
        log.ego.append((xe, v_ego, 0.0, 0.0, 0.0, 0.0))
        log.mode.append("active")
        log.plan_time.append(1e-4)
        log.ids.append(("a",))
        log.nb.append(np.array([[xe + dx_of_t(t), dy, v_nb, -1.0, 1, 4.0, 2.0]]))
    return log


def test_metrics_gap_ttc_intrusion_and_overlap_are_exact():
    dt = 0.1
    # a neighbour 20 m ahead (centres), closing at 5 m/s: gap = 20 - 5t - (4.8 + 4)/2
    log = _log(lambda t: 20.0 - 5.0 * t, v_ego=20.0, v_nb=15.0, n=30, dt=dt)
    m = episode_metrics(log, dt, (4.8, 1.8), (5.0, 0.5), [])
    g_end = 20.0 - 5.0 * 2.9 - 4.4
    assert m["min_gap_m"] == pytest.approx(g_end)
    assert m["min_ttc_s"] == pytest.approx(g_end / 5.0)
    # intrusion while |dx| < 4/2 + 5 = 7, i.e. 20 - 5t < 7  <=>  t > 2.6 (steps 2.7, 2.8, 2.9)
    assert m["intrusion_s"] == pytest.approx(3 * dt)
    assert m["collisions"] == 0
    # overlap once |dx| < (4.8 + 4)/2 = 4.4
    log = _log(lambda t: 10.0 - 5.0 * t, v_ego=20.0, v_nb=15.0, n=30, dt=dt)
    m = episode_metrics(log, dt, (4.8, 1.8), (5.0, 0.5), [(1.0, "a", "collision"), (1.0, "b", "collision")])
    assert m["overlap_collisions"] == 1 and m["sumo_collisions"] == 2 and m["collisions"] == 2
    # a neighbour in the next lane (dy = 3.75) never gaps, overlaps or intrudes
    m = episode_metrics(_log(lambda t: 0.0, dy=3.75), dt, (4.8, 1.8), (5.0, 0.5), [])
    assert m["collisions"] == 0 and m["intrusion_s"] == 0 and m["min_gap_m"] is None


def test_rms_of_a_constant_acceleration_is_that_acceleration():
    dt, a = 0.1, 1.5
    log = StepLog()
    for k in range(40):
        t = k * dt
        log.t.append(t)
        log.ego.append((0.5 * a * t * t, a * t, 0.0, 0.0, a, 0.0))
        log.ids.append(())
        log.nb.append(np.zeros((0, 7)))
    m = episode_metrics(log, dt, (4.8, 1.8), (5.0, 0.5), [])
    assert m["rms_accel"][0] == pytest.approx(a) and m["rms_jerk"][0] == pytest.approx(0.0, abs=1e-6)


# -- campaign files -----------------------------------------------------------------------------------
def _summary(planner, traffic, seed, contacts=0):
    """A SPEC §15 summary with every key ``flatten`` reads."""
    return {"mission": "merge", "planner": planner, "traffic": traffic, "seed": seed, "cooperation": "default",
            "sublane": False, "duration_s": 5.0, "period_s": 0.1, "simulated_s": 5.0, "distance_to_end_m": 400.0,
            "success": contacts == 0, "time_to_merge_s": 4.0, "stopped_at_end": False,
            "contacts": contacts, "ego_lost": False,
            "overlap_contacts": contacts, "sumo_contacts": 0, "mingap_violations": 0, "min_ttc_s": None,
            "ttc_below_1_5_s": 0.0, "new_follower": "v1", "follower_max_decel": 1.0, "ego_peak_accel": 2.0,
            "ego_ax_range": [-1.0, 1.0], "ego_ay_peak": 1.0, "ego_jerk_peak": 3.0, "limit_violations": 0,
            "jerk_violations": 0, "lane_change_done_s": 4.0, "lane_changes": 1, "intrusion_s": 0.0,
            "min_gap_m": 10.0, "min_follower_accel": -1.0, "rms_accel": [0.1, 0.2], "rms_jerk": [0.3, 0.4],
            "plan_time_s": {"p50": 1e-4, "p95": 2e-4, "max": 1e-3}, "plans": 10, "planner_calls": 8,
            "executed_plans": 40, "constrained_plans": 2, "infeasible_plans": 0, "rejected": {"limits": 2},
            "late_plans": 0, "deadline_s": None, "fallbacks": 0, "aborts": 0,
            "wall_s": {"total": 1.0, "sumo": 0.5, "prediction": 0.3, "planning": 0.1}, "max_rss_mb": 150.0}


def test_campaign_rows_append_and_a_complete_campaign_resumes_without_running(tmp_path):
    path = tmp_path / "episodes.csv"
    from iamp.simulation.campaign import COLUMNS, manifest_of

    for s in (1, 2):
        _append(path, COLUMNS, flatten(_summary("pmp", "light", s, contacts=s - 1)))
    rows = read_rows(path)
    assert [int(r["seed"]) for r in rows] == [1, 2] and rows[0]["min_ttc_s"] == ""
    assert rows[0]["rejected"] == "limits=2" and rows[1]["ego_ax_min"] == "-1.0"
    summ = summarise(rows)
    assert summ[0]["contact_episodes"] == 1 and summ[0]["contact_ci"] == pytest.approx(wilson(1, 2))
    assert summ[0]["success_episodes"] == 1
    episode = {"duration_s": 60.0, "period_s": 0.1, "deadline_s": None, "warmup_s": 5.0, "settle_s": 8.0,
               "cooperation": "default", "sublane": False}
    import json

    (tmp_path / "manifest.json").write_text(json.dumps(manifest_of(["merge"], ["pmp"], ["light"], 2, episode)))
    calls = []
    stats = run_campaign(["pmp"], ["light"], 2, tmp_path, progress=lambda d, t: calls.append((d, t)))
    assert stats["ran"] == 0 and stats["skipped"] == 2 and calls == [(2, 2)]


def test_missing_sumo_raises_the_install_hint(monkeypatch):
    real = builtins.__import__

    def fake(name, *args, **kwargs):
        if name in ("libsumo", "sumolib"):
            raise ImportError(name=name)
        return real(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", fake)
    from iamp.simulation.network import require_sumo

    with pytest.raises(MissingDependencyError, match=r"pip install 'iamp\[sim\]'"):
        require_sumo()


# -- SUMO episodes -----------------------------------------------------------------------------------
#: The tests below run SUMO (libsumo); the ones above do not and are collected without it.
needs_sumo = pytest.mark.skipif(importlib.util.find_spec("libsumo") is None,
                                reason="SUMO is not installed (pip install 'iamp[sim]')")


def _episode(planner, seed=1, traffic="medium", duration=6.0):
    from iamp.simulation.episode import EpisodeSpec, run_episode

    return run_episode(EpisodeSpec(traffic=traffic, seed=seed, planner=planner, duration_s=duration,
                                   deadline_s=None, mission="discretionary"))


def _strip(summary):
    return {k: v for k, v in summary.items() if k not in ("plan_time_s", "wall_s", "max_rss_mb")}


@needs_sumo
def test_network_lane_centres_match_the_geometry():
    from iamp.simulation.network import build_network, lane_centres

    hw = Highway()
    np.testing.assert_allclose(lane_centres(build_network(hw)), [hw.lane_centre(k) for k in range(3)], atol=0.01)


@needs_sumo
def test_same_seed_same_numbers_and_the_plan_is_what_the_ego_executes():
    a, b = _episode("pmp"), _episode("pmp")
    assert _strip(a.summary) == _strip(b.summary)
    np.testing.assert_array_equal(np.asarray(a.log.ego), np.asarray(b.log.ego))
    s = a.summary
    assert set(s) >= {"planner", "traffic", "seed", "duration_s", "period_s", "lane_change_done_s", "collisions",
                      "intrusion_s", "min_gap_m", "min_ttc_s", "rms_accel", "rms_jerk", "plan_time_s", "plans",
                      "infeasible_plans", "fallbacks", "mission", "success", "contacts"}
    assert len(a.log.t) == round(6.0 / 0.1)
    # the executed ego motion is continuous: no step moves it further than its speed allows
    E = np.asarray(a.log.ego)
    assert np.all(np.abs(np.diff(E[:, 0])) <= 0.1 * np.maximum(E[:-1, 1], E[1:, 1]) + 0.5)
    assert np.all(np.abs(np.diff(E[:, 2])) < 0.5)


@needs_sumo
def test_another_seed_gives_other_traffic():
    assert _strip(_episode("sumo", seed=1).summary) != _strip(_episode("sumo", seed=2).summary)


@needs_sumo
@pytest.mark.slow
def test_a_full_minute_of_each_planner_runs_and_reports_finite_numbers():
    for planner in ("pmp", "qp", "sumo"):
        s = _episode(planner, seed=3, traffic="dense", duration=60.0).summary
        assert s["plans"] == 0 if planner == "sumo" else s["plans"] > 0
        assert all(math.isfinite(v) for v in s["rms_accel"] + s["rms_jerk"])


@needs_sumo
def test_campaign_on_an_existing_scheduler_writes_rows_and_resumes(tmp_path):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                  dashboard_address=":0") as cluster:
        seen = []
        stats = run_campaign(["sumo"], ["light"], 2, tmp_path, scheduler=cluster.scheduler_address,
                             duration_s=1.0, progress=lambda d, t: seen.append((d, t)))
        assert stats["ran"] == 2 and stats["failed"] == 0 and seen[-1] == (2, 2)
        rows = read_rows(tmp_path / "episodes.csv")
        assert sorted(int(r["seed"]) for r in rows) == [1, 2]
        again = run_campaign(["sumo"], ["light"], 2, tmp_path, scheduler=cluster.scheduler_address, duration_s=1.0)
        assert again["ran"] == 0 and again["skipped"] == 2
