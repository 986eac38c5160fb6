"""The node means' row keys sliced from the batch's bytes and the rows joined by one ``concatenate``
(:meth:`iamp.prediction.predictor.Predictor._node_means`, issue 32: the closed loop's prediction cost) give
the former numbers, bit for bit, and the former store.

The former method (a ``tobytes()`` per row, ``np.stack``) is kept here as the oracle; both run on their own
predictor of the same model over generated sequences of batches (repeated pasts within and across batches,
two horizons, a store small enough to be emptied), compared with ``tobytes()``.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from iamp.prediction import predictor as pred
from iamp.prediction.mtd import MTDModel
from iamp.prediction.predictor import Predictor


def _node_means_former(p: Predictor, states: np.ndarray, M: int) -> np.ndarray:
    """``Predictor._node_means`` before the sliced keys (verbatim)."""
    S = np.ascontiguousarray(np.atleast_2d(states), dtype=np.int64)
    kept = p._abar_rows.setdefault(M, {})
    keys = [row.tobytes() for row in S]
    new = [k for k in dict.fromkeys(keys) if k not in kept]
    if new:
        if sum(len(d) for d in p._abar_rows.values()) + len(new) > pred.ABAR_CACHE_ROWS:
            for d in p._abar_rows.values():
                d.clear()
        batch = np.frombuffer(b"".join(new), dtype=np.int64)
        _, abar = p._node_accelerations(batch.reshape(-1, S.shape[1]), M)
        for k, row in zip(new, abar):
            row.setflags(write=False)
            kept[k] = row
    out: np.ndarray = np.stack([kept[k] for k in keys])
    return out


def _twin_predictors() -> tuple[Predictor, Predictor]:
    base = Predictor.default().model
    models = [MTDModel(Q=base.Q, lam=base.lam, edges=base.edges, centres=base.centres, dt=base.dt) for _ in range(2)]
    return Predictor(models[0], "former"), Predictor(models[1], "new")


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), calls=st.integers(1, 6), store=st.sampled_from([3, 10, pred.ABAR_CACHE_ROWS]))
def test_batches_give_the_former_rows_and_store(seed: int, calls: int, store: int) -> None:
    rng = np.random.default_rng(seed)
    former, new = _twin_predictors()
    m = former.model.n_states
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(pred, "ABAR_CACHE_ROWS", store)
        for _ in range(calls):
            B = int(rng.integers(1, 12))
            S = rng.integers(0, int(rng.integers(1, m + 1)), (B, former.model.order + int(rng.integers(0, 2))))
            M = int(rng.choice([3, 7]))
            want = _node_means_former(former, S, M)
            got = new._node_means(S, M)
            assert got.shape == want.shape and got.tobytes() == want.tobytes()
            stores = [{k: sorted(d) for k, d in p._abar_rows.items()} for p in (new, former)]
            assert stores[0] == stores[1]


def test_no_rows_is_numpys_error_as_before() -> None:
    former, new = _twin_predictors()
    S = np.zeros((0, former.model.order), dtype=np.int64)
    with pytest.raises(ValueError) as a:
        _node_means_former(former, S, 5)
    with pytest.raises(ValueError) as b:
        new._node_means(S, 5)
    assert str(a.value) == str(b.value)
