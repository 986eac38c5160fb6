"""The expected state value by one reduction from ``-0.0`` (:func:`iamp.prediction.mtd.chain.expected_value`,
issue 32: the closed loop's prediction cost) is the former loop's number, bit for bit.

The former loop over the states (one product added at a time) is kept here as the oracle, compared over
generated distributions and values with signed zeros, NaN, infinities, subnormals and batches of one row
(where numpy would otherwise sum along the row, pairwise), with ``tobytes()``.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from iamp.prediction.mtd.chain import expected_value
from iamp.prediction.predictor import Predictor


def _expected_former(probs: np.ndarray, values: np.ndarray) -> np.ndarray:
    """``expected_value`` before the reduction (verbatim)."""
    acc = probs[..., 0] * values[0]
    for k in range(1, probs.shape[-1]):
        acc = acc + probs[..., k] * values[k]
    return acc


FLOATS = st.one_of(st.floats(allow_nan=True, allow_infinity=True, width=64),
                   st.sampled_from([0.0, -0.0, 5e-324, -5e-324, 1.0, -1.0]), st.floats(-3.0, 3.0))


@settings(max_examples=300, deadline=None)
@given(data=st.data(), lead=hnp.array_shapes(min_dims=1, max_dims=3, min_side=0, max_side=5),
       m=st.integers(1, 16))
@pytest.mark.filterwarnings("ignore::RuntimeWarning")
def test_the_reduction_is_the_former_loop_bit_for_bit(data: st.DataObject, lead: tuple[int, ...], m: int) -> None:
    probs = data.draw(hnp.arrays(np.float64, lead + (m,), elements=FLOATS))
    values = data.draw(hnp.arrays(np.float64, (m,), elements=FLOATS))
    if data.draw(st.booleans()):  # a strided view, as the propagation's rows may be
        probs = np.concatenate([probs, probs], axis=-1)[..., ::2]
    got, want = expected_value(probs, values), _expected_former(probs, values)
    assert got.shape == want.shape and got.tobytes() == want.tobytes()


def test_one_distribution_gives_the_former_scalar() -> None:
    """A single distribution (no batch axis): the same number (NaN as NaN: numpy's scalar arithmetic, which
    the former loop ran on, picks a NaN operand by the compiler's order)."""
    rng = np.random.default_rng(5)
    for m in (1, 2, 7, 13, 16):
        p, v = rng.random(m), rng.normal(size=m)
        got, want = expected_value(p, v), _expected_former(p, v)
        assert type(got) is type(want) and got.tobytes() == want.tobytes()


def test_the_shipped_models_node_means_over_the_closed_loops_horizons() -> None:
    model = Predictor.default().model
    S = np.random.default_rng(2).integers(0, model.n_states, (40, model.order))
    for steps in (1, 36, 76):
        probs = model.propagate_batch(S, steps)
        for rows in (probs, probs[:1], probs[:, :1]):
            assert expected_value(rows, model.centres).tobytes() == _expected_former(rows, model.centres).tobytes()
