"""The closed loop's speed levers change no number (issue 20 item 5).

(The PMP screen — a compiled twin of the PMP whose plans were kept when the decision layer would
reject them on the limits — was removed in issue 32: every planner now plans with the limits.)

* the kkt family's costs and states (:func:`iamp.planners.qp.core.family_unpacked`) equal the
  one-by-one ones bit for bit;
* :func:`iamp.core.limits.polynomial_message` with its memory answers as without it;
* :func:`iamp.core.polyroots.pad_coeffs` is ``np.pad``.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st


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
