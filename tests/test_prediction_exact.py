"""The predictor's faster paths compute the same numbers, bit for bit, as the code they replace
(issue 32 item 5: the closed loop's prediction cost).

The formulations replaced are kept here, verbatim, as the references: the chain propagated lag by lag
(``propagate_batch``), the clamped integration as a loop over the nodes in numpy (``_foh_nodes``) and
the query evaluation of ``integrate_nodes``.  Each is compared with the package's code over generated
models, accelerations and histories (hypothesis), with ``tobytes()``: the same IEEE numbers, signed
zeros included.
"""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from iamp.prediction.initial_state import noise_sigma, smooth_histories
from iamp.prediction.kinematics import integrate_nodes, integrate_positions
from iamp.prediction.mtd import MTDModel
from iamp.prediction.predictor import Predictor


def _propagate_batch_reference(model: MTDModel, init_states: np.ndarray, steps: int) -> np.ndarray:
    """The chain propagated step by step, every entry accumulated lag by lag and state by state,
    ``((W_1[j,0] x_{t-1}[0] + W_1[j,1] x_{t-1}[1]) + …) + W_n[j,m-1] x_{t-n}[m-1]`` (the summation order
    the package fixes so that no number depends on BLAS), one column of products at a time."""
    S = np.asarray(init_states, dtype=np.int64)
    B = S.shape[0]
    n, m = model.order, model.n_states
    W = model.Q * model.lam[:, None, None]
    hist = [np.eye(m)[S[:, -1 - i]] for i in range(n)]
    out = np.empty((B, int(steps), m))
    for s in range(int(steps)):
        x = hist[0][:, 0:1] * W[0][None, :, 0]
        for i in range(n):
            for k in range(1 if i == 0 else 0, m):
                x = x + hist[i][:, k:k + 1] * W[i][None, :, k]
        out[:, s] = x
        hist = [x] + hist[:-1]
    return out


def _expected_reference(probs: np.ndarray, values: np.ndarray) -> np.ndarray:
    acc = probs[..., 0] * values[0]
    for k in range(1, probs.shape[-1]):
        acc = acc + probs[..., k] * values[k]
    return acc


def _foh_nodes_reference(x0: np.ndarray, v0: np.ndarray, abar: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    B, M1 = abar.shape
    M = M1 - 1
    a0, a1 = abar[:, :-1], abar[:, 1:]
    dv = dt * 0.5 * (a0 + a1)
    vs = np.empty((B, M + 1))
    vs[:, 0] = v0
    np.cumsum(dv, axis=1, out=vs[:, 1:])
    vs[:, 1:] += v0[:, None]
    xs = np.empty((B, M + 1))
    if np.all(vs >= 0.0):
        xs[:, 0] = x0
        np.cumsum(vs[:, :-1] * dt + dt * dt * (a0 / 3.0 + a1 / 6.0), axis=1, out=xs[:, 1:])
        xs[:, 1:] += x0[:, None]
        return xs, vs
    xs[:, 0], vs[:, 0] = x0, v0
    for k in range(M):
        v, x = vs[:, k], xs[:, k]
        v_new = v + dv[:, k]
        x_new = x + v * dt + dt * dt * (a0[:, k] / 3.0 + a1[:, k] / 6.0)
        stop = v_new < 0.0
        if np.any(stop):
            am = np.minimum(0.5 * (a0[:, k] + a1[:, k]), -1e-12)
            x_new = np.where(stop, x + v * v / (2.0 * -am), x_new)
            v_new = np.where(stop, 0.0, v_new)
        xs[:, k + 1], vs[:, k + 1] = x_new, v_new
    return xs, vs


def _integrate_nodes_reference(x0, v0, abar, dt, query):  # type: ignore[no-untyped-def]
    abar = np.atleast_2d(np.asarray(abar, dtype=float))
    B = abar.shape[0]
    x_start = np.broadcast_to(np.asarray(x0, dtype=float), (B,)).copy()
    v_start = np.maximum(np.broadcast_to(np.asarray(v0, dtype=float), (B,)), 0.0)
    xs, vs = _foh_nodes_reference(x_start, v_start, abar, dt)
    M = abar.shape[1] - 1
    q = np.asarray(query, dtype=float)
    k = np.clip(np.floor(q / dt + 1e-9).astype(int), 0, M - 1)
    s = (q - k * dt)[None, :]
    ak, d = abar[:, k], (abar[:, k + 1] - abar[:, k])
    xk, vk = xs[:, k], vs[:, k]
    x = xk + vk * s + 0.5 * ak * s * s + d * s ** 3 / (6.0 * dt)
    v = vk + ak * s + d * s * s / (2.0 * dt)
    stopped = vs[:, k + 1] == 0.0
    if np.any(stopped):
        x = np.where(stopped, np.minimum(x, xs[:, k + 1]), x)
        x = np.where(stopped & (v < 0), xs[:, k + 1], x)
        v = np.where(stopped, np.maximum(v, 0.0), v)
    return x, np.maximum(v, 0.0)


def _predict_batch_reference(P: Predictor, t_hist, X_hist, query, tf, cubic):  # type: ignore[no-untyped-def]
    """``Predictor.predict_batch`` as it was, on the references above (its initial state is shared)."""
    M, t = P._horizon(tf)
    x0, v0, states = P.initial_state(np.asarray(t_hist, dtype=float), np.atleast_2d(X_hist))
    abar = _expected_reference(_propagate_batch_reference(P.model, states, M + 1), P.centres)
    q = np.asarray(query, dtype=float)
    if not cubic:
        return _integrate_nodes_reference(x0, v0, abar, P.dt, q)[0]
    x, _ = _integrate_nodes_reference(x0, v0, abar, P.dt, t)
    V = np.vander(np.array(t), 4, increasing=True)
    C, *_ = np.linalg.lstsq(V, x.T, rcond=None)
    return np.polynomial.polynomial.polyval(q, C)


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


@st.composite
def _models(draw: st.DrawFn) -> MTDModel:
    n = draw(st.integers(1, 5))
    m = draw(st.integers(2, 14))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    Q = rng.random((n, m, m)) ** draw(st.sampled_from([1.0, 4.0, 12.0]))  # from flat to nearly one-hot columns
    Q /= Q.sum(axis=1, keepdims=True)
    lam = rng.random(n) + 1e-3
    return MTDModel(Q=Q, lam=lam / lam.sum())


@settings(max_examples=150, deadline=None)
@given(model=_models(), B=st.integers(0, 40), extra=st.integers(0, 3), steps=st.integers(0, 45),
       seed=st.integers(0, 2**32 - 1))
def test_propagate_batch_is_the_lag_by_lag_formula_bit_for_bit(model, B, extra, steps, seed):
    """The products summed by one reduction are the entry-by-entry accumulation, per bit."""
    S = np.random.default_rng(seed).integers(0, model.n_states, (B, model.order + extra))
    new = model.propagate_batch(S, steps)
    assert new.flags.c_contiguous
    assert _same(new, _propagate_batch_reference(model, S, steps))


def test_propagate_batch_of_the_shipped_model_over_many_pasts():
    """Every one of 3000 pasts of the shipped model, in batches of 1 to 64."""
    model = Predictor.default().model
    rng = np.random.default_rng(7)
    for B in (1, 2, 3, 5, 8, 13, 18, 31, 64):
        S = rng.integers(0, model.n_states, (B, model.order))
        for steps in (1, 26, 36, 51):
            assert _same(model.propagate_batch(S, steps), _propagate_batch_reference(model, S, steps))


_accel = st.floats(-9.0, 4.0, allow_nan=False)


@settings(max_examples=200, deadline=None)
@given(B=st.integers(1, 12), M=st.integers(1, 40), dt=st.sampled_from([0.05, 0.1, 0.2, 0.25]),
       seed=st.integers(0, 2**32 - 1), stopping=st.floats(0.0, 1.0), scale=st.sampled_from([0.3, 1.0, 3.0]),
       cubic_times=st.booleans())
def test_integration_is_the_node_loop_bit_for_bit(B, M, dt, seed, stopping, scale, cubic_times):
    """Rows that stop and rows that do not, in one batch: the accumulated sums of the rows that never stop
    and the scalar recursion of the rows that do are the node loop's numbers, per bit."""
    rng = np.random.default_rng(seed)
    abar = scale * rng.normal(0.0, 2.0, (B, M + 1)) - 3.0 * stopping * (rng.random((B, 1)) < stopping)
    abar[rng.random(abar.shape) < 0.1] = 0.0
    x0 = rng.normal(0.0, 50.0, B)
    v0 = np.where(rng.random(B) < 0.2, 0.0, rng.uniform(-1.0, 30.0, B) * rng.random(B))
    if cubic_times:
        q = dt * np.arange(M + 1)
        q[-1] = M * dt * (1 - 1e-12)
    else:
        q = np.sort(rng.uniform(0.0, M * dt, 17))
    x_ref, v_ref = _integrate_nodes_reference(x0, v0, abar, dt, q)
    x, v = integrate_nodes(x0, v0, abar, dt, q)
    assert _same(x, x_ref) and _same(v, v_ref)
    assert _same(integrate_positions(x0, v0, abar, dt, q), x_ref)
    xs_ref, vs_ref = _foh_nodes_reference(x0.copy(), np.maximum(v0, 0.0), abar, dt)
    from iamp.prediction.kinematics import _foh_nodes

    xs, vs = _foh_nodes(x0.copy(), np.maximum(v0, 0.0), abar, dt)
    assert _same(xs, xs_ref) and _same(vs, vs_ref)


def test_integration_with_one_row_stopping_among_many():
    """The mixed case on purpose: one row brakes to a stop, the others cruise (the others are summed
    step by step then, not by the cumulative sums of a batch where nobody stops)."""
    dt, M = 0.2, 35
    abar = np.zeros((4, M + 1))
    abar[0] = -6.0
    abar[1] = 0.37
    abar[2, 10:] = -1.3
    x0 = np.array([0.0, 10.3, -7.1, 100.0])
    v0 = np.array([3.0, 25.1, 12.9, 31.3])
    q = dt * np.arange(M + 1)
    x_ref, v_ref = _integrate_nodes_reference(x0, v0, abar, dt, q)
    x, v = integrate_nodes(x0, v0, abar, dt, q)
    assert v_ref[0, -1] == 0.0 and np.all(v_ref[1:, -1] > 0)
    assert _same(x, x_ref) and _same(v, v_ref)
    # and the batch really is summed differently from the cumulative sums (what the test guards)
    x_alone, _ = _integrate_nodes_reference(x0[1:], v0[1:], abar[1:], dt, q)
    assert not _same(x_alone, x_ref[1:])


_T_HIST = np.round(np.arange(-30, 1) * 0.1, 9)


@settings(max_examples=40, deadline=None)
@given(B=st.integers(1, 25), K=st.integers(11, 31), tf=st.sampled_from([0.7, 3.0, 5.0, 7.0, 8.35]),
       seed=st.integers(0, 2**32 - 1), cubic=st.booleans(), noise=st.sampled_from([0.0, 0.003, 0.05]))
def test_predict_batch_is_the_previous_pipeline_bit_for_bit(B, K, tf, seed, cubic, noise):
    """Histories of cruising, braking (to a stop) and accelerating vehicles: the positions (or the cubic's
    values at the loop's Chebyshev points) are the previous pipeline's, per bit."""
    P = Predictor.default()
    rng = np.random.default_rng(seed)
    t = _T_HIST[-K:]
    v = rng.uniform(0.0, 33.0, (B, 1))
    a = rng.choice([-7.0, -3.0, 0.0, 0.5, 2.0], (B, 1)) * rng.random((B, 1))
    X = rng.normal(0.0, 100.0, (B, 1)) + v * t + 0.5 * a * t * t + noise * rng.standard_normal((B, K))
    k = np.arange(4)
    q = tf / 2 * (1 - np.cos((2 * k + 1) * np.pi / 8)) if cubic else np.linspace(0.0, tf, 11)
    new = P.predict_batch(t, X, q, tf, cubic=cubic)
    assert _same(new, _predict_batch_reference(P, t, X, q, tf, cubic))


@settings(max_examples=60, deadline=None)
@given(B=st.integers(1, 30), K=st.integers(4, 31), seed=st.integers(0, 2**32 - 1),
       noise=st.sampled_from([0.0, 1e-4, 0.003, 0.05]), nan_row=st.booleans())
def test_smoother_noise_levels_are_each_rounded_to_two_digits(B, K, seed, noise, nan_row):
    """The noise levels (rounded once per distinct value) are each history's level rounded to two
    significant digits, repeated levels and NaN histories included."""
    rng = np.random.default_rng(seed)
    t = _T_HIST[-K:]
    X = rng.uniform(0.0, 30.0, (B, 1)) * t + noise * rng.standard_normal((B, K))
    X[rng.random(B) < 0.3] = X[0]
    if nan_row:
        X[-1, K // 2] = np.nan
    ref = [float(f"{s:.2g}") for s in noise_sigma(t, X)]
    assert smooth_histories(t, X).sigma.tobytes() == np.asarray(ref).tobytes()
