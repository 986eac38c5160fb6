"""A held trajectory's ``states``: the located piece's width from its two nodes and the columns
written in place are the long way's numbers (``np.diff(t_nodes)[k]``, ``np.stack``) bit for bit."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as hst

from iamp.core.hold_trajectory import HoldTrajectory


def _long_way(tr: HoldTrajectory, t: np.ndarray) -> np.ndarray:
    tt = np.atleast_1d(np.asarray(t, dtype=float))
    k = np.clip(np.searchsorted(tr.t_nodes, tt, side="right") - 1, 0, len(tr.t_nodes) - 2).astype(np.int64)
    dt, h = tt - tr.t_nodes[k], np.diff(tr.t_nodes)[k]
    s0, v0, d = tr.X[k][:, [0, 2]], tr.X[k][:, [1, 3]], dt[:, None]
    if tr.hold == "zoh":
        u = tr.U[k]
        v = v0 + u * d
        s = s0 + v0 * d + u * d**2 / 2
    else:
        u0, du = tr.U[k], (tr.U[k + 1] - tr.U[k]) / h[:, None]
        v = v0 + u0 * d + du * d**2 / 2
        s = s0 + v0 * d + u0 * d**2 / 2 + du * d**3 / 6
    return np.stack([s[:, 0], v[:, 0], s[:, 1], v[:, 1]], axis=1)


@settings(max_examples=80, deadline=None)
@given(seed=hst.integers(0, 2**31 - 1), hold=hst.sampled_from(["foh", "zoh"]), n=hst.integers(1, 30))
def test_states_are_the_long_ways(seed: int, hold: str, n: int) -> None:
    rng = np.random.default_rng(seed)
    nodes = np.r_[0.0, np.cumsum(rng.uniform(0.01, 1.0, size=n))]  # uneven pieces
    X = rng.normal(size=(n + 1, 4)) * 10.0
    U = rng.normal(size=(n + 1 if hold == "foh" else n, 2))
    tr = HoldTrajectory(nodes, X, U, hold)
    t = np.r_[rng.uniform(-0.5, nodes[-1] + 0.5, size=50), nodes, nodes[-1]]
    assert np.array_equal(tr.states(t), _long_way(tr, t))
    assert np.array_equal(tr.states(float(t[0])), _long_way(tr, t[:1]))
