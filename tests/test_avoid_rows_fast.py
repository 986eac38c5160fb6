"""The QP side of the crossing-time search without its repeated conversions, bit for bit as before.

* :meth:`~iamp.planners.avoid.continuous.ContinuousAvoidQP._build_spec_rows` keeps the kernels'
  arrays of a spec's rows as it builds them (the row pointers converted to int64 once per number of
  Bernstein rows): :meth:`~iamp.planners.avoid.continuous.ContinuousAvoidQP.csr_arrays` returns
  what :func:`~iamp.planners.avoid.schur.csr_arrays` of the matrix returned before (the oracle).
* The count of mirrored limit rows is kept with the limit rows: the former computation from the
  QP's own arrays (:func:`~iamp.planners.avoid.continuous._mirrored`) is the oracle.
* After a QP's first node solve, its later solves test only the Bernstein rows' columns of ``K⁻¹``
  (``SchurActiveSet.solve(columns=...)``): the same status, ``z``, ``y``, working rows and
  iterations, and the same columns solved, as the former solve that tested every entry's column
  (the oracle: the node solver called on the same rows without ``columns``, on a twin QP).
* ``SchurActiveSet.solve`` tests ``x`` (``z`` and the equality multipliers) and ``λ`` for
  finiteness instead of ``z`` and ``y``: the same truth value for distinct working rows, on drawn
  arrays with NaN and infinities (the former test is the oracle).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st_h

from iamp.planners.avoid.check import crossing_orders
from iamp.planners.avoid.continuous import ContinuousAvoidQP, GridShare, _mirrored
from iamp.planners.avoid.schur import csr_arrays
from iamp.planners.examples import overtake_problem, overtake_three_problem

_PROBLEMS = {1: overtake_problem(), 3: overtake_three_problem()}


def _qp(m: int, shared: GridShare | None = None) -> ContinuousAvoidQP:
    return ContinuousAvoidQP(_PROBLEMS[m], 20, "foh", "clarabel", shared=shared)


@st_h.composite
def _specs(draw: Any, m: int) -> list[Any]:
    """Up to five specs of the ``m``-vehicle overtake: per vehicle an order and a box ``[a, b]``
    (ends on and between the grid's nodes, at ``0`` and ``t_f``)."""
    tf = _PROBLEMS[m].tf
    ends = st_h.one_of(st_h.sampled_from([0.0, tf, tf / 2, tf / 20, 3 * tf / 20]), st_h.floats(0.0, tf))
    orders, _ = crossing_orders(_PROBLEMS[m])
    out = []
    for _ in range(draw(st_h.integers(1, 5))):
        spec = []
        for i in range(m):
            first, second = draw(st_h.sampled_from(orders[i]))
            a, b = sorted((draw(ends), draw(ends)))
            spec.append((first, second, a, b))
        out.append(tuple(spec))
    return out


def _same(a: Any, b: Any) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st_h.sampled_from([1, 3]), st_h.data())
def test_the_kept_kernel_arrays_and_mirrored_count_are_the_former_conversions(m: int, data: Any) -> None:
    qp = _qp(m)
    assert qp._lim_mirrored == _mirrored(qp._lim_indptr, qp._lim_indices, qp._lim_data)
    for spec in data.draw(_specs(m)):
        A, _, _ = qp.spec_rows(spec)
        got, want = qp.csr_arrays(A), csr_arrays(A)
        assert all(_same(g, w) for g, w in zip(got, want, strict=True))
        assert got[0].flags.writeable and got[1].flags.writeable  # numba's usual signature


def _check_solves(m: int, specs: list[Any], shared: GridShare | None) -> None:
    new, old = _qp(m, shared), _qp(m)
    for spec in specs:
        got = new.solve(spec)
        A, u, ids = old.spec_rows(spec)
        assert old.schur is not None and new.schur is not None
        want = old.schur.solve(A, u, None, None, csr_arrays(A), old._lim_mirrored)  # every entry's column tested
        if want.status not in ("optimal", "infeasible"):  # the backend's solve then
            continue
        assert got.status == want.status and got.iterations == want.iterations
        assert _same(got.z, want.z) and _same(got.y, want.y)
        assert _same(got.active(), ids[want.y[old.data.n_eq:] > 0])
        # every column the rows touch is solved, and no other than before
        assert new.schur._have[csr_arrays(A)[1]].all()
        assert _same(new.schur._have, old.schur._have) or shared is not None
        assert _same(new.schur._Kinv[old.schur._have], old.schur._Kinv[old.schur._have])


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st_h.sampled_from([1, 3]), st_h.data())
def test_solves_testing_the_bernstein_columns_only_are_the_former_solves(m: int, data: Any) -> None:
    _check_solves(m, data.draw(_specs(m)), None)


def test_a_shared_node_solver_solves_the_former_way() -> None:
    """A QP whose node solver a plan before factored (its columns partly solved)."""
    share = GridShare()
    _qp(1, share).solve(((0, 1, 1.0, 1.0),))  # its columns partly solved
    qp = _qp(1, share)
    assert qp.schur is not None and 0 < qp.schur._have.sum()
    _check_solves(1, [((0, 1, 2.0, 3.0),), ((1, 0, 0.5, 4.0),), ((0, 1, 0.0, 5.0),)], share)


_VALUES = st_h.sampled_from([0.0, -0.0, 1.0, -2.5, np.nan, np.inf, -np.inf, 1e308])


@settings(max_examples=300, deadline=None)
@given(st_h.integers(0, 6), st_h.integers(1, 6), st_h.data())
def test_the_finiteness_of_x_and_lambda_is_that_of_z_and_y(n_eq: int, n: int, data: Any) -> None:
    n_in = data.draw(st_h.integers(0, 8))
    x = np.array(data.draw(st_h.lists(_VALUES, min_size=n + n_eq, max_size=n + n_eq)), dtype=float)
    rows = np.array(data.draw(st_h.lists(st_h.integers(0, max(n_in - 1, 0)), max_size=n_in, unique=True))
                    if n_in else [], dtype=np.int64)
    lam = np.array(data.draw(st_h.lists(_VALUES, min_size=rows.size, max_size=rows.size)), dtype=float)
    # y as the solve builds it (its working rows are distinct)
    z = np.array(x[:n], dtype=float)
    y = np.zeros(n_eq + n_in)
    y[:n_eq] = x[n:]
    if rows.size:
        y[n_eq + rows] = lam
    former = bool(np.isfinite(z).all() and np.isfinite(y).all())
    assert bool(np.isfinite(x).all() and np.isfinite(lam).all()) == former
