"""Shared by the node-solver kernel tests: the overtake QPs and the arguments of
:func:`~iamp.planners.avoid.schur_kernel.active_set` for one spec."""

from __future__ import annotations

from typing import Any

import numpy as np

from iamp.planners.avoid.continuous import ContinuousAvoidQP
from iamp.planners.avoid.schur import DEPENDENT_REL, FIXED_REL, WARM_COND
from iamp.planners.avoid.solve import GENERATION_TOL
from iamp.planners.examples import overtake_problem, overtake_three_problem

_QPS: dict[int, ContinuousAvoidQP] = {}


def overtake_qp(m: int) -> ContinuousAvoidQP:
    """The QP of the overtake with ``m`` vehicles (one or three) on 20 pieces, built once."""
    if m not in _QPS:
        _QPS[m] = ContinuousAvoidQP(overtake_problem() if m == 1 else overtake_three_problem(), 20, "foh", "clarabel")
    return _QPS[m]


def kernel_args(qp: ContinuousAvoidQP, spec: Any, start: Any = None, cutoff: float | None = None,
                cap: int | None = None) -> tuple[Any, ...]:
    """``active_set``'s arguments for ``spec`` (the limit rows paired as the QP pairs them), the
    working set's capacity ``cap`` (default: the node solver's, from the seed's size)."""
    s = qp.schur
    assert s is not None
    A, u, _ = qp.spec_rows(spec)
    indptr, indices = np.asarray(A.indptr, dtype=np.int64), np.asarray(A.indices, dtype=np.int64)
    s._columns(indices)
    seed = np.zeros(0, dtype=np.int64) if start is None else np.asarray(start, dtype=np.int64)
    if cap is None:
        cap = min(max(32, 2 * seed.size), u.size, s.n) + 1
    return (s.z0, s._Kinv, s._colnorm, indptr, indices, np.asarray(A.data, dtype=float), u,
            u.size - qp._lim_mirrored, seed, cutoff is not None, 0.0 if cutoff is None else float(cutoff), s._Pp,
            s._Pi, s._Px, s.max_iter, GENERATION_TOL, DEPENDENT_REL, FIXED_REL, WARM_COND, cap, np.empty(s.n),
            np.zeros(cap), np.zeros(cap, dtype=np.int64), np.zeros(1))
