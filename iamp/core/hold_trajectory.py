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
IntArray = NDArray[np.intp]


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
        interior nodes ``<= t``) and its offset ``t − t_k`` (a scalar ``t`` as one time, as
        ``numpy.atleast_1d`` makes it; ``take`` copies the nodes that indexing with ``k`` would)."""
        tt = np.asarray(t, dtype=float)
        if tt.ndim == 0:
            tt = tt.reshape(1)
        nodes = np.asarray(self.t_nodes, dtype=float)
        k = nodes[1:-1].searchsorted(tt, side="right")
        return k, tt - nodes.take(k)

    def _cached(self, name: str) -> FloatArray | None:
        """The per-piece rows kept under ``name`` by a first call (never changed in place)."""
        rows: FloatArray | None = self.__dict__.get(name)
        return rows

    def inputs(self, t: ArrayLike) -> FloatArray:
        """``(u_x, u_y)`` at the times ``t``, shape ``(len(t), 2)``.

        ZOH ``u_k``; FOH ``u_k + (u_{k+1} − u_k)(δ / h_k)``, ``δ = t − t_k``, from the located
        piece's row of :meth:`_input_rows` (the same subtractions per piece as for the located
        pieces alone, so the same numbers)."""
        k, dt = self._locate(t)
        if self.hold == "zoh":
            return np.asarray(np.asarray(self.U).take(k, 0), dtype=float)
        r = self._input_rows().take(k, 0)
        u0 = r[:, :2]
        return np.asarray(u0 + r[:, 2:4] * (dt / r[:, 4])[:, None], dtype=float)

    def _input_rows(self) -> FloatArray:
        """Per FOH piece ``k`` (computed once per trajectory): ``(u_k, u_{k+1} − u_k, h_k)``,
        ``h_k = t_{k+1} − t_k``, five columns."""
        rows = self._cached("_inrows")
        if rows is None:
            nodes = np.asarray(self.t_nodes, dtype=float)
            n = nodes.size - 1
            U = np.asarray(self.U)
            rows = np.empty((n, 5), dtype=np.result_type(U, nodes))
            rows[:, :2] = U[:n]
            rows[:, 2:4] = U[1:n + 1] - U[:n]
            rows[:, 4] = nodes[1:] - nodes[:-1]
            self.__dict__["_inrows"] = rows
        return rows

    def _piece_rows(self) -> FloatArray:
        """Per piece ``k`` (computed once per trajectory; never changed in place), one row:
        the nodal state ``X[k]`` (4 columns), ``G1[k] = (v_x, u_x, v_y, u_y)`` at ``t_k``, the
        factors of ``δ`` in the state's columns (4), and ``G2[k]``, those of ``δ²/2``: FOH
        ``(u_x, u̇_x, u_y, u̇_y)`` (4), ZOH ``(u_x, u_y)`` (2, the position's only), with
        ``u̇ = (u_{k+1} − u_k)/h_k`` (the same subtraction and division per piece as for the
        located pieces alone).  One ``take`` of these rows gives what indexing ``X``, ``G1`` and
        ``G2`` with ``k`` would, in one call."""
        rows = self._cached("_state_rows")
        if rows is None:
            nodes = np.asarray(self.t_nodes, dtype=float)
            n = nodes.size - 1
            X, U = np.asarray(self.X), np.asarray(self.U)
            zoh = self.hold == "zoh"
            rows = np.empty((n, 10 if zoh else 12), dtype=np.result_type(X, U))
            rows[:, :4] = X[:n]
            rows[:, 4:8:2] = X[:n, 1::2]
            rows[:, 5:8:2] = U[:n]
            if zoh:
                rows[:, 8:] = U[:n]
            else:
                rows[:, 8::2] = U[:n]
                rows[:, 9::2] = (U[1:n + 1] - U[:n]) / (nodes[1:] - nodes[:-1])[:, None]
            self.__dict__["_state_rows"] = rows
        return rows

    def states(self, t: ArrayLike) -> FloatArray:
        """``(s_x, v_x, s_y, v_y)`` at the times ``t``, shape ``(len(t), 4)``.

        With ``δ = t − t_k``: ZOH ``v = v_k + u_k δ``, ``s = s_k + v_k δ + u_k δ²/2``; FOH
        ``v = v_k + u_k δ + u̇ δ²/2``, ``s = s_k + v_k δ + u_k δ²/2 + u̇ δ³/6``, each sum from the
        left, its terms computed for the four columns at once (:meth:`_piece_rows`)."""
        k, dt = self._locate(t)
        r = self._piece_rows().take(k, 0)
        d = dt[:, None]
        d2 = d**2
        out = r[:, :4] + r[:, 4:8] * d  # (s + v δ, v + u δ)
        g2 = r[:, 8:]
        if self.hold == "zoh":
            out[:, 0::2] += g2 * d2 / 2
        else:
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
