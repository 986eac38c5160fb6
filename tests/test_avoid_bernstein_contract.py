"""The contract of :func:`iamp.planners.avoid.bernstein.piece_matrix` beyond its values (the
values are checked against scipy's Hermite cubic in tests/test_avoid_continuous.py): a degree
below the cubic's is refused, and the default degree is the cubic's own (3).  Both were
surviving mutants of ``scripts/mutation_score.py planners/avoid/bernstein.py``."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.interpolate import CubicHermiteSpline

from iamp.planners.avoid.bernstein import piece_matrix


@pytest.mark.parametrize("degree", [0, 1, 2])
def test_a_degree_below_three_is_refused(degree: int) -> None:
    with pytest.raises(ValueError, match="at least 3"):
        piece_matrix(0.5, 0.0, 1.0, degree)


def test_the_default_degree_is_three_and_reproduces_the_cubic() -> None:
    h, nodes = 0.7, np.array([1.0, -2.0, 0.5, 3.0])  # (s_k, v_k, s_{k+1}, v_{k+1})
    M = piece_matrix(h, 0.2, 0.9)
    assert M.shape == (4, 4)
    coef = M @ nodes
    rho = np.linspace(0.0, 1.0, 11)
    basis = np.array([[1, 3, 3, 1][r] * rho**r * (1 - rho) ** (3 - r) for r in range(4)])
    exact = CubicHermiteSpline([0.0, h], nodes[[0, 2]], nodes[[1, 3]])((0.2 + 0.7 * rho) * h)
    assert np.max(np.abs(coef @ basis - exact)) < 1e-12
