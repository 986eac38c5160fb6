r"""The physical jump system ``M z = rhs`` at given contact times (SPEC §2).

With :math:`u(t) = a + b t - \sum_j \Phi_j (t - t_j)_+` per axis, the interior-point
constraints :math:`s(t_j) = \text{corner}_j` and the final position and speed are linear in
:math:`z = (a, b, \Phi_1..\Phi_m)`.  Solved by :mod:`.fixed`, re-checked by
:meth:`.solution.PMPSolution.system_residual`.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from iamp.core.problem import Problem

FloatArray = npt.NDArray[np.float64]
ArrayLike = Any


def jump_system(problem: Problem, t: ArrayLike, corners: FloatArray | None = None) -> tuple[FloatArray, FloatArray]:
    """The linear system ``M z = rhs`` of the necessary and co-state jump conditions.

    Unknowns per axis (columns of ``z``): ``(a, b, Φ_1..Φ_m)``; rows: the ``m``
    interior-point constraints ``s(t_j) = corner_j``, then the final position and speed.
    ``corners``: ``problem.corners(t)`` if the caller has it already.
    """
    t = np.asarray(t, dtype=float)
    m, ego, T = problem.m, problem.ego, problem.tf
    M = np.empty((m + 2, m + 2))
    M[:m, 0] = t**2 / 2
    M[:m, 1] = t**3 / 6
    M[:m, 2:] = -np.maximum(t[:, None] - t[None, :], 0.0) ** 3 / 6
    M[m] = np.r_[T**2 / 2, T**3 / 6, -((T - t) ** 3) / 6]
    M[m + 1] = np.r_[T, T**2 / 2, -((T - t) ** 2) / 2]
    C = problem.corners(t) if corners is None else corners
    rhs = np.empty((m + 2, 2))
    rhs[:m, 0] = C[:, 0] - ego.x0 - ego.vx0 * t
    rhs[:m, 1] = C[:, 1] - ego.y0 - ego.vy0 * t
    rhs[m] = [ego.xf - ego.x0 - ego.vx0 * T, ego.yf - ego.y0 - ego.vy0 * T]
    rhs[m + 1] = [ego.vxf - ego.vx0, ego.vyf - ego.vy0]
    return M, rhs
