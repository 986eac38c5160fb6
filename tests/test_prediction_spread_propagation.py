"""The chain's propagation over spread distributions (:func:`iamp.prediction.mtd.chain._propagate`, issue 32:
the closed loop's prediction cost) computes the same numbers, bit for bit, as the formulation it replaced.

The former code, a broadcast product of the lag window with ``W`` per step, is kept here verbatim as the
oracle.  Both are compared over generated models, pasts (one-hot states, and distributions with signed
zeros, NaN and infinities through :func:`~iamp.prediction.mtd.chain.propagate`) and buffer sizes small
enough to force the row chunks and the buffer's wrap-around, with ``tobytes()``.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from iamp.prediction.mtd import MTDModel, chain
from iamp.prediction.predictor import Predictor


def _propagate_former(model: MTDModel, past: np.ndarray, steps: int) -> np.ndarray:
    """The propagation before the spread buffer (the code it replaced, verbatim)."""
    n, B, m = past.shape
    W = chain._lag_operators(model)
    L = n + steps
    Z = np.empty((L, B, m))
    Z[L - n:] = past
    P = np.empty((n, m, B, m))
    Wk = W.transpose(0, 2, 1)[:, :, None, :]
    flat = P.reshape(n * m, B, m)
    for s in range(steps):
        a = L - n - s
        np.multiply(Z[a:a + n].transpose(0, 2, 1)[:, :, :, None], Wk, out=P)
        np.add.reduce(flat, axis=0, out=Z[a - 1])
    out: np.ndarray = np.ascontiguousarray(Z[:L - n][::-1].transpose(1, 0, 2))
    return out


@st.composite
def _models(draw: st.DrawFn) -> MTDModel:
    n = draw(st.integers(1, 5))
    m = draw(st.integers(2, 14))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    Q = rng.random((n, m, m)) ** draw(st.sampled_from([1.0, 4.0, 12.0]))
    zero = rng.random((n, m, m)) < draw(st.sampled_from([0.0, 0.3]))  # exact zeros (ties of products)
    zero[:, np.arange(m), np.arange(m)] = False  # every column keeps some mass
    Q[zero] = 0.0
    Q /= Q.sum(axis=1, keepdims=True)
    lam = rng.random(n) + 1e-3
    return MTDModel(Q=Q, lam=lam / lam.sum())


SPREADS = st.sampled_from([chain.SPREAD_BYTES, 1, 3000, 20000, 200000])


@settings(max_examples=120, deadline=None)
@given(model=_models(), B=st.integers(0, 30), extra=st.integers(0, 3), steps=st.integers(0, 40),
       seed=st.integers(0, 2**32 - 1), spread=SPREADS)
def test_one_hot_pasts_propagate_as_before_bit_for_bit(model: MTDModel, B: int, extra: int, steps: int, seed: int,
                                                       spread: int) -> None:
    S = np.random.default_rng(seed).integers(0, model.n_states, (B, model.order + extra))
    past = np.eye(model.n_states)[S[:, :-model.order - 1:-1].T]  # (n, B, m), newest first
    want = _propagate_former(model, past, steps)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(chain, "SPREAD_BYTES", spread)
        got = model.propagate_batch(S, steps)
    assert got.shape == (B, steps, model.n_states) and got.flags.c_contiguous
    assert got.tobytes() == want.tobytes()


SPECIAL = st.sampled_from([0.0, -0.0, 1.0, 0.5, 1e-300, -1e-300, 5e-324, 1e300, np.inf, -np.inf, np.nan])


@settings(max_examples=120, deadline=None)
@given(model=_models(), data=st.data(), steps=st.integers(0, 30), spread=SPREADS)
@pytest.mark.filterwarnings("ignore::RuntimeWarning")
def test_distributions_with_signed_zeros_nan_and_inf_propagate_as_before(model: MTDModel, data: st.DataObject,
                                                                         steps: int, spread: int) -> None:
    n, m = model.order, model.n_states
    T = data.draw(st.integers(n, n + 2))
    values = data.draw(st.lists(st.one_of(SPECIAL, st.floats(-2.0, 2.0)), min_size=T * m, max_size=T * m))
    D = np.array(values, dtype=float).reshape(T, m)
    want = _propagate_former(model, D[-1:-n - 1:-1][:, None, :], steps)[0]
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(chain, "SPREAD_BYTES", spread)
        got = chain.propagate(model, D, steps)
    assert got.tobytes() == want.tobytes()


def test_the_shipped_model_over_the_closed_loops_horizons() -> None:
    """The shipped model (order 4, 13 states) over 36 and 76 nodes (7 s and 15 s at 0.2 s), batches of 1 to 64
    and a batch past the row chunk."""
    model = Predictor.default().model
    rng = np.random.default_rng(11)
    for B in (1, 2, 3, 17, 25, 64, 400):
        S = rng.integers(0, model.n_states, (B, model.order))
        past = np.eye(model.n_states)[S[:, ::-1].T]
        for steps in (1, 36, 76):
            assert model.propagate_batch(S, steps).tobytes() == _propagate_former(model, past, steps).tobytes()
