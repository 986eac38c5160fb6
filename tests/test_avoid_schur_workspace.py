"""The node solver's kernel reads no work space it has not written.

:func:`~iamp.planners.avoid.schur_kernel.active_set` allocates its work space (the working rows'
``w_r``, the Schur complement ``S``, its factors, the right-hand sides) without zeroing it.  Its
former implementation zeroed every array; run as Python with that work space filled with zeros
(the former implementation) and filled with NaN (a read before a write would show), and compiled
by numba, it gives the same status, working set, multipliers, ``z`` and cutoff bound bit for bit
on the QPs of a search at drawn crossing times: cold, warm-started and with a cutoff.
"""

from __future__ import annotations

import types
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st_h
from schur_args import SOLVE_DRAWS, drawn_solve, kernel_args, overtake_qp

from iamp.planners.avoid import schur_kernel as kernel
from iamp.planners.avoid.solve import GENERATION_TOL
from iamp.planners.pmp import jit

_qp, _args = overtake_qp, kernel_args


def _numpy_with_empty(fill: float) -> types.SimpleNamespace:
    """numpy as the kernel uses it, but ``empty`` filled with ``fill``."""
    ns = types.SimpleNamespace(**{k: getattr(np, k) for k in dir(np) if not k.startswith("__")})
    ns.empty = lambda shape, dtype=float: np.full(shape, fill, dtype=dtype)
    return ns


def _run_python(args: tuple[Any, ...], fill: float, monkeypatch: pytest.MonkeyPatch) -> tuple[Any, ...]:
    with monkeypatch.context() as mp:
        mp.setattr(kernel, "np", _numpy_with_empty(fill))
        return tuple(kernel.active_set(*args))


@settings(max_examples=25, deadline=None)
@given(**SOLVE_DRAWS)
def test_the_kernel_reads_no_work_space_before_writing_it(m: int, taus: list[float], widths: list[float],
                                                          mode: str) -> None:
    monkeypatch = pytest.MonkeyPatch()
    qp = _qp(m)
    spec, start, cutoff = drawn_solve(qp, taus, widths, mode)
    outs = []
    for fill in (0.0, np.nan):  # the former implementation (zeroed), and poisoned work space
        args = _args(qp, spec, start, cutoff)
        code = _run_python(args, fill, monkeypatch)
        outs.append((code, args[-4:]))
    if jit.available():
        args = _args(qp, spec, start, cutoff)
        code = tuple(jit.twin(kernel.active_set, cache=True)(*args))
        outs.append((code, args[-4:]))
    (code0, arr0), rest = outs[0], outs[1:]
    k = int(code0[1])
    for code, arr in rest:
        assert tuple(int(x) for x in code) == tuple(int(x) for x in code0)
        z, lam, rows, out = arr
        assert z.tobytes() == arr0[0].tobytes()
        assert lam[:k].tobytes() == arr0[1][:k].tobytes()
        assert rows[:k].tobytes() == arr0[2][:k].tobytes()
        assert out.tobytes() == arr0[3].tobytes()


@st_h.composite
def _rows(draw: Any) -> tuple[Any, ...]:
    """Rows ``G z <= u`` (CSR, a few entries each, some rows empty), ``z`` and ``u``; NaN sometimes."""
    n, m = draw(st_h.integers(1, 8)), draw(st_h.integers(0, 12))
    fl = st_h.floats(-1e3, 1e3, allow_nan=False, allow_infinity=False)
    lens = draw(st_h.lists(st_h.integers(0, 4), min_size=m, max_size=m))
    indptr = np.concatenate(([0], np.cumsum(lens))).astype(np.int32)
    nnz = int(indptr[-1])
    indices = np.array(draw(st_h.lists(st_h.integers(0, n - 1), min_size=nnz, max_size=nnz)), dtype=np.int32)
    data = np.array(draw(st_h.lists(fl, min_size=nnz, max_size=nnz)), dtype=float)
    z = np.array(draw(st_h.lists(fl, min_size=n, max_size=n)), dtype=float)
    u = np.array(draw(st_h.lists(fl, min_size=m, max_size=m)), dtype=float)
    if m and draw(st_h.booleans()) and draw(st_h.booleans()):
        u[draw(st_h.integers(0, m - 1))] = np.nan
    return indptr, indices, data, z, u, n


@settings(max_examples=200, deadline=None)
@given(rows=_rows())
def test_the_violation_of_inherit_is_the_former_matvec_test(rows: tuple[Any, ...]) -> None:
    """:meth:`~iamp.planners.avoid.schur.SchurActiveSet.violation` (``inherit``'s first test) against
    the former ``max(matvec(A, z) - u)``: the same number bit for bit, floored at zero, where no row
    is NaN; ``inf`` where one is (the former test then passed on to the KKT residual, which gives
    ``inf`` on the same row: ``inherit`` returns None either way)."""
    import scipy.sparse as sp

    from iamp.planners.avoid.schur import SchurActiveSet, csr_arrays
    from iamp.planners.qp.backends.base import compressed, matvec

    indptr, indices, data, z, u, n = rows
    A = compressed(sp.csr_matrix, data, indices, indptr, (u.size, n))
    solver = object.__new__(SchurActiveSet)  # violation reads no factored matrix
    got = solver.violation(csr_arrays(A), z, u)
    fns = [kernel._abs_max_rows] + ([jit.twin(kernel._abs_max_rows, cache=True)] if jit.available() else [])
    for fn in fns:
        assert np.float64(fn(*csr_arrays(A), z, u, 0.0, u.size)).tobytes() == np.float64(got).tobytes()
    if not u.size:
        assert got == 0.0
        return
    former = float(np.max(matvec(A, z) - u))
    if np.isnan(former):
        assert got == np.inf
    else:
        assert np.float64(got).tobytes() == np.float64(max(0.0, former)).tobytes()
        assert (got > GENERATION_TOL) == (former > GENERATION_TOL)
