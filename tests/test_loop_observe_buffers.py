"""The observation's bookkeeping without numpy scalars (:class:`iamp.simulation.simulator.TrackBuffer`
keeps its newest time as a Python float and reads the oldest with ``item``; :meth:`Simulator.observe`
reads its rows into one array with ``np.fromiter``): the same kept samples and the same columns, bit
for bit, as the former code (kept here as the oracles) — repeated and out-of-order times, samples
of one time observed twice, compaction and growth of the buffers, empty observations."""

from __future__ import annotations

import itertools
import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from iamp.simulation.simulator import TrackBuffer


class _OldTrackBuffer:
    """The former buffer: every comparison reads the numpy arrays."""

    def __init__(self, capacity: int = 64) -> None:
        self.t = np.empty(capacity)
        self.x = np.empty(capacity)
        self.lo = 0
        self.hi = 0

    def record(self, t: float, x: float, oldest: float) -> None:
        lo, hi, tt = self.lo, self.hi, self.t
        if hi > lo and tt[hi - 1] >= t - 1e-9:
            hi -= 1
        if hi == tt.size:
            n = hi - lo
            if 2 * n > tt.size:
                self.t = np.concatenate([tt, np.empty(tt.size)])
                self.x = np.concatenate([self.x, np.empty(self.x.size)])
            self.t[:n] = tt[lo:hi].copy()
            self.x[:n] = self.x[lo:hi].copy()
            lo, hi, tt = 0, n, self.t
        tt[hi] = t
        self.x[hi] = x
        hi += 1
        while hi > lo and tt[lo] < oldest:
            lo += 1
        self.lo, self.hi = lo, hi


finite = st.floats(-1e3, 1e3, allow_nan=False, allow_infinity=False)
step = st.one_of(st.sampled_from([0.0, 1e-10, 0.1, 0.1, 0.1, 0.25, -0.05, 1.0]), st.floats(-0.2, 1.0))


@settings(max_examples=150, deadline=None)
@given(steps=st.lists(st.tuples(step, finite, st.sampled_from([0.35, 1.0, 3.0, math.inf])), min_size=1, max_size=120),
       capacity=st.sampled_from([1, 2, 4, 64]), start=st.sampled_from([0.0, -0.0, 12.3, 1e6]))
def test_track_buffer_keeps_the_former_samples(steps, capacity, start):
    new, old = TrackBuffer(capacity=capacity), _OldTrackBuffer(capacity=capacity)
    t = start
    for dt, x, horizon in steps:
        t += dt
        new.record(t, x, t - horizon)
        old.record(t, x, t - horizon)
        assert (new.lo, new.hi) == (old.lo, old.hi)
        assert new.t[new.lo:new.hi].tobytes() == old.t[old.lo:old.hi].tobytes()
        assert new.x[new.lo:new.hi].tobytes() == old.x[old.lo:old.hi].tobytes()
        assert new.t.size == old.t.size
        assert np.float64(new.last).tobytes() == new.t[new.hi - 1].tobytes()


value = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.sampled_from([0.0, -0.0, 5e-324]),
                  st.integers(-10**6, 10**6))


@settings(max_examples=200, deadline=None)
@given(rows=st.lists(st.tuples(*[value] * 7), min_size=0, max_size=40))
def test_observation_columns_are_the_former_array(rows):
    """``np.fromiter`` of the rows' values in order, reshaped, gives the columns ``np.array(rows)`` gave."""
    old = np.array(rows, dtype=np.float64).reshape(len(rows), 7).T.copy()
    new = np.fromiter(itertools.chain.from_iterable(rows), dtype=np.float64,
                      count=7 * len(rows)).reshape(len(rows), 7).T.copy()
    assert new.shape == old.shape and new.dtype == old.dtype and new.flags.c_contiguous == old.flags.c_contiguous
    assert new.tobytes() == old.tobytes()
