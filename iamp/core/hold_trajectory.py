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

    The arrays are not changed after construction: :meth:`states` keeps per-piece rows computed
    from them on its first call.
    """

    t_nodes: FloatArray
    X: FloatArray
    U: FloatArray
    hold: str

    def _locate(self, t: ArrayLike) -> tuple[IntArray, FloatArray]:
        """Each time's piece ``k`` (the last node ``<= t``, clipped to ``0..N-1``: the count of the
        interior nodes ``<= t``) and its offset ``t − t_k``."""
        tt = np.atleast_1d(np.asarray(t, dtype=float))
        nodes = np.asarray(self.t_nodes, dtype=float)
        k = np.searchsorted(nodes[1:-1], tt, side="right").astype(np.int64, copy=False)
        return k, tt - nodes[k]

    def inputs(self, t: ArrayLike) -> FloatArray:
        """``(u_x, u_y)`` at the times ``t``, shape ``(len(t), 2)``."""
        k, dt = self._locate(t)
        if self.hold == "zoh":
            return np.asarray(self.U[k], dtype=float)
        nodes = np.asarray(self.t_nodes, dtype=float)
        h = nodes[k + 1] - nodes[k]  # the widths of the located pieces (np.diff(nodes)[k]: the same subtraction)
        u0 = self.U[k]
        return np.asarray(u0 + (self.U[k + 1] - u0) * (dt / h)[:, None], dtype=float)

    def _piece_rows(self) -> tuple[FloatArray, FloatArray]:
        """Per piece ``k`` (computed once per trajectory; its arrays are never changed in place):
        ``G1[k] = (v_x, u_x, v_y, u_y)`` at ``t_k``, the factors of ``δ`` in the state's columns,
        and ``G2[k]``, those of ``δ²/2``: FOH ``(u_x, u̇_x, u_y, u̇_y)``, ZOH ``(u_x, u_y)`` (the
        position's only), with ``u̇ = (u_{k+1} − u_k)/h_k`` (the same subtraction and division per
        piece as for the located pieces alone)."""
        rows = self.__dict__.get("_rows")
        if rows is None:
            nodes = np.asarray(self.t_nodes, dtype=float)
            n = nodes.size - 1
            U = self.U
            G1 = np.empty((n, 4), dtype=np.result_type(self.X, U))
            G1[:, 0::2] = self.X[:n, 1::2]
            G1[:, 1::2] = U[:n]
            if self.hold == "zoh":
                G2 = np.asarray(U[:n])
            else:
                G2 = np.empty((n, 4), dtype=G1.dtype)
                G2[:, 0::2] = U[:n]
                G2[:, 1::2] = (U[1:n + 1] - U[:n]) / (nodes[1:] - nodes[:-1])[:, None]
            rows = self.__dict__["_rows"] = (G1, G2)
        return rows

    def states(self, t: ArrayLike) -> FloatArray:
        """``(s_x, v_x, s_y, v_y)`` at the times ``t``, shape ``(len(t), 4)``.

        With ``δ = t − t_k``: ZOH ``v = v_k + u_k δ``, ``s = s_k + v_k δ + u_k δ²/2``; FOH
        ``v = v_k + u_k δ + u̇ δ²/2``, ``s = s_k + v_k δ + u_k δ²/2 + u̇ δ³/6``, each sum from the
        left, its terms computed for the four columns at once (:meth:`_piece_rows`)."""
        k, dt = self._locate(t)
        G1, G2 = self._piece_rows()
        d = dt[:, None]
        d2 = d**2
        out = self.X[k] + G1[k] * d  # (s + v δ, v + u δ)
        if self.hold == "zoh":
            out[:, 0::2] += G2[k] * d2 / 2
        else:
            g2 = G2[k]
            out += g2 * d2 / 2  # (u δ²/2, u̇ δ²/2)
            out[:, 0::2] += g2[:, 1::2] * d**3 / 6
        return out

    def cost(self) -> float:
        """``J = ½∫|u|²`` of the held input, exactly."""
        h = np.diff(self.t_nodes)[:, None]
        if self.hold == "zoh":
            return float(0.5 * np.sum(h * self.U**2))
        u0, u1 = self.U[:-1], self.U[1:]
        return float(np.sum(h / 6 * (u0**2 + u0 * u1 + u1**2)))
