r"""The vehicles at their contact times: the corners ``(x_s,i(t_i) ± (L_i/2 + S_x,i), y_s,i ± (W_i/2 + S_y,i))``
and the speeds ``ẋ_s,i(t_i)`` a plan's interior-point constraints and jumps read (SPEC §2).

One function per question over all vehicles, so that a planner reads the vehicles at its contact
times in one call (``scripts/walk.py``: the planner does not go back into :mod:`iamp.core.problem`,
whose objects only carry their coefficients and attributes); :meth:`Problem.corners` and
:meth:`Problem.corners_and_speeds` are these functions.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

if TYPE_CHECKING:
    from iamp.core.problem import Problem

__all__ = ["corners", "corners_and_speeds"]


def corners(problem: Problem, contact_times: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """Corner positions ``(m, 2)``: row ``i`` is ``(x_s,i(t_i) + offset_x,i, corner_y,i)``."""
    t = np.asarray(contact_times, dtype=float)
    P = np.polynomial.polynomial
    return np.array([[np.asarray(P.polyval(np.asarray(ti, dtype=np.float64), v.x_poly), dtype=np.float64)
                      + v.offset_x, v.corner_y] for v, ti in zip(problem.vehicles, t)])


def corners_and_speeds(problem: Problem, contact_times: npt.ArrayLike) -> tuple[npt.NDArray[np.float64],
                                                                              npt.NDArray[np.float64]]:
    """``(corners(t), [ẋ_s,i(t_i)])`` in one call (``ẋ_s = 0`` for a constant ``x_s``)."""
    t = np.asarray(contact_times, dtype=float)
    P = np.polynomial.polynomial
    speeds = [float(np.asarray(P.polyval(np.asarray(ti, dtype=np.float64),
                                         P.polyder(v.x_poly) if len(v.x_poly) > 1 else [0.0]), dtype=np.float64))
              for v, ti in zip(problem.vehicles, t)]
    return corners(problem, t), np.array(speeds)
