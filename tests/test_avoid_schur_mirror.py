"""The node solver's row scan forms each mirrored pair's product once.

:func:`~iamp.planners.avoid.schur_kernel.active_set` finds the most violated row among rows whose
last ``h`` negate the ``h`` before them (the limit rows ``[A_lim; -A_lim]``): the negated rows'
products are the negated products of their twins (:func:`~iamp.planners.avoid.schur_kernel.
_most_violated`).  Its former scan summed every row; against it (kept here as the oracle) the same
row is chosen and the same violation found — up to the sign of a zero, which no comparison sees —
on drawn rows full of ties, zeros (both signs) and NaN, as Python and compiled; and the kernel
gives the same status, working set, multipliers, ``z`` and cutoff bound bit for bit with the
pairs as without (``mirror = m``: the former scan) on the QPs of a search.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st_h
from schur_args import SOLVE_DRAWS, drawn_solve, kernel_args, overtake_qp

from iamp.planners.avoid import schur_kernel as kernel
from iamp.planners.avoid.continuous import ContinuousAvoidQP, _mirrored
from iamp.planners.pmp import jit

_qp, _args = overtake_qp, kernel_args


def _former_scan(indptr: Any, indices: Any, data: Any, u: Any, z: Any, inw: Any) -> tuple[int, float]:
    """The former implementation: every row's product summed."""
    p = -1
    best = 0.0
    for r in range(u.shape[0]):
        if inw[r]:
            continue
        s = 0.0
        for j in range(indptr[r], indptr[r + 1]):
            s += data[j] * z[indices[j]]
        v = s - u[r]
        if p < 0 or v > best:
            p = r
            best = v
    return p, best


_FEW = st_h.sampled_from([0.0, -0.0, 1.0, -1.0, 2.0, 0.5, -0.5])  # ties and zeros
_ANY = st_h.floats(-1e3, 1e3, allow_nan=False, allow_infinity=False)


@st_h.composite
def _mirrored_rows(draw: Any) -> tuple[Any, ...]:
    """Rows ``[P; B; -B]`` (CSR, up to four entries each, some empty), ``z``, ``u``, working rows."""
    fl = st_h.one_of(_FEW, _ANY) if draw(st_h.booleans()) else _FEW
    n, m0, h = draw(st_h.integers(1, 6)), draw(st_h.integers(0, 5)), draw(st_h.integers(0, 8))
    lens = draw(st_h.lists(st_h.integers(0, 4), min_size=m0 + h, max_size=m0 + h))
    lens += lens[m0:]
    indptr = np.concatenate(([0], np.cumsum(lens))).astype(np.int32)
    top = int(indptr[m0 + h])
    nnz = top - int(indptr[m0])
    indices = np.array(draw(st_h.lists(st_h.integers(0, n - 1), min_size=top, max_size=top)), dtype=np.int32)
    data = np.array(draw(st_h.lists(fl, min_size=top, max_size=top)), dtype=float)
    indices = np.concatenate((indices, indices[top - nnz:]))
    data = np.concatenate((data, -data[top - nnz:]))
    m = m0 + 2 * h
    z = np.array(draw(st_h.lists(fl, min_size=n, max_size=n)), dtype=float)
    u = np.array(draw(st_h.lists(fl, min_size=m, max_size=m)), dtype=float)
    if draw(st_h.booleans()) and draw(st_h.booleans()):  # NaN sometimes
        if m and draw(st_h.booleans()):
            u[draw(st_h.integers(0, m - 1))] = np.nan
        else:
            z[draw(st_h.integers(0, n - 1))] = np.nan
    inw = np.array(draw(st_h.lists(st_h.booleans(), min_size=m, max_size=m)), dtype=np.bool_)
    return indptr, indices, data, u, z, inw, h


@settings(max_examples=400, deadline=None)
@given(rows=_mirrored_rows())
def test_the_mirrored_scan_is_the_former_scan(rows: tuple[Any, ...]) -> None:
    indptr, indices, data, u, z, inw, h = rows
    m = u.size
    assert _mirrored(indptr[m - 2 * h:] - indptr[m - 2 * h], indices[indptr[m - 2 * h]:],
                     data[indptr[m - 2 * h]:]) == h
    p0, best0 = _former_scan(indptr, indices, data, u, z, inw)
    fns = [kernel._most_violated] + ([jit.twin(kernel._most_violated, cache=True)] if jit.available() else [])
    got = []
    for fn in fns:
        for mirror in (m - h, m):  # paired, and unpaired (the former scan itself)
            p, best = fn(indptr, indices, data, u, mirror, z, inw, np.empty(m - mirror))
            assert int(p) == p0
            if np.isnan(best0):
                assert np.isnan(best)
            else:
                assert best == best0  # the same number; a zero's sign may differ
                assert (best <= 1e-9) == (best0 <= 1e-9)
            got.append(np.float64(best).tobytes())
    if len(fns) == 2:  # compiled and Python: the same bits
        assert got[:2] == got[2:]


def test_the_limit_rows_are_mirrored() -> None:
    qp = _qp(1)
    h = qp.u_lim.size // 2
    assert h and qp._lim_mirrored == h
    A = qp.A_lim
    assert (A[h:] + A[:h]).count_nonzero() == 0
    bad = qp._lim_data.copy()
    bad[-1] = np.nextafter(bad[-1], np.inf)
    assert _mirrored(qp._lim_indptr, qp._lim_indices, bad) == 0
    assert _mirrored(qp._lim_indptr[:2], qp._lim_indices, qp._lim_data) == 0


@settings(max_examples=25, deadline=None)
@given(**SOLVE_DRAWS)
def test_the_kernel_with_pairs_is_the_kernel_without(m: int, taus: list[float], widths: list[float],
                                                     mode: str) -> None:
    qp: ContinuousAvoidQP = _qp(m)
    assert qp._lim_mirrored > 0 or qp.u_lim.size == 0
    spec, start, cutoff = drawn_solve(qp, taus, widths, mode)
    fns = [kernel.active_set] + ([jit.twin(kernel.active_set, cache=True)] if jit.available() else [])
    outs = []
    for fn in fns:
        for paired in (False, True):
            args = list(_args(qp, spec, start, cutoff))
            if not paired:
                args[7] = args[6].size  # no pairs: the former scan
            code = tuple(int(x) for x in fn(*args))
            outs.append((code, [a.tobytes() for a in args[-4:]], code[1]))
    code0, arr0, k = outs[0]
    for code, arr, _ in outs[1:]:
        assert code == code0
        assert arr[0] == arr0[0] and arr[3] == arr0[3]  # z, the cutoff's bound
        assert arr[1][:8 * k] == arr0[1][:8 * k] and arr[2][:8 * k] == arr0[2][:8 * k]  # lam, rows


@settings(max_examples=300, deadline=None)
@given(rows=_mirrored_rows(), sign=st_h.sampled_from([0.0, 1.0]))
def test_the_mirrored_residual_rows_are_the_former_rows(rows: tuple[Any, ...], sign: float) -> None:
    """:func:`~iamp.planners.avoid.schur_kernel._abs_max_rows` (the KKT residual's and ``inherit``'s
    row test) with the pairs is the same number bit for bit as without (every row summed, the
    former implementation), Python and compiled."""
    indptr, indices, data, u, z, _, h = rows
    m = u.size
    fns = [kernel._abs_max_rows] + ([jit.twin(kernel._abs_max_rows, cache=True)] if jit.available() else [])
    want = np.float64(kernel._abs_max_rows(indptr, indices, data, z, u, sign, m)).tobytes()
    for fn in fns:
        assert np.float64(fn(indptr, indices, data, z, u, sign, m - h)).tobytes() == want
        assert np.float64(fn(indptr, indices, data, z, u, sign, m)).tobytes() == want
