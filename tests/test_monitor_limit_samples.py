"""The monitor counts the executed steps that break a physical limit in one pass
(:func:`iamp.simulation.decision.limit_violation_samples`) instead of calling
:func:`~iamp.simulation.decision.limit_violations_of` on each one-sample slice: the same steps, bit for
bit the same comparisons, checked against the former loop and the former ``limit_violations_of``
(kept here as the oracles) over accelerations and speeds with ``nan``, infinities, signed zeros and
values at the bounds' tolerance, and limits with and without each bound."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from iamp.core.physical import PASSENGER_CAR, PhysicalLimits
from iamp.simulation.decision import limit_violation_samples, limit_violations_of


def _old_limit_violations_of(ax, ay, vx, limits, tol=1e-6):
    bad = []
    for name, values in (("ax", ax), ("ay", ay), ("vx", vx)):
        rng = getattr(limits, name)
        if rng is not None and values.size and (values.min() < rng[0] - tol or values.max() > rng[1] + tol):
            bad.append(name)
    if limits.a_total is not None and ax.size and float(np.max(np.hypot(ax, ay))) > limits.a_total + tol:
        bad.append("a_total")
    return bad


def _old_count(ax, ay, vx, limits):
    viol = 0
    if ax.size:
        for k in range(ax.size):
            viol += bool(_old_limit_violations_of(ax[k:k + 1], ay[k:k + 1], vx[k:k + 1], limits))
    return viol


EDGES = [-6.0 - 1e-6, float(np.nextafter(-6.0 - 1e-6, 0.0)), 3.0 + 1e-6, float(np.nextafter(3.0 + 1e-6, 9.0)),
         2.0 + 1e-6, -2.0 - 1e-6, 40.0 + 1e-6, 0.0, -0.0, math.nan, math.inf, -math.inf, 8.0 + 1e-6]
value = st.one_of(st.floats(-12.0, 45.0), st.sampled_from(EDGES))
limits = st.one_of(st.just(PASSENGER_CAR), st.builds(
    PhysicalLimits, ax=st.none() | st.just((-6.0, 3.0)), ay=st.none() | st.just((-2.0, 2.0)),
    a_total=st.none() | st.sampled_from([8.0, 3.0]), vx=st.none() | st.just((0.0, 40.0))))


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
@settings(max_examples=250, deadline=None)
@given(rows=st.lists(st.tuples(value, value, value), min_size=0, max_size=30), lim=limits)
def test_the_steps_that_break_a_limit_are_the_former_loops(rows, lim):
    A = np.array(rows, dtype=float).reshape(-1, 3)
    ax, ay, vx = A[:, 0].copy(), A[:, 1].copy(), A[:, 2].copy()
    per = limit_violation_samples(ax, ay, vx, lim)
    assert per.shape == ax.shape and per.dtype == bool
    assert per.tolist() == [bool(_old_limit_violations_of(ax[k:k + 1], ay[k:k + 1], vx[k:k + 1], lim))
                            for k in range(ax.size)]
    assert int(np.count_nonzero(per)) == _old_count(ax, ay, vx, lim)
    # and the whole-array question is unchanged (nan in a quantity hides its other samples, as before)
    assert limit_violations_of(ax, ay, vx, lim) == _old_limit_violations_of(ax, ay, vx, lim)
