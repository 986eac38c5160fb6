"""The closed loop's per-step bookkeeping, made cheaper, computes the same numbers (issue 32 item 5).

* :meth:`iamp.simulation.simulator.Simulator.observe` builds its columns from one list of rows:
  each column equals the per-vehicle formula (front bumper to centre along SUMO's heading, the
  lane of the centre), is a contiguous float array, and the histories record every observed
  vehicle and forget the ones that left the radius — checked against a stub of ``libsumo``;
* a neighbour's speed cubic is derived once per neighbour: a neighbour with another cubic
  (``dataclasses.replace``) has the speed of that cubic, never a kept one.
"""

from __future__ import annotations

import dataclasses
import math
from types import SimpleNamespace
from typing import Any

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from iamp.simulation.decision import Neighbour
from iamp.simulation.network import Highway
from iamp.simulation.simulator import EGO, Simulator

P = np.polynomial.polynomial
POS, SPEED, ACC, ANGLE = 0x42, 0x40, 0x72, 0x43


class _StubSumo:
    """The few ``libsumo`` calls :meth:`Simulator.observe` makes, over a fixed context result."""

    VAR_POSITION, VAR_SPEED, VAR_ACCELERATION, VAR_ANGLE = POS, SPEED, ACC, ANGLE

    def __init__(self, res: dict[str, dict[int, Any]], sizes: dict[str, tuple[float, float]]) -> None:
        self.res = res
        self.vehicle = SimpleNamespace(getContextSubscriptionResults=lambda vid: self.res,
                                       getLength=lambda vid: sizes[vid][0], getWidth=lambda vid: sizes[vid][1])


def _reference(hw: Highway, res: dict[str, dict[int, Any]], sizes: dict[str, tuple[float, float]]
               ) -> dict[str, tuple[float, ...]]:
    """The observation of each vehicle as the per-vehicle loop before the change computed it."""
    out = {}
    for vid in sorted(k for k in res if k != EGO):
        r = res[vid]
        length, width = sizes[vid]
        psi = math.radians(90.0 - float(r[ANGLE]))
        fx, fy = r[POS]
        x = fx - length / 2 * math.cos(psi)
        y = fy - length / 2 * math.sin(psi)
        out[vid] = (x, y, r[SPEED], r[ACC], float(hw.lane_of(float(y))), length, width, psi)
    return out


vehicle = st.tuples(st.floats(-50.0, 900.0), st.floats(-12.0, 0.0), st.floats(0.0, 40.0), st.floats(-6.0, 3.0),
                    st.floats(80.0, 100.0))
#: A vehicle's body (SUMO's does not change; the simulator asks once per vehicle).
SIZES = {f"v{k}": [(4.5, 1.8), (12.0, 2.5), (4.8, 1.8)][k % 3] for k in range(12)}


@settings(max_examples=60, deadline=None)
@given(first=st.dictionaries(st.sampled_from([f"v{k}" for k in range(12)]), vehicle, max_size=10),
       second=st.dictionaries(st.sampled_from([f"v{k}" for k in range(12)]), vehicle, max_size=10))
def test_observe_columns_are_the_per_vehicle_formula(first: dict[str, Any], second: dict[str, Any]) -> None:
    hw = Highway()
    sizes = {**SIZES, EGO: (4.8, 1.8)}
    sim = Simulator("dense", 1, highway=hw)
    for step, vehicles in enumerate((first, second)):
        res: dict[str, dict[int, Any]] = {EGO: {POS: (0.0, -5.0), SPEED: 20.0, ACC: 0.0, ANGLE: 90.0}}
        for vid, (fx, fy, v, a, ang) in vehicles.items():
            res[vid] = {POS: (fx, fy), SPEED: v, ACC: a, ANGLE: ang}
        sim._ls = _StubSumo(res, sizes)
        sim.t = 1.0 + 0.1 * step
        obs = sim.observe()
        ref = _reference(hw, res, sizes)
        assert obs.ids == tuple(ref)
        cols = (obs.x, obs.y, obs.v, obs.a, obs.lane, obs.length, obs.width, obs.heading)
        for j, col in enumerate(cols):
            assert col is not None and col.shape == (len(ref),) and col.flags.c_contiguous
            assert col.dtype == (np.dtype(int) if j == 4 else np.float64)
            assert [float(c).hex() for c in col] == [float(r[j]).hex() for r in ref.values()]
        # the histories: every vehicle observed now, none that left; its last sample is this one
        assert set(sim.histories) == set(ref)
        for k, vid in enumerate(obs.ids):
            h = sim.histories[vid]
            assert h.t[h.hi - 1] == sim.t and h.x[h.hi - 1] == obs.x[k]
            assert len(h) == (2 if step == 1 and vid in first else 1)


def test_observe_of_no_vehicle_is_empty_columns() -> None:
    sim = Simulator("dense", 1)
    sim._ls = _StubSumo({EGO: {POS: (0.0, -5.0), SPEED: 20.0, ACC: 0.0, ANGLE: 90.0}}, {EGO: (4.8, 1.8)})
    obs = sim.observe()
    assert obs.ids == () and obs.x.shape == (0,) and obs.lane.shape == (0,) and sim.histories == {}


coef = st.floats(-1e4, 1e4) | st.sampled_from([0.0, -0.0, -2.5])


@settings(max_examples=100, deadline=None)
@given(a=st.lists(coef, min_size=4, max_size=4).map(tuple), b=st.lists(coef, min_size=4, max_size=4).map(tuple),
       t=st.floats(-10.0, 10.0))
def test_a_neighbours_speed_is_that_of_its_own_cubic(a: tuple[float, ...], b: tuple[float, ...], t: float) -> None:
    n = Neighbour("v", a, 0.0, 4.5, 1.8, 1)
    assert n.v(t) == float(P.polyval(t, P.polyder(a)))  # derives and keeps a's speed cubic
    m = dataclasses.replace(n, poly=b)
    assert m.v(t) == float(P.polyval(t, P.polyder(b)))
    assert n.v(t) == float(P.polyval(t, P.polyder(a)))
    assert m == Neighbour("v", b, 0.0, 4.5, 1.8, 1)  # the kept cubic is no field: equality as before
