"""Shared by the node-solver kernel tests: the overtake QPs and the arguments of
:func:`~iamp.planners.avoid.schur_kernel.active_set` for one spec."""

from __future__ import annotations

from typing import Any

import numpy as np
from hypothesis import strategies as st_h

from iamp.planners.avoid.check import crossing_orders
from iamp.planners.avoid.continuous import ContinuousAvoidQP
from iamp.planners.avoid.schur import DEPENDENT_REL, FIXED_REL, WARM_COND
from iamp.planners.avoid.solve import GENERATION_TOL
from iamp.planners.examples import overtake_problem, overtake_three_problem

_QPS: dict[int, ContinuousAvoidQP] = {}

# the draws of a node solve on a search's QP: one or three vehicles, each vehicle's crossing
# interval (its start ``taus``, its width ``widths``, fractions of t_f) and the solve's mode
SOLVE_DRAWS = {"m": st_h.sampled_from([1, 3]),
               "taus": st_h.lists(st_h.floats(0.05, 0.95), min_size=3, max_size=3),
               "widths": st_h.lists(st_h.floats(0.0, 0.3), min_size=3, max_size=3),
               "mode": st_h.sampled_from(["cold", "warm", "cutoff"])}


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


def drawn_solve(qp: ContinuousAvoidQP, taus: list[float], widths: list[float], mode: str
                ) -> tuple[Any, Any, float | None]:
    """The spec of :data:`SOLVE_DRAWS` (each vehicle's first order, its crossing interval
    ``[t, min(1, t + w)] t_f``) and the node solve's seed and cutoff for ``mode``: ``cold`` none;
    ``warm`` the rows of a nearby candidate (every vehicle crossing 5 % later); ``cutoff`` half
    the spec's optimum (1 where it has none)."""
    tf = qp.tf
    orders, _ = crossing_orders(qp.problem)
    first = [o[0] for o in orders]
    spec = tuple((f, s, float(t * tf), float(min(1.0, t + w) * tf)) for (f, s), t, w in zip(first, taus, widths))
    ref = qp.solve(spec)
    start, cutoff = None, None
    if mode == "warm":
        near = tuple((f, s, a, a) for f, s, a in ((f, s, min(b + 0.05 * tf, tf)) for f, s, _, b in spec))
        other = qp.solve(near)
        _, _, ids = qp.spec_rows(spec)
        start = np.flatnonzero(np.isin(ids, other.active()))
    elif mode == "cutoff":
        cutoff = 0.5 * ref.cost if np.isfinite(ref.cost) else 1.0
    return spec, start, cutoff
