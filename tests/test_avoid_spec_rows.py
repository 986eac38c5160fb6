"""The imposed rows of a crossing-time spec equal, bit for bit, those of the construction before
:meth:`~iamp.planners.avoid.continuous.ContinuousAvoidQP._build_spec_rows` concatenated its
segments' blocks at once and its planes shared what does not depend on the vehicles.

The oracle below is that construction, written out here: per segment its sub-pieces' values
``σ (Σ_j λ^j M_j)`` and bounds ``Σ_j λ^j r_j`` (``r`` fitted on the samples of the piece, per piece
and end), the full pieces' slices, the node columns indexed by the layout numbers, then every array
concatenated with the limit rows.  Checked on specs of one to three vehicles, on a fresh QP and on
QPs that share a :class:`~iamp.planners.avoid.continuous.GridShare` with earlier plans of other
vehicles (whose kept values must not leak: ``forget_vehicles``), both holds, with and without
limits.
"""

from __future__ import annotations

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st_h

from iamp.core.physical import PASSENGER_CAR
from iamp.core.problem import EgoBoundary, Problem, SurroundingVehicle
from iamp.planners.avoid.bernstein import piece_matrix
from iamp.planners.avoid.continuous import ContinuousAvoidQP, GridShare
from iamp.planners.avoid.dual import fit_polynomial, fit_polynomials


def _problem(shift: float, vehicles: int, limits: bool) -> Problem:
    ego = EgoBoundary(tf=5.0, x0=0.0, y0=-2.0, vx0=20.0, xf=118.0, yf=3.75, vxf=24.0)
    vs = tuple(SurroundingVehicle(x_poly=(5.0 + 30.0 * i + shift, 20.0 - i, 0.1 * i), corner="front-lower",
                                  y=3.75 + 0.25 * i + 0.1 * shift, length=4.8, width=1.8, safety_x=5.0,
                                  safety_y=0.5, name=f"sv{i}") for i in range(vehicles))
    return Problem(ego, vs, "binding", limits=PASSENGER_CAR if limits else None)


def _old_rhs_polynomial(qp: ContinuousAvoidQP, i: int, plane: int, k: int, pre: bool) -> np.ndarray:
    hp = qp.data.planes[i][plane]
    tk = float(qp.data.t_nodes[k])
    ends = tk + np.linspace(0.0, 1.0, qp.degree + 1) * qp.h
    vals = (qp._rhs(hp, np.full_like(ends, tk), ends) if pre
            else qp._rhs(hp, ends, np.full_like(ends, tk + qp.h)))
    return fit_polynomial(vals, qp.degree)


def _old_split(qp: ContinuousAvoidQP, i: int, plane: int, k: int, l0: float,
               l1: float) -> tuple[np.ndarray, np.ndarray]:
    hp = qp.data.planes[i][plane]
    D = qp.degree
    if l0 == 0.0 or l1 == 1.0:
        pre = l0 == 0.0
        x = l1 if pre else l0
        pw = x ** np.arange(D + 1)
        lam = np.linspace(0.0, 1.0, D + 1)
        M = fit_polynomial(np.array([piece_matrix(qp.h, 0.0, float(s), D) if pre
                                     else piece_matrix(qp.h, float(s), 1.0, D) for s in lam]), D)
        return hp.sigma * (pw @ M.reshape(M.shape[0], -1)), pw @ _old_rhs_polynomial(qp, i, plane, k, pre)
    t0 = float(qp.data.t_nodes[k])
    return (hp.sigma * piece_matrix(qp.h, l0, l1, D).ravel(), qp._rhs(hp, t0 + l0 * qp.h, t0 + l1 * qp.h))


def _old_rows(qp: ContinuousAvoidQP, spec: tuple[tuple[int, int, float, float], ...]) -> tuple[np.ndarray, ...]:
    n = qp.degree + 1
    vals, rhs, ids = [], [], []
    for i, (first, second, a, b) in enumerate(spec):
        segs = [(first, 0.0, a)] if a > 0.0 else []
        if b < qp.tf:
            segs.append((second, b, qp.tf))
        for plane, ta, tb in sorted(segs):
            base = (i * 2 + plane) * qp.N * n
            for k, l0, l1 in qp.segment_pieces(ta, tb):
                if (l0, l1) == (0.0, 1.0):
                    hp = qp.data.planes[i][plane]
                    v = hp.sigma * piece_matrix(qp.h, 0.0, 1.0, qp.degree).ravel()
                    c = qp._rhs(hp, qp.data.t_nodes[k], qp.data.t_nodes[k] + qp.h).ravel()
                else:
                    v, c = _old_split(qp, i, plane, k, l0, l1)
                vals.append(v)
                rhs.append(c)
                ids.append(np.arange(base + k * n, base + (k + 1) * n, dtype=np.int64))
    idb = np.concatenate(ids) if ids else np.zeros(0, dtype=np.int64)
    data = np.concatenate(vals + [qp._lim_data])
    cols = np.concatenate((qp._bern_cols[idb].ravel(), qp._lim_indices))
    return data, cols, np.concatenate(rhs + [qp.u_lim]), np.concatenate((idb, qp._lim_ids))


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


_END = st_h.one_of(st_h.sampled_from([0.0, 5.0, 2.5, 3.7, 3.75, 0.1, 4.9]), st_h.floats(0.0, 5.0))


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow], derandomize=True)
@given(st_h.integers(1, 3), st_h.sampled_from(["foh", "zoh"]), st_h.booleans(), st_h.integers(3, 30),
       st_h.lists(st_h.tuples(_END, _END, st_h.booleans()), min_size=3, max_size=3), st_h.floats(-3.0, 3.0))
def test_spec_rows_equal_the_segment_by_segment_construction(vehicles, hold, limits, steps, ends, shift):
    limits = limits and hold == "foh"  # the jerk bound needs FOH
    shared = GridShare()
    # an earlier plan of other vehicles on the same grid fills what the planes share
    earlier = ContinuousAvoidQP(_problem(shift + 7.0, vehicles, limits), steps, hold, "piqp", shared=shared)
    for a, b, flip in ends:
        spec = tuple((1, 0, min(a, b), max(a, b)) if not flip else (0, 1, min(a, b), max(a, b))
                     for _ in range(vehicles))
        earlier.spec_rows(spec)
    for qp in (ContinuousAvoidQP(_problem(shift, vehicles, limits), steps, hold, "piqp"),
               ContinuousAvoidQP(_problem(shift, vehicles, limits), steps, hold, "piqp", shared=shared)):
        for a, b, flip in ends + [(e[1], e[0], not e[2]) for e in ends]:
            spec = tuple(((1, 0) if (flip ^ (i % 2 == 1)) else (0, 1)) + (min(a, b), max(a, b))
                         for i in range(vehicles))
            A, u, ids = qp.spec_rows(spec)
            data, cols, rhs, lids = _old_rows(qp, spec)
            assert _same(A.data, data) and _same(A.indices, cols) and _same(u, rhs) and _same(ids, lids)
            assert A.indptr.dtype == np.int32 and A.shape == (ids.size, qp.data.n)
            assert np.array_equal(np.diff(A.indptr), np.diff(np.concatenate(
                (np.arange(0, 4 * int(np.sum(ids < qp.n_b)) + 1, 4), 4 * int(np.sum(ids < qp.n_b))
                 + qp._lim_indptr[1:]))))
            for i in range(vehicles):  # the split pieces' bound polynomials: the old fit's
                for plane in (0, 1):
                    for k, pre in ((0, True), (steps - 1, False), (steps // 2, True), (steps // 2, False)):
                        assert _same(qp.rhs_polynomial(i, plane, k, pre), _old_rhs_polynomial(qp, i, plane, k, pre))


@settings(max_examples=60, deadline=None, derandomize=True)
@given(st_h.integers(3, 6), st_h.integers(1, 5), st_h.integers(1, 6), st_h.integers(0, 2**31 - 1))
def test_stacked_fits_equal_one_at_a_time(degree, stack, width, seed):
    # one stacked solve gives each system's own numbers (ContinuousAvoidQP.rhs_polynomial fits a
    # piece and its neighbours at once)
    values = np.random.default_rng(seed).normal(scale=10.0 ** (seed % 7), size=(stack, degree + 1, width))
    fits = fit_polynomials(values, degree)
    assert fits.shape == values.shape
    for m in range(stack):
        one = fit_polynomial(values[m], degree)
        assert _same(fits[m], one) and fits[m].flags.c_contiguous == one.flags.c_contiguous
