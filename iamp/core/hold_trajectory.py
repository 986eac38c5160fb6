r"""The exact continuous-time trajectory of a held input on a grid (the discretised QP's plans),
evaluated by the core.

On a grid :math:`0 = t_0 < \dots < t_N = t_f` with steps :math:`h_k = t_{k+1} - t_k`, the
input is held per interval: ZOH, :math:`u(t) = u_k`; FOH,
:math:`u(t) = u_k + (u_{k+1} - u_k)(t - t_k)/h_k`.  Integrating the double integrator
exactly from the nodal state :math:`(s_k, v_k)` gives, with :math:`\delta = t - t_k`,

* ZOH: :math:`v = v_k + u_k\delta`, :math:`s = s_k + v_k\delta + u_k\delta^2/2`;
* FOH: :math:`v = v_k + u_k\delta + \dot u\,\delta^2/2`,
  :math:`s = s_k + v_k\delta + u_k\delta^2/2 + \dot u\,\delta^3/6`,
  :math:`\dot u = (u_{k+1} - u_k)/h_k`,

and the cost :math:`J = \tfrac12\int |u|^2` exactly: ZOH :math:`\tfrac12\sum_k h_k u_k^2`,
FOH :math:`\sum_k \tfrac{h_k}{6}(u_k^2 + u_k u_{k+1} + u_{k+1}^2)`.

:class:`HoldTrajectory` holds only numbers (the grid, the nodal states and inputs, the hold), so
a plan's safety report, peaks and samples evaluate a QP plan's trajectory here, without calling
back into the planner (``scripts/walk.py``: no upward call).  The QP builds it
(:mod:`iamp.planners.qp.hold` re-exports it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


@dataclass
class HoldTrajectory:
    """Exact continuous-time trajectory of a discrete solution under its input hold.

    Attributes
    ----------
    t_nodes : ndarray, shape (N+1,)
    X : ndarray, shape (N+1, 4)
        Nodal states ``(s_x, v_x, s_y, v_y)``.
    U : ndarray, shape (N, 2) for ZOH, (N+1, 2) for FOH
        Nodal inputs ``(u_x, u_y)``.
    hold : {"foh", "zoh"}
    """

    t_nodes: FloatArray
    X: FloatArray
    U: FloatArray
    hold: str

    def _locate(self, t: ArrayLike) -> tuple[FloatArray, IntArray, FloatArray, FloatArray]:
        tt = np.atleast_1d(np.asarray(t, dtype=float))
        nodes = np.asarray(self.t_nodes, dtype=float)
        # clip to [0, N - 1] (np.clip's numbers, without its wrapper's overhead)
        k = np.minimum(np.maximum(np.searchsorted(nodes, tt, side="right") - 1, 0), len(nodes) - 2)
        k = k.astype(np.int64, copy=False)
        # the widths of the located pieces only (np.diff(nodes)[k]: the same subtraction)
        nk = nodes[k]
        return tt, k, tt - nk, nodes[k + 1] - nk

    def inputs(self, t: ArrayLike) -> FloatArray:
        """``(u_x, u_y)`` at the times ``t``, shape ``(len(t), 2)``."""
        _, k, dt, h = self._locate(t)
        if self.hold == "zoh":
            return np.asarray(self.U[k], dtype=float)
        u0 = self.U[k]
        return np.asarray(u0 + (self.U[k + 1] - u0) * (dt / h)[:, None], dtype=float)

    def states(self, t: ArrayLike) -> FloatArray:
        """``(s_x, v_x, s_y, v_y)`` at the times ``t``, shape ``(len(t), 4)``."""
        _, k, dt, h = self._locate(t)
        Xk = self.X[k]
        s0 = Xk[:, 0::2]  # (s_x, s_y): the columns [0, 2] (a view, the same numbers)
        v0 = Xk[:, 1::2]
        d = dt[:, None]
        d2 = d**2
        if self.hold == "zoh":
            u = self.U[k]
            v = v0 + u * d
            s = s0 + v0 * d + u * d2 / 2
        else:
            u0 = self.U[k]
            du = (self.U[k + 1] - u0) / h[:, None]
            v = v0 + u0 * d + du * d2 / 2
            s = s0 + v0 * d + u0 * d2 / 2 + du * d**3 / 6
        out = np.empty((k.size, 4), dtype=np.result_type(s, v))
        out[:, 0::2] = s
        out[:, 1::2] = v
        return out

    def cost(self) -> float:
        """``J = ½∫|u|²`` of the held input, exactly."""
        h = np.diff(self.t_nodes)[:, None]
        if self.hold == "zoh":
            return float(0.5 * np.sum(h * self.U**2))
        u0, u1 = self.U[:-1], self.U[1:]
        return float(np.sum(h / 6 * (u0**2 + u0 * u1 + u1**2)))
