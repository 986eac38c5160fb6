"""The root finder's kernels (``iamp/core/polyroots_kernel.py``), written once.

* The Python functions and their numba twins give the same numbers bit for bit: the kernels
  alone, :func:`~iamp.core.polyroots.roots_in_unit_interval`, and whole safety reports and
  leave times of plans (so no result depends on whether numba is installed).
* The roots against independent references (hypothesis): polynomials built from known roots
  (numpy's ``polyfromroots``) have every root in ``[0, 1]`` found, to the conditioning of the
  root, and nothing else; on random polynomials every sign change of a dense sampling of
  ``[0, 1]`` holds a root found, and every root found is a root of ``numpy.roots``' or a point
  where the polynomial is zero to round-off.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from test_safety_exact_speed import _hold_problem, _polys, _report_hex

import iamp.core.polyroots as pr
from iamp.core import jit
from iamp.core import polyroots_kernel as kernel
from iamp.core.safety import safety_report

needs_numba = pytest.mark.skipif(not jit.available(), reason="numba is not installed")


def _hex(rows: np.ndarray, sig: np.ndarray) -> list[tuple[int, str]]:
    return [(int(r), float(s).hex()) for r, s in zip(rows, sig)]


@needs_numba
@pytest.mark.parametrize("degree", [1, 2, 3, 5, 7, 9])
def test_the_compiled_kernels_are_the_python_functions_bit_for_bit(degree: int) -> None:
    for seed in range(6):
        C = np.ascontiguousarray(_polys(seed, n=300, degree=degree))
        C[3::53, 2 % C.shape[1]] = np.nan  # NaN and infinite coefficients: kept, never skipped
        C[4::59, 0] = np.inf
        M = pr._bernstein_matrix(C.shape[1] - 1)
        for skip in (True, False):
            py, nb = np.empty(C.shape[0], dtype=np.int64), np.empty(C.shape[0], dtype=np.int64)
            with np.errstate(over="ignore", invalid="ignore"):
                kernel.root_degrees(C, M, 1e-6, skip, py)
            jit.twin(kernel.root_degrees, cache=True)(C, M, 1e-6, skip, nb)
            assert py.tolist() == nb.tolist()
        # eigenvalue-like inputs in and around the window, on every row
        rng = np.random.default_rng(seed)
        rows = rng.integers(0, C.shape[0], 500).astype(np.int64)
        re = rng.uniform(-0.2, 1.2, 500)
        re[::7] = rng.choice([0.0, -0.0, 1.0, -1e-9, 1 + 1e-9, -2e-9], 500)[::7]
        im = rng.choice([0.0, 1e-7, -1e-6, 2e-6], 500)
        with np.errstate(invalid="ignore"):
            py_out = kernel.polish_roots(C, rows, re, im, 1e-6)
        nb_out = jit.twin(kernel.polish_roots, cache=True)(C, rows, re, im, 1e-6)
        assert py_out[0].tolist() == nb_out[0].tolist()
        assert _hex(*py_out) == _hex(*nb_out)


@needs_numba
def test_roots_reports_and_leave_times_are_the_same_with_and_without_numba() -> None:
    from iamp.planners import registry
    from iamp.planners.avoid.check import leave_time
    from iamp.planners.avoid.data import HalfPlane
    from iamp.planners.examples import overtake_three_problem

    cases = [(_polys(seed, degree=d), None, None) for seed in range(4) for d in (3, 7)]
    cases += [(None, *_hold_problem(seed, 1 + seed % 3)) for seed in range(6)]
    prob = overtake_three_problem()
    plan = registry.make_planner("qp-avoid", steps=30, hold="foh", solver="clarabel",
                                 safety="continuous").plan(prob)
    cases.append((None, prob, plan.trajectory))

    def outputs() -> list[object]:
        out: list[object] = []
        for C, problem, traj in cases:
            if C is not None:
                out.append(_hex(*pr.roots_in_unit_interval(C)))
            else:
                out.append(_report_hex(safety_report(problem, traj)))
                out.append([float(leave_time(traj, HalfPlane(v, a), problem.tf)).hex()
                            for v in problem.vehicles for a in ("x", "y")])
        return out

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(pr, "_PYTHON", True)
        python = outputs()
        assert pr.load() and not pr._PYTHON  # the compiled twins from here on
        assert outputs() == python


def _from_roots(roots: list[float], extra: list[complex], scale: float) -> np.ndarray:
    c = np.polynomial.polynomial.polyfromroots(np.r_[np.asarray(roots, dtype=complex), extra])
    return np.real(c) * scale


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.floats(0.02, 0.98), min_size=1, max_size=4, unique=True),
       st.lists(st.floats(1.3, 4.0), max_size=2),
       st.booleans(), st.floats(-3.0, 3.0))
def test_known_roots_in_the_interval_are_found_and_nothing_else(inside, outside, pair, log_scale):
    inside = sorted(inside)
    if np.min(np.diff(inside), initial=1.0) < 0.05:  # well separated: each root's conditioning bounded
        inside = inside[:1]
    extra = [complex(0.5, 0.3), complex(0.5, -0.3)] if pair else []  # a complex pair over the window
    C = _from_roots(inside + [-r for r in outside], extra, 10.0 ** log_scale)[None, :]
    rows, sig = pr.roots_in_unit_interval(C)
    assert set(rows.tolist()) <= {0}
    found = np.sort(sig)
    assert found.size == len(inside)
    assert np.max(np.abs(found - np.asarray(inside))) < 1e-9


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.integers(0, 2**31 - 1), st.integers(1, 7))
def test_random_polynomials_against_sampling_and_numpy_roots(seed, degree):
    rng = np.random.default_rng(seed)
    C = rng.normal(size=(8, degree + 1)) * 10.0 ** rng.uniform(-3, 3, (8, 1))
    rows, sig = pr.roots_in_unit_interval(C)
    x = np.linspace(0.0, 1.0, 20001)
    for r in range(C.shape[0]):
        mine = np.sort(sig[rows == r])
        ref = np.roots(C[r, ::-1])
        real = np.sort(ref.real[(np.abs(ref.imag) <= 1e-6) & (ref.real >= -1e-9) & (ref.real <= 1 + 1e-9)])
        p = np.polynomial.polynomial.polyval(x, C[r])
        size = np.polynomial.polynomial.polyval(x, np.abs(C[r]))  # the round-off scale of p
        # each strict sign change of the sampling holds a root found
        for k in np.flatnonzero(p[:-1] * p[1:] < 0):
            assert np.any((mine >= x[k] - 1e-9) & (mine <= x[k + 1] + 1e-9))
        # each root found is near a real root of numpy.roots, or p vanishes there to round-off
        for s in mine:
            near = real.size and np.min(np.abs(real - s)) < 1e-6
            tiny = abs(np.polynomial.polynomial.polyval(s, C[r])) <= 1e-8 * np.polynomial.polynomial.polyval(
                abs(s), np.abs(C[r]))
            assert near or tiny
        # and each simple root numpy finds well inside the window is found
        for s in real[(real > 1e-6) & (real < 1 - 1e-6)]:
            assert np.any(np.abs(mine - s) < 1e-6) or np.max(size) == 0
