"""The closed loop's speed levers change no number (issue 20 item 5).

* the PMP screen (:func:`iamp.simulation.planning.screened`): its test
  (:func:`~iamp.simulation.decision.clearly_beyond_limits`) is sufficient for the decision
  layer's limit test on any trajectory close enough to the screened one; episodes with the
  screen on and off are identical;
* the kkt family's costs and states (:func:`iamp.planners.qp.core.family_unpacked`) equal the
  one-by-one ones bit for bit;
* :func:`iamp.core.limits.polynomial_message` with its memory answers as without it;
* :func:`iamp.core.polyroots.pad_coeffs` is ``np.pad``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from test_bench_logic import fake  # noqa: F401  (its fixture: run_bench with every measurement faked)

from iamp.core.physical import PASSENGER_CAR
from iamp.simulation.decision import check_times, clearly_beyond_limits, limit_violations

TOL = 1e-6  # limit_violations' tolerance


class Poly:
    """A trajectory whose input is a polynomial per axis on ``[0, t_j)`` and another on
    ``[t_j, tf]`` (an input jump at ``t_j``, like a PMP plan at a contact time)."""

    def __init__(self, x0: float, vx0: float, ua: np.ndarray, ub: np.ndarray, tj: float) -> None:
        self.x0, self.vx0, self.ua, self.ub, self.tj = x0, vx0, ua, ub, tj

    def inputs(self, t: np.ndarray) -> np.ndarray:
        t = np.asarray(t, float)
        P = np.polynomial.polynomial.polyval
        out = np.empty((t.size, 2))
        for ax in range(2):
            out[:, ax] = np.where(t < self.tj, P(t, self.ua[ax]), P(t, self.ub[ax]))
        return out

    def states(self, t: np.ndarray) -> np.ndarray:
        # only v_x is judged: v_x(t) = vx0 + ∫ u_x (exactly, piecewise)
        t = np.asarray(t, float)
        I = np.polynomial.polynomial.polyint
        P = np.polynomial.polynomial.polyval
        ia, ib = I(self.ua[0]), I(self.ub[0])
        va = self.vx0 + P(t, ia)
        vb = self.vx0 + P(self.tj, ia) + P(t, ib) - P(self.tj, ib)
        vx = np.where(t < self.tj, va, vb)
        X = np.zeros((t.size, 4))
        X[:, 1] = vx
        return X


coef = st.floats(-1.0, 1.0)
polys = st.lists(coef, min_size=3, max_size=3)


@settings(max_examples=150, deadline=None)
@given(ua=st.tuples(polys, polys), ub=st.tuples(polys, polys), tj=st.floats(0.3, 4.7), vx0=st.floats(5.0, 35.0),
       tf=st.floats(1.0, 5.0), shift=st.floats(-1.0, 1.0), eps=st.tuples(polys, polys), margin=st.sampled_from(
           [1e-3, 1e-2, 0.3]))
def test_the_screen_is_sufficient_for_the_limit_test_of_any_close_trajectory(ua, ub, tj, vx0, tf, shift, eps, margin):
    """If the screen finds a bound broken by more than ``margin`` (away from the jump), every
    trajectory whose inputs and v_x differ by less than ``margin/√2 - tol`` at those samples,
    and whose jump lies within ``away_s`` of this one, breaks a bound in ``limit_violations``."""
    tj = min(tj, tf * 0.9)
    a = Poly(0.0, vx0, np.array(ua), np.array(ub), tj)
    # a second trajectory: a polynomial perturbation of size < margin/(√2·2) - tol per axis
    # (inputs and v_x), its jump moved by less than away_s = 1e-6
    e = np.array(eps)
    T = max(tf, 1.0)
    allowance = margin / math.sqrt(2) - TOL
    de = e * allowance / 4 / ((np.abs(e).sum(axis=1, keepdims=True) + 1e-12) * T**2 * (1 + T))
    # |Σ de_k t^k| ≤ Σ|de_k| T² ≤ allowance/4 on [0, tf], and its integral ≤ allowance/4 too
    b = Poly(0.0, vx0, np.array(ua) + de, np.array(ub) + de, tj + shift * 0.9e-6)
    ts = check_times(tf, 0.01)
    keep = np.abs(ts - tj) > 1e-6
    da = np.abs(a.inputs(ts[keep]) - b.inputs(ts[keep])).max(initial=0.0)
    dv = np.abs(a.states(ts[keep])[:, 1] - b.states(ts[keep])[:, 1]).max(initial=0.0)
    assume(max(da, dv) < allowance)  # (the jump's shift adds ≤ |Δu|·1e-6 to v_x: rarely too much)
    screened = clearly_beyond_limits(a, tf, PASSENGER_CAR, 0.01, margin, [tj])
    if screened:
        assert limit_violations(b, tf, PASSENGER_CAR, 0.01)
    # and the screen never claims more than the limit test of the same trajectory
    assert set(screened) <= set(limit_violations(a, tf, PASSENGER_CAR, 0.01))


def test_the_screen_ignores_samples_at_a_jump():
    """An input beyond a bound only at the sample of its jump is not screened (the exact
    plan's jump may sit on the other side of that sample)."""
    tf = 2.0
    tj = 1.0  # a sample of check_times(2, 0.01)
    a = Poly(0.0, 20.0, np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]), np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]),
             tj)
    a.inputs = lambda t: np.where(np.abs(np.asarray(t)[:, None] - tj) < 1e-12, 9.0, 0.0) * np.array([1.0, 0.0])
    assert limit_violations(a, tf, PASSENGER_CAR, 0.01)
    assert clearly_beyond_limits(a, tf, PASSENGER_CAR, 0.01, 1e-3, [tj]) == []
    assert clearly_beyond_limits(a, tf, PASSENGER_CAR, 0.01, 1e-3) != []


# -- the screen around real planners -------------------------------------------------------------------
def test_screened_returns_the_exact_plan_unless_the_fast_one_is_clearly_rejected():
    from iamp.core.physical import PhysicalLimits
    from iamp.planners.examples import random_problem
    from iamp.planners.pmp.planner import PMPPlanner
    from iamp.simulation.planning import Screen, screened

    exact_pl = PMPPlanner(max_boxes=2000, compiled=False, diagnostics=False)
    calls = {"exact": 0, "fast": 0}

    def exact(p):
        calls["exact"] += 1
        return exact_pl.plan(p)

    def fast(p):  # a stand-in "fast twin": the same planner (so the screen's premise holds exactly)
        calls["fast"] += 1
        return exact_pl.plan(p)

    tight = Screen(PhysicalLimits(ax=(-0.01, 0.01), ay=(-0.01, 0.01), a_total=0.02, vx=(0.0, 100.0)), 0.01)
    loose = Screen(PhysicalLimits(ax=(-1e3, 1e3), ay=(-1e3, 1e3), a_total=2e3, vx=(-1e3, 1e3)), 0.01)
    p = random_problem(3, m=2)
    ref = exact_pl.plan(p)
    assert ref.status in ("optimal", "local")
    got = screened(exact, lambda: fast, tight)(p)
    assert got.info.get("screened") and calls == {"exact": 0, "fast": 1}
    assert limit_violations(ref.require_trajectory(), float(p.tf), tight.limits, 0.01)
    got = screened(exact, lambda: fast, loose)(p)
    assert not got.info.get("screened") and calls == {"exact": 1, "fast": 2}
    assert np.array_equal(got.contact_times, ref.contact_times) and got.cost == ref.cost
    # one vehicle is never screened; no fast planner (numba missing): always exact
    one = random_problem(3, m=1)
    screened(exact, lambda: fast, tight)(one)
    assert calls == {"exact": 2, "fast": 2}
    screened(exact, lambda: None, tight)(p)
    assert calls == {"exact": 3, "fast": 2}

    def broken(p):
        raise ZeroDivisionError

    got = screened(exact, lambda: broken, tight)(p)
    assert calls == {"exact": 4, "fast": 2} and np.array_equal(got.contact_times, ref.contact_times)


def _episode(planner, screen, mission="merge", traffic="medium", seed=1, duration=10.0):
    pytest.importorskip("libsumo")
    from iamp.simulation.controller import ControllerConfig
    from iamp.simulation.episode import EpisodeSpec, run_episode

    return run_episode(EpisodeSpec(traffic=traffic, seed=seed, planner=planner, mission=mission, duration_s=duration),
                       config=ControllerConfig(screen=screen))


def _numbers(s):
    return {k: v for k, v in s.items() if k not in ("plan_time_s", "wall_s", "max_rss_mb")}


def _log(r):
    L = r.log
    return (L.t, L.ego, L.mode, L.ids, [np.asarray(a).tolist() for a in L.nb])


def test_a_pmp_merge_is_the_same_with_the_screen_on_and_off(monkeypatch):
    """10 s of the seed-1 medium merge with ``pmp``: the episode (summary minus times, step log)
    with the screen on must be the one without it.
    The PMP's search has one implementation since issue 32 (its numba copy, the screen's fast
    twin, was removed), so the screen has no fast planner and is never consulted."""
    from iamp.simulation import planning

    hits = []
    real = planning.clearly_beyond_limits

    def counting(*a, **k):
        out = real(*a, **k)
        hits.append(bool(out))
        return out

    monkeypatch.setattr(planning, "clearly_beyond_limits", counting)
    on = _episode("pmp", True)
    n = len(hits)
    assert n == 0  # no fast twin: every plan is the exact one
    off = _episode("pmp", False)
    assert len(hits) == n  # with it off the screen is not consulted
    assert _numbers(on.summary) == _numbers(off.summary)
    assert _log(on) == _log(off)


def test_loop_pmps_are_pinned_to_the_pure_search():
    """Once the screen has loaded the compiled search in a process, a PMP with the default
    ``compiled=None`` would switch to it; the loop's pmp and pmp-active must not."""
    from iamp.simulation.planning import SIM_OPTIONS

    assert SIM_OPTIONS["pmp"]["compiled"] is False and SIM_OPTIONS["pmp-active"]["compiled"] is False


# -- the QP family -----------------------------------------------------------------------------------
@pytest.mark.parametrize("hold", ["foh", "zoh"])
@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), m=st.integers(1, 2), scale=st.floats(1e-3, 1e3))
def test_family_costs_and_states_equal_the_one_by_one_ones_bit_for_bit(hold, seed, m, scale):
    from iamp.planners.examples import random_problem
    from iamp.planners.qp.core import DiscretisedQP, family_unpacked
    from iamp.planners.qp.hold import HoldTrajectory

    qp = DiscretisedQP(random_problem(seed % 50, m=m), steps=12, hold=hold, solver="kkt")
    d = qp.data
    rng = np.random.default_rng(seed)
    Z = rng.normal(size=(37, d.n)) * scale
    Y = rng.normal(size=(37, d.n_rows))
    X, U, costs, nu = family_unpacked(d, Z, hold, Y)
    for j in range(Z.shape[0]):
        X1, U1 = d.unpack(Z[j])
        assert np.array_equal(X[j], X1) and np.array_equal(U[j], U1)
        assert costs[j] == HoldTrajectory(d.t_nodes.copy(), X1, U1, hold).cost()
        assert np.array_equal(nu[j], d.collision_multipliers(Y[j]))


def test_family_nodes_are_checked_like_one_by_one():
    from iamp.planners.examples import random_problem
    from iamp.planners.qp.core import DiscretisedQP, _checked_nodes

    d = DiscretisedQP(random_problem(1, m=2), steps=12, hold="foh", solver="kkt").data
    good = [(1, 2), (np.int64(11), 3), [4, 5], (1.5, 2)]
    assert _checked_nodes(d, good) == [d.check_nodes(c) for c in good] == [(1, 2), (11, 3), (4, 5), (1, 2)]
    assert all(type(k) is int for c in _checked_nodes(d, good) for k in c)
    for bad in ([(0, 2)], [(1, 12)], [(1, 2, 3)], [(1, 2), (3, 0)]):
        with pytest.raises(ValueError) as e1:
            [d.check_nodes(c) for c in bad]
        with pytest.raises(ValueError) as e2:
            _checked_nodes(d, bad)
        assert str(e1.value) == str(e2.value)


# -- polynomial_message and pad_coeffs ---------------------------------------------------------------
@settings(max_examples=200, deadline=None)
@given(c=st.lists(st.floats(-1e6, 1e6) | st.sampled_from([0.0, -0.0, 1e300]), min_size=1, max_size=6),
       tf=st.floats(0.01, 60.0))
def test_polynomial_message_with_its_memory_answers_as_without(c, tf):
    from iamp.core import limits

    want = limits._polynomial_message(np.asarray(c, dtype=float), tf)
    assert limits.polynomial_message(c, tf) == want
    assert limits.polynomial_message(tuple(c), tf) == want  # asked again: from the memory


def test_polynomial_message_memory_follows_the_bounds(monkeypatch):
    from iamp.core import limits

    c = (0.0, 50.0)  # 50 m/s
    assert limits.polynomial_message(c, 5.0) is None
    monkeypatch.setitem(limits.LIMITS, "speed_max_mps", 40.0)
    msg = limits.polynomial_message(c, 5.0)
    assert msg is not None and "40" in msg


@settings(max_examples=100, deadline=None)
@given(rows=st.integers(1, 5), cols=st.integers(1, 6), extra=st.integers(0, 4), order=st.sampled_from("CFS"))
def test_pad_coeffs_is_np_pad(rows, cols, extra, order):
    from iamp.core.polyroots import pad_coeffs

    base = np.random.default_rng(rows * 10 + cols).normal(size=(rows, 2, cols))
    A = base[:, 0, :] if order == "S" else np.asarray(base[:, 0, :], order=order)
    got, want = pad_coeffs(A, cols + extra), np.pad(A, ((0, 0), (0, extra)))
    assert got.dtype == want.dtype and np.array_equal(got, want)
    assert got.flags.c_contiguous == want.flags.c_contiguous and got.flags.f_contiguous == want.flags.f_contiguous


# -- iamp bench's closed-loop entry --------------------------------------------------------------------
def test_bench_loop_entry_is_skipped_with_quick_and_reports_a_differing_episode(monkeypatch):
    from iamp.comparison.bench import loop as bench_loop_mod
    from iamp.comparison.bench import run as bench

    notes: list[str] = []
    assert bench._loop(True, notes) is None and "skipped with --quick" in notes[0]
    pytest.importorskip("libsumo")
    stub = {"episode_s": {"pmp_screen": 1.0, "pmp_pure": 4.0}, "loop_pmp_screen_to_pure": 0.25,
            "same_numbers": False}
    monkeypatch.setattr(bench_loop_mod, "bench_loop", lambda repeats: stub)
    notes = []
    assert bench._loop(False, notes) is stub
    assert any("differs" in n for n in notes)
    stub["same_numbers"] = True
    notes = []
    bench._loop(False, notes)
    assert notes == []



@pytest.mark.usefixtures("fake")
def test_bench_text_shows_the_loop_block(monkeypatch):
    """``format_bench`` prints the closed-loop block from ``run_bench``'s ``loop`` object."""
    from iamp.comparison.bench import run as bench
    from iamp.comparison.bench.text import format_bench

    loop = {"case": {"duration_s": 10.0, "mission": "merge", "traffic": "medium", "seed": 1},
            "episode_s": {"pmp_screen": 0.5, "pmp_pure": 5.0}, "loop_pmp_screen_to_pure": 0.1, "same_numbers": True}
    monkeypatch.setattr(bench, "_loop", lambda quick, notes: loop)
    out = bench.run_bench(quick=True)
    assert out["loop_episode_s"] == loop["episode_s"] and out["ratios"]["loop_pmp_screen_to_pure"] == 0.1
    text = format_bench(out)
    assert "Closed loop, whole 10 s merge episodes (medium, seed 1)" in text
    assert "pmp screened / pure: 0.100; same numbers: yes" in text
