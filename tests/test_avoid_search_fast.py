"""The crossing-time search's faster paths (issue 32): each gives what the numpy expression it
replaced gave, bit for bit, run as Python and compiled by numba.

* :meth:`~iamp.planners.avoid.continuous.ContinuousAvoidPlanner._probe` (the grid, the polynomials'
  values and the points passed over in one kernel, :func:`~iamp.planners.avoid.search_kernel.probe_grid`)
  against its former numpy formulation, kept here as the oracle;
* :class:`~iamp.planners.avoid.dual.DualStore`'s regions, kept as rows of arrays, against the regions
  computed with numpy as they were.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st_h

from iamp.planners.avoid import dual, search_kernel
from iamp.planners.avoid.continuous import ContinuousAvoidPlanner, _Box
from iamp.planners.avoid.dual import DualPolynomial, polys_values
from iamp.planners.pmp import jit


def _former_probe(box: Any, tau: Any, polys: Any, solved: Any, h: float, skip: float) -> tuple[Any, float]:
    """``_probe`` as it was (numpy.repeat grid, :func:`~iamp.planners.avoid.dual.polys_values`, the
    points near a solved candidate by numpy.max / numpy.min, numpy.argmin)."""
    polys = [dp for dp in polys if dp.vehicles]
    if not polys:
        return tau, -np.inf
    vs = sorted({v for dp in polys for v in dp.vehicles if box.hi[v] > box.lo[v] and dp.mass[v] > 0})
    n = {1: 9, 2: 5}.get(len(vs), 3)
    k = len(vs)
    pts = np.repeat(tau[None, :], n ** k, axis=0)
    ramp = np.arange(n, dtype=float)
    for c, v in enumerate(vs):
        lo_v, hi_v = float(box.lo[v]), float(box.hi[v])
        step = (hi_v - lo_v) / (n - 1)
        line = ramp / (n - 1) * (hi_v - lo_v) + lo_v if step == 0.0 else ramp * step + lo_v
        line[-1] = hi_v
        pts[:, v] = np.repeat(np.repeat(line, n ** (k - 1 - c))[None, :], n ** c, axis=0).ravel()
    vals = polys_values(polys, pts)
    if solved is not None and len(solved):
        apart = np.max(np.abs(pts[:, None, :] - solved[None, :, :]), axis=2)
        near = np.min(apart, axis=1) <= skip * h
        if not near.all():
            vals = np.where(near, np.inf, vals)
    at = int(np.argmin(vals))
    return np.asarray(pts[at], dtype=float), float(vals[at])


def _bits(a: Any) -> bytes:
    return np.ascontiguousarray(a).tobytes()


@st_h.composite
def _probes(draw: Any) -> tuple[Any, ...]:
    """A box of ``m`` vehicles (some intervals points, some inside one piece), polynomials on some of
    its vehicles (some without multipliers on a vehicle, some with a NaN coefficient), a ``tau`` and
    solved crossing times (some on the grid's points, some NaN)."""
    m = draw(st_h.integers(1, 3))
    h = 0.1
    seed = draw(st_h.integers(0, 2**31 - 1))
    rng = np.random.default_rng(seed)
    lo = rng.uniform(0.0, 0.4, m)
    hi = lo + rng.uniform(0.0, 0.1, m) * rng.integers(0, 2, m)
    if draw(st_h.booleans()):
        hi = lo + np.where(rng.random(m) < 0.5, 0.0, 1e-17)  # zero steps
    polys = []
    for _ in range(draw(st_h.integers(0, 4))):
        q = int(rng.integers(0, m + 1))
        vehicles = tuple(sorted(rng.choice(m, q, replace=False).tolist()))
        n = int(rng.choice([3, 5]))
        coef = rng.standard_normal((n,) * q)
        if q and rng.random() < 0.1:
            coef.flat[int(rng.integers(0, coef.size))] = np.nan
        mass = np.where(rng.random(m) < 0.3, 0.0, rng.uniform(0.0, 2.0, m))
        pieces = tuple(int(np.floor(lo[v] / h)) for v in vehicles)
        polys.append(DualPolynomial(vehicles, pieces, coef, h, mass))
    tau = rng.uniform(0.0, 0.5, m)
    solved = None
    kind = draw(st_h.sampled_from(["none", "empty", "random", "grid", "all"]))
    if kind == "empty":
        solved = np.empty((0, m))
    elif kind == "random":
        solved = rng.uniform(0.0, 0.5, (int(rng.integers(1, 4)), m))
        if rng.random() < 0.2:
            solved[0, int(rng.integers(0, m))] = np.nan
    elif kind in ("grid", "all"):  # on (or within the tolerance of) points of the probe's grid
        solved = np.repeat(tau[None, :], 2, axis=0)
        solved[:, :] = np.where(rng.random((2, m)) < 0.5, lo, hi) + rng.uniform(-1e-6, 1e-6, (2, m)) * h
        if kind == "all":
            solved = np.concatenate([solved, rng.uniform(lo, hi, (30, m))])
    return _Box(0.0, 0, ((0, 1),) * m, lo, hi, None), tau, polys, solved, h  # type: ignore[arg-type]


@settings(max_examples=300, deadline=None, derandomize=True)
@given(_probes())
def test_the_probe_is_its_former_numpy_formulation(case: tuple[Any, ...]) -> None:
    box, tau, polys, solved, h = case
    planner = ContinuousAvoidPlanner()
    want = _former_probe(box, tau, polys, solved, h, planner.PROBE_SKIP_STEPS)
    if solved is not None:
        solved = solved.copy()
        solved.flags.writeable = False  # as the search's _SolvedPoints hands them out
    for packing in (None, dual.Packing()):
        got = planner._probe(box, tau, polys, solved, h, packing)
        assert _bits(got[0]) == _bits(want[0]) and _bits(got[1]) == _bits(want[1])


@pytest.mark.skipif(not jit.available(), reason="numba is not installed")
@settings(max_examples=100, deadline=None, derandomize=True)
@given(_probes())
def test_the_probe_kernel_is_its_twin_bit_for_bit(case: tuple[Any, ...]) -> None:
    box, tau, polys, solved, h = case
    polys = [dp for dp in polys if dp.vehicles]
    if not polys:
        return
    m = tau.size
    vs = np.array(sorted({v for dp in polys for v in dp.vehicles}), dtype=np.int64)
    n = 3
    solved = np.empty((0, m)) if solved is None else solved
    outs = []
    for fn in (search_kernel.probe_grid, jit.twin(search_kernel.probe_grid, cache=True)):
        flat, meta, W, largest = dual._pack(polys)
        T = n ** vs.size
        pts, vals, near = np.empty((T, m)), np.empty(T), np.empty(T, dtype=np.bool_)
        at = fn(flat, meta, W, h, tau, vs, box.lo, box.hi, n, solved, 1e-5, pts, vals, near, np.empty(W),
                np.empty(largest))
        outs.append((at, _bits(pts), _bits(vals)))
    assert outs[0] == outs[1]


_EDGES = st_h.one_of(st_h.floats(allow_nan=True, allow_infinity=True), st_h.sampled_from([0.0, -0.0, 1.0, -1.0]))


@settings(max_examples=500, deadline=None, derandomize=True)
@given(_EDGES, _EDGES, _EDGES)
def test_the_polish_clip_is_numpy_clip(x: float, lo: float, hi: float) -> None:
    want = float(np.clip(np.float64(x), np.float64(lo), np.float64(hi)))
    got = ContinuousAvoidPlanner._clip(x, lo, hi)
    assert _bits(got) == _bits(want) or (np.isnan(got) and np.isnan(want))
