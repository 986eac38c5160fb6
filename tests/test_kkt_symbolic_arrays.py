"""The direct backend's symbolic analysis builds its KKT pattern and each connected component's
submatrix from the arrays (:func:`~iamp.planners.qp.backends.kkt_symbolic._pattern`,
:func:`~iamp.planners.qp.backends.kkt_symbolic._component`): the arrays scipy's COO conversion and
fancy indexing give, bit for bit, so the reverse Cuthill-McKee orders, and with them every
factorisation, are those of the scipy construction."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from iamp.planners.qp.backends.kkt_symbolic import _component, _pattern


@pytest.mark.parametrize("seed", range(30))
def test_pattern_and_components_are_scipys_arrays(seed: int) -> None:
    rng = np.random.default_rng(seed)
    nk, k = int(rng.integers(1, 80)), int(rng.integers(0, 300))
    r, c = rng.integers(0, nk, k), rng.integers(0, nk, k)  # repeated entries too
    rows, cols = np.concatenate([r, c, np.arange(nk)]), np.concatenate([c, r, np.arange(nk)])  # symmetric
    ref = sp.csr_matrix((np.ones(rows.size), (rows, cols)), shape=(nk, nk))
    got = _pattern(rows, cols, nk)
    pairs = [(ref, got)]
    ncomp, label = connected_components(ref, directed=False)
    for comp in range(ncomp):
        nodes = np.flatnonzero(label == comp)
        pairs.append((sp.csr_matrix(ref[nodes][:, nodes]), _component(ref, nodes)))
    for a, b in pairs:
        assert a.shape == b.shape
        for name in ("data", "indices", "indptr"):
            x, y = getattr(a, name), getattr(b, name)
            assert x.dtype == y.dtype and np.array_equal(x, y)
