"""The bounded one-vehicle certificate's curvature term (issue 32): the time within ``[0, t']``
where the fixed-multiplier law ``u = clip(w)`` is free, bounded for every ``t'`` of an interval
by :func:`iamp.planners.pmp.bounded._free_measure` (it was ``t' ≤ b``: a smaller ``M`` certifies
larger intervals, 132 -> 116 axis solves on the bench's paper-1 problem).  Checked against a
dense count of the free set of ``w(τ; t') = w_a + w_b τ + s Φ (t' - t)`` (``τ < min(t, t')``,
either sign ``s``) plus the stretch between ``t`` and ``t'``."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from iamp.planners.pmp.bounded import _free_measure

finite = st.floats(-20.0, 20.0, allow_nan=False)


@settings(max_examples=200, deadline=None)
@given(wa=finite, wb=finite, lo=st.floats(-8.0, -0.1), hi=st.floats(0.1, 8.0), t=st.floats(0.1, 9.0),
       delta=st.floats(1e-6, 0.5), phi=st.floats(0.0, 30.0))
def test_the_free_measure_bounds_the_free_time_at_every_contact_time_of_the_interval(
        wa: float, wb: float, lo: float, hi: float, t: float, delta: float, phi: float) -> None:
    b = t + delta
    bound = _free_measure(wa, wb, lo, hi, t, delta, phi, b)
    assert bound <= b
    for tp in np.linspace(t - delta, t + delta, 7):
        if tp <= 0:
            continue
        tau = np.linspace(0.0, tp, 4001)
        dt = tp / 4000
        before = tau < min(t, tp)
        for sign in (-1.0, 1.0):
            w = wa + wb * tau + sign * phi * (tp - t)
            free = before & (w > lo) & (w < hi)
            measured = np.count_nonzero(free) * dt + max(0.0, tp - t)
            assert measured <= bound + 2 * dt, (tp, sign, measured, bound)


def test_an_unbounded_axis_or_a_flat_law_is_free_throughout() -> None:
    assert _free_measure(1.0, 0.5, -np.inf, np.inf, 2.0, 0.1, 3.0, 2.1) == 2.1
    assert _free_measure(0.0, 0.0, -1.0, 1.0, 2.0, 0.1, 3.0, 2.1) == 2.1  # 2 + δ, widened, capped at b
    assert _free_measure(5.0, 0.0, -1.0, 1.0, 2.0, 0.1, 3.0, 2.1) == min(2.1, 0.1 + 1e-9 * 2.1)
