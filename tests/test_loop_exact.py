"""The closed loop's speed-ups compute the same numbers as the code they replace (issue 32 item 5).

Each faster path is checked against an independent statement of what it must equal: the kept
history against a queue of pairs, the row median against ``numpy.median``, the fail-safe check
of many vehicles against the same check one vehicle at a time.
"""

from __future__ import annotations

from collections import deque

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from iamp.prediction.initial_state import _row_median, noise_sigma, smooth_histories
from iamp.simulation.failsafe import Obstacle, SafeParams, feasible_brakes
from iamp.simulation.simulator import TrackBuffer

finite = st.floats(-1e3, 1e3, allow_nan=False, allow_infinity=False)


@settings(max_examples=60, deadline=None)
@given(steps=st.lists(st.tuples(st.sampled_from([0.0, 0.1, 0.1, 0.1, 0.25, 1.0]), finite), min_size=1, max_size=150),
       horizon=st.sampled_from([0.35, 1.0, 3.0]))
def test_track_buffer_keeps_what_a_queue_of_pairs_keeps(steps, horizon):
    """Appending (replacing a sample of the same time) and dropping the old ones as a deque does."""
    ref: deque[tuple[float, float]] = deque()
    buf = TrackBuffer(capacity=4)
    now = 0.0
    for dt, x in steps:
        now += dt
        if ref and ref[-1][0] >= now - 1e-9:
            ref.pop()
        ref.append((now, x))
        while ref and ref[0][0] < now - horizon:
            ref.popleft()
        buf.record(now, x, now - horizon)
        assert len(buf) == len(ref)
        assert buf.t[buf.lo:buf.hi].tolist() == [p[0] for p in ref]
        assert buf.x[buf.lo:buf.hi].tolist() == [p[1] for p in ref]


@settings(max_examples=80, deadline=None)
@given(rows=st.integers(1, 6), n=st.integers(1, 40), seed=st.integers(0, 2**31 - 1), ties=st.booleans())
def test_row_median_is_numpy_median_bit_for_bit(rows, n, seed, ties):
    A = np.abs(np.random.default_rng(seed).standard_normal((rows, n)))
    if ties:
        A = np.round(A, 1)
    assert _row_median(A).tobytes() == np.median(A, axis=1).tobytes()
    A[0, 0] = np.nan  # a NaN row: numpy's answer (NaN) too
    assert np.array_equal(_row_median(A), np.median(A, axis=1), equal_nan=True)


def test_noise_sigma_of_white_noise_and_of_a_quadratic():
    """The robust scale recovers the noise of white noise on a quadratic (module docstring) and the floor
    for a noise-free quadratic; the smoother's noise levels are its two-digit rounding."""
    t = np.round(np.arange(-30, 1) * 0.1, 9)
    rng = np.random.default_rng(3)
    clean = 20.0 * t + 0.4 * t**2
    noisy = clean + 0.05 * rng.standard_normal((200, t.size))
    sig = noise_sigma(t, noisy)
    assert abs(float(np.median(sig)) - 0.05) < 0.01
    assert noise_sigma(t, clean[None, :])[0] == 1e-3
    sm = smooth_histories(t, noisy[:5])
    assert sm.sigma.tolist() == [float(f"{s:.2g}") for s in sig[:5]]


vehicle = st.tuples(st.floats(-60, 60), st.floats(0, 35), st.floats(-2, 2), st.floats(-9.0, -1.0),
                    st.floats(-1.5, 1.5), st.floats(4.0, 12.0))


@settings(max_examples=60, deadline=None)
@given(vehicles=st.lists(vehicle, min_size=1, max_size=6), ego_v=st.floats(0, 35), ego_y=st.floats(-9.0, -1.0),
       ego_vy=st.floats(-1.5, 1.5), ax=st.floats(-6, 3))
def test_feasible_brakes_of_many_is_the_intersection_of_each_alone(vehicles, ego_v, ego_y, ego_vy, ax):
    """A deceleration is safe against several vehicles iff it is safe against each one alone; the
    culprit of a sample is the first vehicle (in the given order) that alone excludes every one."""
    t = np.linspace(0.0, 3.0, 31)
    X = np.stack([ego_v * t, np.full_like(t, ego_v), ego_y + ego_vy * t, np.full_like(t, ego_vy)], axis=1)
    axs = np.full_like(t, ax)
    yfs = np.full_like(t, -5.625)
    params = SafeParams()
    others = [Obstacle(f"v{i}", (x0, v, acc / 2, 0.0), y, length, 1.8, vy)
              for i, (x0, v, acc, y, vy, length) in enumerate(vehicles)]
    ok, culprit = feasible_brakes(t, X, axs, others, (4.8, 1.8), params, yfs)
    alone = [feasible_brakes(t, X, axs, [o], (4.8, 1.8), params, yfs) for o in others]
    expect = np.logical_and.reduce([a[0] for a in alone])
    assert np.array_equal(ok, expect)
    for k in range(t.size):
        first = next((o.name for o, a in zip(others, alone) if not a[0][k].any()), "")
        assert culprit[k] == first
    # one vehicle: the pair alone, the lateral and longitudinal RSS tests of the module docstring
    for ok1, _ in alone:
        assert ok1.shape == (t.size, len(params.brakes))
        assert (ok1.all(axis=1) | ~ok1.any(axis=1)).all()  # without a lane end every b or none


@settings(max_examples=300, deadline=None)
@given(v_r=st.floats(-5, 45), v_f=st.floats(-5, 45), rho=st.sampled_from([0.2, 0.5, 1.0, 0.37]), a_acc=st.floats(-8, 4),
       b_min=st.floats(0.5, 8), b_max=st.floats(0.5, 9))
def test_rss_distance_of_floats_is_its_array_expression_bit_for_bit(v_r, v_f, rho, a_acc, b_min, b_max):
    """The scalar path of :func:`rss_distance` gives the bytes of the array expression on 0-d arrays."""
    from iamp.simulation.rss import rss_distance

    fast = rss_distance(v_r, v_f, rho, a_acc, b_min, b_max)
    arrays = rss_distance(*(np.asarray(z) for z in (v_r, v_f, rho, a_acc, b_min, b_max)))
    assert fast.shape == arrays.shape == ()
    assert fast.tobytes() == arrays.tobytes()
    vr = max(v_r, 0.0)
    expect = (vr * rho + 0.5 * a_acc * rho**2 + max(vr + rho * a_acc, 0.0) ** 2 / (2 * b_min)
              - max(v_f, 0.0) ** 2 / (2 * b_max))
    assert float(fast) == pytest.approx(max(expect, 0.0), rel=1e-12, abs=1e-9)


@settings(max_examples=200, deadline=None)
@given(ys=st.lists(st.floats(-20.0, 5.0), min_size=1, max_size=50), lanes=st.integers(1, 5),
       width=st.sampled_from([3.0, 3.2, 3.5, 3.75]))
def test_lane_centres_of_is_lane_centre_of_lane_of_bit_for_bit(ys, lanes, width):
    """The vectorised lane indices and centres (the verification's fail-safe lane per sample) equal the scalar ones,
    boundaries included (a multiple of the lane width and its neighbouring floats)."""
    from iamp.simulation.network import Highway

    hw = Highway(lanes=lanes, lane_width=width)
    edges = [-k * width for k in range(lanes + 2)]
    y = np.array(ys + edges + [float(np.nextafter(e, 1.0)) for e in edges] + [-0.0])
    got = hw.lane_centres_of(y)
    expect = np.array([hw.lane_centre(hw.lane_of(float(v))) for v in y])
    assert got.tobytes() == expect.tobytes()
    lanes_of = hw.lanes_of(y)  # the observation's lane column (Simulator.observe)
    assert lanes_of.dtype == np.array([1]).dtype and lanes_of.tolist() == [hw.lane_of(float(v)) for v in y]
    assert np.all(np.abs(got - np.clip(y, -lanes * width + width / 2, -width / 2)) <= width / 2 + 1e-12)


def test_monitor_with_the_shared_geometry_equals_the_monitor_without_it():
    """run_episode computes the oriented separations once (metrics.episode_geometry) for the metrics and
    the monitor; both give what they give when they compute them themselves."""
    from iamp.simulation.metrics import StepLog, episode_geometry, episode_metrics
    from iamp.simulation.monitor import monitor

    dt = 0.1
    log = StepLog()
    for k in range(60):
        t = k * dt
        log.t.append(t)
        log.ego.append((20.0 * t, 20.0, -5.625 + min(t, 3.0) * 1.25, 1.25 if t < 3 else 0.0, 0.0, 0.0))
        log.ids.append(("a", "b"))
        log.nb.append(np.array([[20.0 * t + 8.0 - 0.5 * t, -1.875, 19.5, 0.0, 1, 4.6, 1.8, 0.0],
                                [20.0 * t - 9.0 + 0.8 * t, -1.875, 20.8, 0.0, 1, 4.6, 1.8, 0.02]]))
        log.mode.append("active")
        log.plan_time.append(float("nan"))
        log.ego_heading.append(0.06 if t < 3 else 0.0)

    def lane(y: float) -> int:
        return 0 if y < -3.75 else 1

    geo = episode_geometry(log, (4.8, 1.8))
    assert len(geo) == 60 and all(sep.shape == (2,) for _, sep in geo)
    shared = episode_metrics(log, dt, (4.8, 1.8), (3.5, 1.2), [], geo)
    assert shared == episode_metrics(log, dt, (4.8, 1.8), (3.5, 1.2), [])
    with_geo = monitor(log, dt, (4.8, 1.8), lane, 1, 30.0, None, [], geometry=geo)
    assert with_geo == monitor(log, dt, (4.8, 1.8), lane, 1, 30.0, None, [])
    assert min(float(sep.min()) for _, sep in geo) < 0.0 and with_geo["contacts"] == 1  # the follower is touched


@settings(max_examples=200, deadline=None)
@given(v_r=st.one_of(st.floats(-5, 45), st.integers(0, 40), st.sampled_from([0.0, -0.0])),
       v_f=st.one_of(st.floats(-5, 45), st.integers(0, 40)), brake_min=st.sampled_from([4.0, 4, 3.3]))
def test_safe_longitudinal_float_is_the_float_of_the_array_function(v_r, v_f, brake_min):
    from iamp.simulation.rss import RssParameters, safe_longitudinal_distance, safe_longitudinal_float

    p = RssParameters(brake_min=brake_min)
    got = safe_longitudinal_float(v_r, v_f, p)
    assert isinstance(got, float)
    assert np.float64(got).tobytes() == np.float64(float(safe_longitudinal_distance(v_r, v_f, p))).tobytes()


@settings(max_examples=300, deadline=None)
@given(speeds=st.lists(st.one_of(st.floats(-40, 40), st.sampled_from([0.0, -0.0, 5e-324])), min_size=0, max_size=2),
       ego_v=st.floats(0, 40))
def test_gap_speed_is_numpy_mean_bit_for_bit(speeds, ego_v):
    """The gap's speed (the tactical layer's aim and end speeds) is np.mean of the predicted speeds, signed
    zeros included (numpy's sum starts at +0)."""
    from iamp.simulation.decision import EgoNow, Gap, Neighbour
    from iamp.simulation.tactical import gap_speed

    cars = [Neighbour(f"v{i}", (10.0 * i, v, 0.0, 0.0), -1.875, 4.6, 1.8, 1) for i, v in enumerate(speeds)]
    gap = Gap(cars[0] if cars else None, cars[1] if len(cars) > 1 else None)
    ego = EgoNow(0.0, ego_v, -5.625, 0.0, 4.8, 1.8)
    got = gap_speed(ego, gap, 0.0)
    expect = float(np.mean([n.v(0.0) for n in cars])) if cars else ego_v
    assert np.float64(got).tobytes() == np.float64(expect).tobytes()


@settings(max_examples=40, deadline=None)
@given(entries=st.lists(st.tuples(st.integers(0, 3), st.integers(0, 40), finite), min_size=1, max_size=60))
def test_histories_of_is_history_of_each_and_shares_equal_times(entries):
    """Simulator.histories_of gives every vehicle's history as Simulator.history does; vehicles observed at the
    same steps share one (read-only) time array."""
    from iamp.simulation.simulator import Simulator

    sim = Simulator("medium", 1)
    seen: dict[str, int] = {}
    for step, (vid, start, x) in enumerate(entries):
        name = f"v{vid}"
        seen.setdefault(name, start)
        sim.t = round(0.1 * (step + 1), 10)
        for other, first in seen.items():  # every vehicle seen so far is observed at this step
            if step >= first % 5:
                sim.histories.setdefault(other, TrackBuffer()).record(sim.t, x + len(other), sim.t - 3.0)
    ids = [*sorted(seen), "absent"]
    got = sim.histories_of(ids)
    for vid, (t, x) in zip(ids, got):
        t_ref, x_ref = sim.history(vid)
        assert t.tobytes() == t_ref.tobytes() and x.tobytes() == x_ref.tobytes()
    for (t1, _), (t2, _) in zip(got, got[1:]):
        if t1.size and t1.tobytes() == t2.tobytes():
            assert t1 is t2 and not t1.flags.writeable


@settings(max_examples=40, deadline=None)
@given(data=st.data(), n=st.integers(0, 12), pool=st.integers(1, 6), headed=st.booleans())
def test_tracks_of_puts_each_logged_row_where_a_step_by_step_copy_does(data, n, pool, headed):
    """The monitor's tracks (one scatter of every logged row) equal each step's rows copied one vehicle at a
    time; unobserved (step, vehicle) cells stay nan; no heading column gives heading 0."""
    from iamp.simulation.metrics import StepLog
    from iamp.simulation.monitor import tracks_of

    names = [f"v{i}" for i in range(pool)]
    log = StepLog()
    for k in range(n):
        ids = tuple(data.draw(st.lists(st.sampled_from(names), unique=True, max_size=pool)))
        log.t.append(0.1 * k)
        log.ids.append(ids)
        cols = 8 if headed else 7
        log.nb.append(np.array(data.draw(st.lists(st.lists(finite, min_size=cols, max_size=cols),
                                                  min_size=len(ids), max_size=len(ids))), dtype=float)
                      .reshape(len(ids), cols))
    tr = tracks_of(log)
    seen = list(dict.fromkeys(v for ids in log.ids for v in ids))
    assert list(tr.ids) == seen
    names7 = ("x", "y", "v", "a", "lane", "L", "W")
    for q in names7 + ("psi",):
        assert getattr(tr, q).shape == (n, len(seen))
    for k, (ids, nb) in enumerate(zip(log.ids, log.nb)):
        for j, vid in enumerate(seen):
            if vid in ids:
                row = nb[ids.index(vid)]
                for c, q in enumerate(names7):
                    assert getattr(tr, q)[k, j] == row[c]
                assert tr.psi[k, j] == (row[7] if headed else 0.0)
            else:
                assert all(np.isnan(getattr(tr, q)[k, j]) for q in names7 + ("psi",))
