"""The ``m ≥ 2`` contact-time search written once (issue 32): its kernels
(:mod:`iamp.planners.pmp.search_kernels`) run as Python by default and, opt-in, compiled by
numba from the same code objects (:func:`iamp.planners.pmp.compiled.load_search`).  The
search is run here in a subprocess with the kernels compiled and as Python, and every number
(contact times, costs, statuses, box counts, box bounds) must be equal bit for bit: no result
depends on whether numba is installed or loaded."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from iamp.planners.examples import random_problem
from iamp.planners.pmp import compiled
from iamp.planners.pmp import search_kernels as sk
from iamp.planners.pmp.fixed import ValueFunction, bridge_kernel

SCRIPT = r"""
import json, sys
import numpy as np
from iamp.planners.examples import random_problem
from iamp.planners.pmp import compiled
from iamp.planners.pmp.bound import lower_bound
from iamp.planners.pmp.fixed import ValueFunction
from iamp.planners.pmp.planner import PMPPlanner

if sys.argv[1] == "twin":
    assert compiled.load_search(), compiled._STATE.get("error")
hexes = lambda xs: [float(x).hex() for x in np.ravel(xs)]
out = {"plans": [], "bounds": []}
cases = [(2, s) for s in range(int(sys.argv[2]))] + [(3, s) for s in range(int(sys.argv[3]))]
for m, seed in cases:
    p = random_problem(seed, m=m)
    plan = PMPPlanner().plan(p, diagnostics=False)
    out["plans"].append([plan.status, plan.diagnostics.search.get("boxes"), *hexes(plan.contact_times),
                         *hexes([plan.cost])])
    vf = ValueFunction(p)
    rng = np.random.default_rng(seed)
    c = rng.uniform(0.05, 0.95, (40, m))
    r = rng.uniform(1e-4, 0.05, (40, m))
    out["bounds"].append(hexes(lower_bound(vf, c, r)) + hexes(vf.quad_sigma(c)) + hexes(vf.gradient_sigma(c)))
print(json.dumps(out))
"""


def _run(mode: str, disable_jit: bool, m2: int, m3: int) -> dict[str, list[list[object]]]:
    env = {**os.environ, "NUMBA_DISABLE_JIT": "1" if disable_jit else "0"}
    res = subprocess.run([sys.executable, "-c", SCRIPT, mode, str(m2), str(m3)], capture_output=True, text=True,
                         env=env, timeout=900)
    assert res.returncode == 0, res.stderr[-2000:]
    out: dict[str, list[list[object]]] = json.loads(res.stdout)
    return out


needs_numba = pytest.mark.skipif(not compiled.numba_available(), reason="numba is not installed")


@needs_numba
def test_the_search_twins_as_python_equal_the_default_path_bit_for_bit() -> None:
    """``NUMBA_DISABLE_JIT=1``: the twins built by :func:`iamp.planners.pmp.jit.twin` (the code
    objects with their globals swapped) run as Python and equal the planner's path."""
    ref = _run("pure", True, 3, 0)
    assert [row[0] for row in ref["plans"]] == ["optimal"] * 3
    assert _run("twin", True, 3, 0) == ref


@pytest.mark.slow
@needs_numba
def test_the_compiled_search_equals_the_python_search_bit_for_bit() -> None:
    """numba's machine code (compiled in the subprocess, about a minute) against the same
    source run as Python: two- and three-vehicle plans, their certificates and box bounds."""
    assert _run("twin", False, 6, 2) == _run("pure", True, 6, 2)


def test_the_column_cholesky_solves_the_kernel_systems() -> None:
    """``q = eᵀK⁻¹e`` and ``K⁻¹e`` of :func:`~iamp.planners.pmp.search_kernels.chol` against
    numpy's solve (an independent LAPACK path) at random distinct times, m = 1..4."""
    rng = np.random.default_rng(1)
    for m in (1, 2, 3, 4):
        sig = rng.uniform(0.02, 0.98, (30, m))
        K = bridge_kernel(sig[:, :, None], sig[:, None, :], 1.0)
        e = rng.normal(size=(30, m))
        L, ok = sk.chol(np.ascontiguousarray(np.moveaxis(K, 0, -1)))
        w = sk.backward(L, sk.forward(L, np.ascontiguousarray(e.T))).T
        ref = np.linalg.solve(K, e[..., None])[..., 0]
        assert ok.all()
        assert np.allclose(w, ref, rtol=1e-7, atol=1e-9 * np.max(np.abs(ref)))


def test_the_value_function_and_gradient_agree_with_finite_differences_and_numpy() -> None:
    """``quad_sigma`` equals ``Σ eᵀK⁻¹e`` by numpy, and ``gradient_sigma`` its central
    difference (three vehicles)."""
    vf = ValueFunction(random_problem(4, m=3))
    rng = np.random.default_rng(2)
    sig = rng.uniform(0.1, 0.9, (20, 3))
    ex, ey = vf.errors_sigma(sig)
    K = bridge_kernel(sig[:, :, None], sig[:, None, :], 1.0)
    ref = sum(np.sum(e * np.linalg.solve(K, e[..., None])[..., 0], axis=1) for e in (ex, ey))
    assert np.allclose(vf.quad_sigma(sig), ref, rtol=1e-9)
    h = 1e-6
    g = vf.gradient_sigma(sig)
    for k in range(3):
        d = np.zeros(3)
        d[k] = h
        fd = 0.5 * (vf.quad_sigma(sig + d) - vf.quad_sigma(sig - d)) / (2 * h)
        assert np.allclose(g[:, k], fd, rtol=1e-5, atol=1e-6 * np.max(np.abs(fd)))


def test_the_least_eigenvalue_by_jacobi_is_numpys() -> None:
    """:func:`~iamp.planners.pmp.search_kernels.min_eig` (the basin box's curvature) against
    ``numpy.linalg.eigvalsh`` on random symmetric matrices up to 5 × 5."""
    rng = np.random.default_rng(3)
    for m in (1, 2, 3, 5):
        for _ in range(20):
            A = rng.normal(size=(m, m))
            H = A + A.T
            assert abs(sk.min_eig(H) - np.linalg.eigvalsh(H)[0]) <= 1e-12 * max(1.0, np.max(np.abs(H)))
