r"""The symbolic analysis of the :mod:`~iamp.planners.qp.backends.kkt` backend, computed once per
sparsity pattern and shared by every backend built on that pattern.

Given the patterns of ``P`` (upper triangle) and ``A`` (both CSC), with the rows of ``A``
split into a long-row **border** (more than ``border_row_nnz`` entries) and the **core**,
the core KKT matrix

.. math::  K_0 = \begin{bmatrix} P & A_0^\top \\ A_0 & 0 \end{bmatrix}

is analysed as follows (values never enter):

* its connected components (the blocks of a block-diagonal :math:`K_0`; the two axes of the
  lane-change QP), each ordered by reverse Cuthill–McKee, stored one after another
  (``perm``/``inv``, block ``c`` at ``starts[c]:starts[c+1]``);
* the bandwidth ``bw`` of the ordered matrix and, for every stored value of ``P`` and of the
  core of ``A``, its position in LAPACK's band storage (``(3 bw + 1, nk)``, row
  ``2 bw + i − j`` for entry ``(i, j)``);
* which blocks have the same size and banded pattern (``twin_of``: candidates for sharing
  one numeric factorisation when their values agree too);
* for every stored entry of the border rows: its row, its column's permuted position, and
  the distinct border columns with their block and local row.

:func:`analyse` caches the result per pattern (the last :data:`CACHE_SIZE` patterns), so a
planner that builds the QP of the same grid again (a closed loop, a benchmark) skips the
analysis.  Every array of a :class:`KKTStructure` is read-only.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass, fields

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components, reverse_cuthill_mckee

from .base import IntArray

#: How many patterns :func:`analyse` remembers.
CACHE_SIZE = 16
_CACHE: OrderedDict[tuple[object, ...], KKTStructure] = OrderedDict()


@dataclass(frozen=True)
class KKTStructure:
    """The pattern-only data of the direct backend (module docstring)."""

    nk: int
    border: IntArray
    core: IntArray
    a_core_pos: IntArray
    a_in_core: IntArray
    perm: IntArray
    inv: IntArray
    starts: IntArray
    comp_of_perm: IntArray
    bandwidth: int
    ab_shape: tuple[int, int]
    p_pos: IntArray
    p_off: IntArray
    p_pos_mirror: IntArray
    a_pos: IntArray
    a_pos_t: IntArray
    twin_of: tuple[int, ...]
    b_pos: IntArray
    b_row: IntArray
    b_range: IntArray
    b_pc: IntArray
    u_comp: IntArray
    u_loc: IntArray
    b_info: IntArray
    block_max: int


def _pattern(rows: IntArray, cols: IntArray, nk: int) -> sp.csr_matrix:
    """``sp.csr_matrix((np.ones(rows.size), (rows, cols)), shape=(nk, nk))``: each distinct entry once,
    its value the number of times it is given, in row-major order (its canonical CSR arrays)."""
    keys, counts = np.unique(rows * nk + cols, return_counts=True)
    idx = np.int32 if max(nk, keys.size) < np.iinfo(np.int32).max else np.int64
    indptr = np.concatenate(([0], np.cumsum(np.bincount(keys // nk, minlength=nk)))).astype(idx)
    return sp.csr_matrix((counts.astype(float), (keys % nk).astype(idx), indptr), shape=(nk, nk))


def _component(pattern: sp.csr_matrix, nodes: IntArray) -> sp.csr_matrix:
    """``pattern[nodes][:, nodes]`` of a connected component ``nodes`` (increasing) of the
    symmetric, canonical ``pattern``: its rows' entries all lie in the component, so the submatrix
    is those rows with their columns renumbered (an increasing map: each row stays sorted), the
    arrays scipy's indexing gives, without its search of every row for the kept columns."""
    at = np.full(pattern.shape[0], -1, dtype=np.int64)
    at[nodes] = np.arange(nodes.size)
    start, stop = pattern.indptr[nodes], pattern.indptr[nodes + 1]
    lens = stop - start
    take = np.repeat(start - np.concatenate(([0], np.cumsum(lens)[:-1])), lens) + np.arange(int(lens.sum()))
    idx = pattern.indices.dtype
    indptr = np.concatenate(([0], np.cumsum(lens))).astype(idx)
    return sp.csr_matrix((pattern.data[take], at[pattern.indices[take]].astype(idx), indptr),
                         shape=(nodes.size, nodes.size))


def _blocks(pattern: sp.csr_matrix, nk: int) -> tuple[IntArray, IntArray, int]:
    """``perm`` (blocks one after another, each in RCM order), ``starts``, number of blocks."""
    ncomp, label = connected_components(pattern, directed=False)
    parts, starts = [], [0]
    for c in range(ncomp):
        nodes = np.flatnonzero(label == c)
        sub = _component(pattern, nodes)
        order = np.asarray(reverse_cuthill_mckee(sub, symmetric_mode=True), dtype=np.int64)
        parts.append(nodes[order])
        starts.append(starts[-1] + nodes.size)
    return np.concatenate(parts), np.asarray(starts, dtype=np.int64), int(ncomp)


def _analyse(P: sp.csc_matrix, A: sp.csc_matrix, border_row_nnz: int) -> KKTStructure:
    n, mrows = P.shape[0], A.shape[0]
    row_nnz = np.bincount(A.indices, minlength=mrows)
    border = np.flatnonzero(row_nnz > border_row_nnz)
    core = np.flatnonzero(row_nnz <= border_row_nnz)
    core_of_row = np.full(mrows, -1, dtype=np.int64)
    core_of_row[core] = np.arange(core.size)
    nk = n + core.size
    a_cols = np.repeat(np.arange(n), np.diff(A.indptr))
    a_rows = A.indices.astype(np.int64)
    in_core = core_of_row[a_rows] >= 0
    kr, kc = n + core_of_row[a_rows[in_core]], a_cols[in_core]
    p_cols = np.repeat(np.arange(n), np.diff(P.indptr))
    p_rows = P.indices.astype(np.int64)
    pr = np.concatenate([p_rows, p_cols, kr, kc, np.arange(nk)])
    pc = np.concatenate([p_cols, p_rows, kc, kr, np.arange(nk)])
    pattern = _pattern(pr, pc, nk)
    perm, starts, ncomp = _blocks(pattern, nk)
    inv = np.empty(nk, dtype=np.int64)
    inv[perm] = np.arange(nk)
    comp_of_perm = np.repeat(np.arange(ncomp), np.diff(starts))
    bw = int(np.max(np.abs(inv[pr] - inv[pc])))
    ab_shape = (3 * bw + 1, nk)

    def flat(i: IntArray, j: IntArray) -> IntArray:
        ii, jj = inv[i], inv[j]
        return np.asarray((2 * bw + ii - jj) * nk + jj, dtype=np.int64)

    off = p_rows != p_cols
    p_pos, p_pos_mirror = flat(p_rows, p_cols), flat(p_cols[off], p_rows[off])
    a_pos, a_pos_t = flat(kr, kc), flat(kc, kr)
    bp = np.zeros(ab_shape, dtype=bool)
    bp.reshape(-1)[np.concatenate([p_pos, p_pos_mirror, a_pos, a_pos_t])] = True
    twin_of: list[int] = []  # block -> first block with the same size and banded pattern
    for c in range(ncomp):
        s, e = starts[c], starts[c + 1]
        twin_of.append(next((d for d in range(c) if starts[d + 1] - starts[d] == e - s
                             and np.array_equal(bp[:, starts[d]:starts[d + 1]], bp[:, s:e])), c))
    b_mask = ~in_core
    border_of_row = np.full(mrows, -1, dtype=np.int64)
    border_of_row[border] = np.arange(border.size)
    b_row = border_of_row[a_rows[b_mask]]
    b_col = a_cols[b_mask]
    b_pc = inv[b_col]  # permuted position of each border entry's column
    ucols, b_ucol = np.unique(b_col, return_inverse=True)  # the distinct border columns
    pu = inv[ucols]
    u_comp = comp_of_perm[pu]
    return KKTStructure(
        nk=nk, border=border, core=core, a_core_pos=np.flatnonzero(in_core), a_in_core=in_core, perm=perm,
        inv=inv, starts=starts, comp_of_perm=comp_of_perm, bandwidth=bw, ab_shape=ab_shape, p_pos=p_pos,
        p_off=np.flatnonzero(off), p_pos_mirror=p_pos_mirror, a_pos=a_pos, a_pos_t=a_pos_t,
        twin_of=tuple(twin_of), b_pos=np.flatnonzero(b_mask), b_row=b_row, b_range=np.arange(border.size),
        b_pc=b_pc, u_comp=u_comp, u_loc=pu - starts[u_comp],
        b_info=np.stack([b_row, b_pc, np.asarray(b_ucol, dtype=np.int64).reshape(-1)]),
        block_max=int(np.max(np.diff(starts))))


def analyse(P: sp.csc_matrix, A: sp.csc_matrix, border_row_nnz: int) -> KKTStructure:
    """The :class:`KKTStructure` of the patterns of ``P`` and ``A`` (sorted CSC), cached."""
    key = (P.shape, A.shape, int(border_row_nnz), P.indptr.tobytes(), P.indices.tobytes(), A.indptr.tobytes(),
           A.indices.tobytes())
    hit = _CACHE.get(key)
    if hit is not None:
        _CACHE.move_to_end(key)
        return hit
    s = _analyse(P, A, int(border_row_nnz))
    for f in fields(s):
        v = getattr(s, f.name)
        if isinstance(v, np.ndarray):
            v.setflags(write=False)
    _CACHE[key] = s
    while len(_CACHE) > CACHE_SIZE:
        _CACHE.popitem(last=False)
    return s
