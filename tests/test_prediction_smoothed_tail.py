"""The smoother's dense product over the operator's tail (:func:`iamp.prediction.initial_state._smooth`,
issue 32: the closed loop's prediction cost) and the predictor's initial state computed from the last samples
alone give the same numbers, bit for bit, as the code they replaced.

The former ``smooth_histories`` body (``einsum("bj,cjk->cbk")`` over the whole operator) and the former
``Predictor.initial_state`` are kept here as the oracles.  They are compared over generated sample times,
histories (signed zeros, NaN and infinities among the positions), noise levels (estimated, given, several
groups) and tails, with ``tobytes()``.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from iamp.prediction import initial_state as I
from iamp.prediction.kinematics import second_differences
from iamp.prediction.predictor import Predictor, _grid_weights


def _smooth_former(t: np.ndarray, Z: np.ndarray, jerk_psd: float, sigma: object = None) -> I.SmoothedHistory:
    """``smooth_histories`` before the tail (verbatim, the operator's path)."""
    t = np.asarray(t, dtype=float)
    Z = np.atleast_2d(np.asarray(Z, dtype=float))
    B, K = Z.shape
    if sigma is None:
        raw = I.noise_sigma(t, Z).tolist()
        rounded = {s: float(f"{s:.2g}") for s in set(raw)}
        sig = np.asarray([rounded[s] for s in raw])
    else:
        sig = np.broadcast_to(np.asarray(sigma, dtype=float), (B,)).copy()
    out = np.empty((3, B, K))
    key = t.tobytes()
    if np.isnan(sig).any():
        levels, inverse = np.unique(sig, return_inverse=True)
        groups = [(float(level), inverse == j) for j, level in enumerate(levels)]
    else:
        groups = [(level, sig == level) for level in sorted(set(sig.tolist()))]
    for level, rows in groups:
        M = I._operator(key, K, float(level), float(jerk_psd))
        out[:, rows] = np.einsum("bj,cjk->cbk", Z[rows], M)
    return I.SmoothedHistory(out[0], out[1], out[2], sig)


def _initial_state_former(p: Predictor, t_hist: np.ndarray, X_hist: np.ndarray) -> tuple[np.ndarray, ...]:
    """``Predictor.initial_state`` before the tail (verbatim, with the former smoother)."""
    sm = _smooth_former(t_hist, X_hist, p.jerk_psd)
    idx, nxt, w, w1 = _grid_weights(t_hist.tobytes(), t_hist.size, p.dt, p.model.order)
    resampled = sm.x[:, idx] * w1 + sm.x[:, nxt] * w
    states = p.model.states(second_differences(resampled, p.dt))
    return sm.x[:, -1], np.maximum(sm.v[:, -1], 0.0), states


SPECIAL = st.sampled_from([0.0, -0.0, np.nan, np.inf, -np.inf, 1e300, -1e-300])


@st.composite
def _histories(draw: st.DrawFn, k_min: int = 3) -> tuple[np.ndarray, np.ndarray]:
    K = draw(st.integers(k_min, 40))
    B = draw(st.integers(0, 9))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    steps = draw(st.sampled_from(["even", "jitter", "ragged"]))
    h = np.full(K - 1, 0.1) if steps == "even" else 0.1 + (0.02 if steps == "jitter" else 0.3) * rng.random(K - 1)
    t = np.concatenate([-np.cumsum(h[::-1])[::-1], [0.0]])
    v = rng.uniform(0.0, 35.0, (B, 1))
    Z = 500.0 + v * t + rng.normal(0.0, draw(st.sampled_from([0.0, 0.003, 0.05, 0.4])), (B, K))
    if B and draw(st.booleans()):  # a few special values (they take their rows' noise levels with them)
        for _ in range(draw(st.integers(1, 3))):
            Z[rng.integers(B), rng.integers(K)] = draw(SPECIAL)
    return t, Z


@settings(max_examples=120, deadline=None)
@given(hist=_histories(), q=st.sampled_from([1.0, 10.0, 30.0]), data=st.data())
@pytest.mark.filterwarnings("ignore::RuntimeWarning")
def test_smoothing_and_its_tails_are_the_former_numbers(hist: tuple[np.ndarray, np.ndarray], q: float,
                                                        data: st.DataObject) -> None:
    t, Z = hist
    B, K = Z.shape
    sigma = data.draw(st.one_of(st.none(), st.sampled_from([0.001, 0.05]),
                                st.lists(st.sampled_from([0.001, 0.002, 0.05]), min_size=B, max_size=B)))
    want = _smooth_former(t, Z, q, sigma)
    got = I.smooth_histories(t, Z, q, sigma)
    for a, b in ((got.x, want.x), (got.v, want.v), (got.a, want.a), (got.sigma, want.sigma)):
        assert a.shape == b.shape and a.tobytes() == b.tobytes()
    first = data.draw(st.integers(0, K - 1))
    tail = I._smooth(t, Z, q, sigma, first)
    for a, b in ((tail.x, want.x), (tail.v, want.v), (tail.a, want.a)):
        assert a.shape == (B, K - first) and a.tobytes() == np.ascontiguousarray(b[:, first:]).tobytes()


@settings(max_examples=120, deadline=None)
@given(hist=_histories(k_min=12))
@pytest.mark.filterwarnings("ignore::RuntimeWarning")
def test_the_predictors_initial_state_is_the_former_one(hist: tuple[np.ndarray, np.ndarray]) -> None:
    t, Z = hist
    p = Predictor.default()
    if t[-1] - t[0] + 1e-9 < p.min_history_s:
        t = t * (p.min_history_s / (t[-1] - t[0])) * 1.01
    got, want = p.initial_state(t, Z), _initial_state_former(p, t, Z)
    for a, b in zip(got, want):
        assert a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


def test_long_histories_take_the_recursions_tail(monkeypatch: pytest.MonkeyPatch) -> None:
    """Past :data:`~iamp.prediction.initial_state.OPERATOR_MAX_K` the tail is the recursions' columns."""
    rng = np.random.default_rng(3)
    t = np.linspace(-6.0, 0.0, 61)
    Z = 100.0 + 20.0 * t + rng.normal(0.0, 0.02, (4, 61))
    full = I.smooth_histories(t, Z)
    monkeypatch.setattr(I, "OPERATOR_MAX_K", 20)
    rec = I.smooth_histories(t, Z)
    tail = I._smooth(t, Z, I.DEFAULT_JERK_PSD, None, 50)
    assert np.allclose(rec.x, full.x, atol=1e-9)
    for a, b in ((tail.x, rec.x), (tail.v, rec.v), (tail.a, rec.a)):
        assert a.tobytes() == np.ascontiguousarray(b[:, 50:]).tobytes()


@settings(max_examples=80, deadline=None)
@given(hist=_histories(), layout=st.sampled_from(["C", "F", "strided", "reversed"]),
       sigma=st.sampled_from([None, 0.001, 0.02]))
@pytest.mark.filterwarnings("ignore::RuntimeWarning")
def test_one_noise_level_takes_every_row_whatever_the_layout(hist: tuple[np.ndarray, np.ndarray], layout: str,
                                                            sigma: float | None) -> None:
    """One noise level (every row selected without a mask): the rows of any memory layout give the numbers
    of the former mask's contiguous copy."""
    t, Z = hist
    if layout == "F":
        Zl = np.asfortranarray(Z)
    elif layout == "strided":
        Zl = np.repeat(Z, 2, axis=1)[:, ::2]
    elif layout == "reversed":
        Zl = Z[::-1, ::-1].copy()[::-1, ::-1]
    else:
        Zl = Z
    assert np.array_equal(Zl, Z, equal_nan=True)
    want = _smooth_former(t, Z, 10.0, sigma)
    got = I.smooth_histories(t, Zl, 10.0, sigma)
    for a, b in ((got.x, want.x), (got.v, want.v), (got.a, want.a)):
        assert a.tobytes() == b.tobytes()
