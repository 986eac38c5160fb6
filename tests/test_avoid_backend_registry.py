"""The avoidance QP solves through the one QP backend registry (issue 32 item 1).

* ``BoundSolver`` holds a registry backend (no solver package is called from
  ``planners/avoid``), with the avoidance's OSQP tolerances added to the registry defaults;
* Clarabel's bound-only updates of the general form ``l <= Az <= u`` equal a fresh set-up even
  when a row's side turns finite or infinite (before: the row split of set-up was kept, so a
  bound that became finite was silently dropped, and a problem with a free row was stacked as
  an equality on ``-inf``);
* the fixed-pattern value updates (``set_values``) equal a fresh set-up on every backend.
"""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as hs

from iamp.core import status as st
from iamp.planners.avoid.solve import AVOID_SETTINGS, BoundSolver
from iamp.planners.qp.backends import ITERATIVE, QPBackend, get_backend

AVOID_DIR = Path(__file__).resolve().parents[1] / "planners" / "avoid"


def test_no_solver_package_is_imported_by_the_avoidance():
    """One QP stack: planners/avoid reaches OSQP, Clarabel and PIQP only through the registry."""
    for path in AVOID_DIR.glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module or ""] if isinstance(node, ast.ImportFrom) else [])
            for name in names:
                assert name.split(".")[0] not in ("osqp", "clarabel", "piqp"), (path.name, name)


@pytest.mark.parametrize("name", ITERATIVE)
def test_bound_solver_holds_a_registry_backend_with_the_avoidance_settings(name):
    P = sp.triu(sp.identity(2, format="csc"), format="csc")
    A = sp.csc_matrix(np.array([[1.0, 1.0], [1.0, 0.0]]))
    s = BoundSolver(name, P, A, np.array([2.0]), np.array([0.5]))
    assert isinstance(s.backend, QPBackend) and s.backend.name == name
    for k, v in AVOID_SETTINGS.get(name, {}).items():
        assert s.settings[k] == v
    sol = s.solve()
    assert sol.status == st.OPTIMAL
    np.testing.assert_allclose(sol.z, [0.5, 1.5], atol=1e-6)  # min ½|z|² s.t. z0 + z1 = 2, z0 <= 0.5
    s.set_upper(np.array([5.0]))  # inactive now: z = (1, 1)
    np.testing.assert_allclose(s.solve().z, [1.0, 1.0], atol=1e-6)


def test_osqp_avoidance_settings_are_the_registry_defaults_plus_two_tolerances():
    P = sp.triu(sp.identity(2, format="csc"), format="csc")
    A = sp.csc_matrix(np.array([[1.0, 1.0], [1.0, 0.0]]))
    s = BoundSolver("osqp", P, A, np.array([2.0]), np.array([0.5]))
    defaults = get_backend("osqp").default_settings()
    assert s.settings == {**defaults, "eps_abs": 1e-7, "max_iter": 50_000}


@settings(max_examples=25, deadline=None)
@given(seed=hs.integers(0, 10_000), steps=hs.lists(hs.lists(hs.sampled_from(["inf", "tight", "loose"]),
                                                            min_size=4, max_size=4), min_size=1, max_size=3))
def test_clarabel_bound_updates_equal_a_fresh_setup(seed, steps):
    """Property: after any sequence of upper-bound updates (sides turning finite or infinite, a
    free row at set-up), Clarabel's updated solver equals a fresh one on the same data."""
    rng = np.random.default_rng(seed)
    n, n_in = 4, 4
    M = rng.normal(size=(n, n))
    P = sp.triu(sp.csc_matrix(M @ M.T + np.eye(n)), format="csc")
    q = rng.normal(size=n)
    A = sp.csc_matrix(np.r_[rng.normal(size=(1, n)), rng.normal(size=(n_in, n))])
    l = np.r_[0.0, np.full(n_in, -np.inf)]
    u0 = np.r_[0.0, np.full(n_in, np.inf)]  # free rows at set-up
    b = get_backend("clarabel")(P, q, A, l, u0)
    for step in steps:
        u = np.r_[0.0, [np.inf if w == "inf" else (-0.1 if w == "tight" else 10.0) for w in step]]
        b.update(u=u)
        got = b.solve()
        ref = get_backend("clarabel")(P, q, A, l, u).solve()
        assert got.status == ref.status
        if ref.status == st.OPTIMAL:
            np.testing.assert_allclose(got.z, ref.z, rtol=1e-7, atol=1e-8)
            np.testing.assert_allclose(got.y, ref.y, rtol=1e-6, atol=1e-7)


@pytest.mark.parametrize("name", ITERATIVE)
def test_fixed_pattern_value_updates_equal_a_fresh_setup(name):
    """``set_values`` (new ``A`` values, explicit zeros kept, and new bounds) = a new BoundSolver."""
    rng = np.random.default_rng(3)
    n = 6
    M = rng.normal(size=(n, n))
    P = sp.triu(sp.csc_matrix(M @ M.T + np.eye(n)), format="csc")
    dense = np.r_[rng.normal(size=(2, n)), rng.normal(size=(3, n))]
    dense[3] = 0.0  # a zero row on the pattern (an inactive block): "0 <= 1"
    mask = np.ones_like(dense, dtype=bool)
    A = sp.csc_matrix((dense[mask], np.nonzero(mask)), shape=dense.shape)  # explicit zeros stored
    b_eq = rng.normal(size=2)
    s = BoundSolver(name, P, A, b_eq, np.array([0.5, 1.0, 0.3]))
    first = s.solve()
    assert first.status == st.OPTIMAL
    A2 = A.copy()
    A2.data = A2.data + rng.normal(scale=0.1, size=A2.data.size)  # the zero row gets values too
    u2 = np.array([0.2, 0.1, 0.4])
    s.set_values(A2, u2)
    got = s.solve()
    ref = BoundSolver(name, P, A2, b_eq, u2).solve()
    assert got.status == ref.status == st.OPTIMAL
    np.testing.assert_allclose(got.z, ref.z, rtol=1e-6, atol=1e-7)
