"""The predictor keeps the node accelerations of each distinct past (issue 32 item 5) and gives the
same numbers as propagating every batch afresh.

:meth:`iamp.prediction.predictor.Predictor._node_means` propagates a past (its ``n`` integer
states) once and reuses the row.  That is exact because the chain's propagation adds each entry's
products one after another without BLAS: a row's numbers do not depend on the other rows, their
number or its place among them, nor on the machine (checked here against plain Python floats,
whose additions in the same order give the same bits by IEEE 754).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import iamp.prediction.predictor as predictor_module
from iamp.prediction.mtd import MTDModel
from iamp.prediction.predictor import Predictor

MODEL = Predictor.default().model
N_STATES, ORDER = MODEL.n_states, MODEL.order


def _fresh() -> Predictor:
    """A predictor whose model keeps no rows yet (the rows are kept with the model)."""
    return Predictor(MTDModel.from_dict(MODEL.to_dict()), "fresh")


pasts = st.lists(st.lists(st.integers(0, N_STATES - 1), min_size=ORDER, max_size=ORDER), min_size=1, max_size=40)


@settings(max_examples=60, deadline=None)
@given(first=pasts, second=pasts, M=st.sampled_from([1, 2, 13, 25, 40, 41]))
def test_kept_rows_are_a_fresh_propagation_bit_for_bit(first: list[list[int]], second: list[list[int]], M: int
                                                       ) -> None:
    p = _fresh()
    for batch in (first, second, first + second, second[:1]):
        S = np.array(batch, dtype=np.int64)
        kept = p._node_means(S, M)
        fresh = _fresh()._node_accelerations(S, M)[1]
        assert kept.shape == fresh.shape == (len(batch), M + 1)
        assert kept.tobytes() == fresh.tobytes()


@settings(max_examples=40, deadline=None)
@given(rows=pasts.filter(lambda r: len(r) >= 2), data=st.data())
def test_a_rows_numbers_do_not_depend_on_the_other_rows_of_a_batch(rows: list[list[int]], data: st.DataObject) -> None:
    """The premise: in a batch of two or more, each row of the propagation is its own."""
    S = np.array(rows, dtype=np.int64)
    M = data.draw(st.sampled_from([1, 25, 40]))
    full = _fresh()._node_accelerations(S, M)[1]
    pick = data.draw(st.lists(st.integers(0, len(rows) - 1), min_size=2, max_size=len(rows) + 3))
    other = _fresh()._node_accelerations(S[pick], M)[1]
    assert other.tobytes() == full[pick].tobytes()


def test_the_store_is_bounded_and_recomputes_the_same(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(predictor_module, "ABAR_CACHE_ROWS", 5)
    rng = np.random.default_rng(0)
    p = _fresh()
    for _ in range(20):
        S = rng.integers(0, N_STATES, (int(rng.integers(2, 5)), ORDER))
        assert p._node_means(S, 25).tobytes() == _fresh()._node_accelerations(S, 25)[1].tobytes()
        assert sum(len(d) for d in p._abar_rows.values()) <= 5


def test_predict_batch_of_a_predictor_with_kept_rows_is_a_fresh_ones() -> None:
    rng = np.random.default_rng(1)
    t = np.round(np.arange(-30, 1) * 0.1, 9)
    p = _fresh()
    for k in range(6):  # the loop's pattern: the same vehicles a period later, mostly the same bins
        X = 300.0 + k * 2.5 + 25.0 * t + rng.normal(0, 0.02, (9, t.size))
        q = np.array([0.1, 2.0, 5.5, 8.0])
        for cubic in (False, True):
            assert p.predict_batch(t, X, q, 8.0, cubic=cubic).tobytes() == \
                _fresh().predict_batch(t, X, q, 8.0, cubic=cubic).tobytes()
    assert sum(len(d) for d in p._abar_rows.values()) > 0
    assert Predictor(p.model, "another")._abar_rows is p._abar_rows  # one store per model
    Predictor(p.model, "another").forget_kept_rows()
    assert sum(len(d) for d in p._abar_rows.values()) == 0


def _python_propagation(S: list[int], steps: int) -> list[list[float]]:
    """The MTD propagation of one past in plain Python floats: every entry ``Σ_i Σ_k W_i[j,k]·x_{t-i}[k]``
    summed lag by lag, state by state (an independent reference: no numpy arithmetic)."""
    m, n = N_STATES, ORDER
    W = [[[float(MODEL.lam[i]) * float(MODEL.Q[i][j][k]) for k in range(m)] for j in range(m)] for i in range(n)]
    hist = [[1.0 if k == s else 0.0 for k in range(m)] for s in S[::-1][:n]]  # newest first
    out = []
    for _ in range(steps):
        x = []
        for j in range(m):
            acc = 0.0
            for i in range(n):
                for k in range(m):
                    acc += W[i][j][k] * hist[i][k]
            x.append(acc)
        out.append(x)
        hist = [x] + hist[:-1]
    return out


@settings(max_examples=25, deadline=None)
@given(rows=pasts, M=st.sampled_from([1, 3, 12]))
def test_every_entry_is_the_plain_python_sum_bit_for_bit(rows: list[list[int]], M: int) -> None:
    """Each row of a batch, and its expected acceleration, equal plain Python's sums in the same order:
    the numbers cannot depend on the batch, on BLAS or on the CPU."""
    probs, abar = _fresh()._node_accelerations(np.array(rows, dtype=np.int64), M)
    c = [float(v) for v in MODEL.centres]
    for b, past in enumerate(rows[:4]):
        ref = _python_propagation(past, M + 1)
        assert probs[b].tolist() == ref
        means = []
        for x in ref:
            acc = x[0] * c[0]
            for k in range(1, N_STATES):
                acc = acc + x[k] * c[k]
            means.append(acc)
        assert abar[b].tolist() == means


def test_propagate_of_one_past_is_the_batchs_row() -> None:
    S = np.array([[6, 6, 6, 6], [6, 7, 6, 5], [3, 9, 12, 0]], dtype=np.int64)
    batch = MODEL.propagate_batch(S, 30)
    for b in range(3):
        assert MODEL.propagate(S[b], 30).tobytes() == batch[b].tobytes()
    assert np.allclose(batch.sum(axis=2), 1.0, atol=1e-12)  # distributions stay distributions


def test_propagate_reads_the_last_n_states_of_a_longer_past_or_its_distributions() -> None:
    rng = np.random.default_rng(3)
    for T in (ORDER, ORDER + 1, ORDER + 5):
        past = rng.integers(0, N_STATES, T)
        want = MODEL.propagate(past[-ORDER:], 12)
        assert MODEL.propagate(past, 12).tobytes() == want.tobytes()
        assert MODEL.propagate(np.eye(N_STATES)[past], 12).tobytes() == want.tobytes()
        assert MODEL.propagate_batch(past[None, :], 12)[0].tobytes() == want.tobytes()
    for bad in ([0] * (ORDER - 1), [N_STATES] + [0] * (ORDER - 1), [-1] + [0] * (ORDER - 1)):
        with pytest.raises(ValueError):
            MODEL.propagate(bad, 3)
    with pytest.raises(ValueError):
        MODEL.propagate(np.eye(N_STATES)[: ORDER - 1], 3)  # fewer distributions than the order
    with pytest.raises(ValueError):
        MODEL.propagate(np.ones((ORDER, N_STATES + 1)) / (N_STATES + 1), 3)  # the wrong number of states
