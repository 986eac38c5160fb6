r"""The exact continuous-time trajectory of a discretised-QP solution, and aligned grids.

The trajectory class, :class:`~iamp.core.hold_trajectory.HoldTrajectory`, lives in the core
(which evaluates it for the safety report, the peaks and the samples) and is re-exported here.

The held-input equations (ZOH, FOH) and the exact cost are written out in
:mod:`iamp.core.hold_trajectory`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from iamp.core.hold_trajectory import HoldTrajectory

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

#: The two input holds of SPEC §3.
HOLDS = ("foh", "zoh")

__all__ = ["HOLDS", "ON_NODE_REL", "HoldTrajectory", "aligned_grid"]


#: A contact time within this many grid steps of a uniform node is that node (rounding only).
ON_NODE_REL = 1e-9


def aligned_grid(times: Sequence[float] | FloatArray, tf: float, steps: int) -> tuple[FloatArray, IntArray]:
    """A piecewise-uniform grid of ``steps`` intervals with nodes at every contact time.

    Returns ``(t_nodes, node_index_of_each_time)``.  Steps are allotted to the pieces
    ``[0, t_(1)], [t_(1), t_(2)], …, [t_(m), t_f]`` in proportion to their lengths (largest
    remainder), at least one per piece; the contact times are placed on their nodes exactly.
    """
    tt = np.asarray(times, dtype=float)
    order = np.argsort(tt)
    bps = np.r_[0.0, tt[order], tf]
    lengths = np.diff(bps)
    if np.any(lengths <= 0):
        raise ValueError("contact times must be distinct and inside (0, tf)")
    if steps < len(lengths):
        raise ValueError(f"need at least {len(lengths)} steps for {len(tt)} contact times")
    k = tt / tf * steps
    k_node = np.round(k)
    if np.all(np.abs(k - k_node) <= ON_NODE_REL) and len(set(k_node.tolist())) == len(k_node):
        # every time is a node of the uniform grid (to rounding): that grid itself, so a sweep's
        # factorisation is reused (a piecewise linspace differs from it in the last bits)
        return np.linspace(0.0, tf, steps + 1), k_node.astype(np.int64)
    raw = lengths / tf * steps
    n = np.maximum(1, np.floor(raw).astype(int))
    while n.sum() > steps:
        n[np.argmax(n - raw)] -= 1
    while n.sum() < steps:
        n[np.argmax(raw - n)] += 1
    nodes = [np.linspace(bps[j], bps[j + 1], n[j] + 1)[:-1] for j in range(len(n))] + [np.array([tf])]
    t_nodes = np.concatenate(nodes)
    idx_sorted = np.cumsum(n)[:-1]
    idx = np.empty(len(tt), dtype=np.int64)
    idx[order] = idx_sorted
    t_nodes[idx] = tt  # exact
    return t_nodes, idx
