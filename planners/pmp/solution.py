r"""The exact piecewise-polynomial solution of the PMP conditions for fixed contact times.

Per axis (column 0 = x, 1 = y): :math:`u(t) = a + bt - \sum_i \Phi_i (t-t_i)_+`, co-states
:math:`p_1 = b - \sum_i \Phi_{i,x} H(t-t_i)`, :math:`p_2 = -u_x` (``p3``, ``p4`` likewise), the
positions and speeds by integrating twice from the initial state.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from iamp.core.problem import Problem

from .jumps import jump_system

if TYPE_CHECKING:
    from .scale import Scaled

FloatArray = npt.NDArray[np.float64]


@dataclass
class PMPSolution:
    """Solution of the necessary + co-state jump conditions for fixed contact times.

    ``a = (−p2(0), −p4(0))``, ``b = (p1(0), p3(0))``, ``jumps[i] = (Φ_i,x, Φ_i,y)``; when
    solved in scaled units, ``scaled`` and ``z_scaled`` (rows ``ã, b̃, Φ̃``) keep the
    dimensionless solve for the self-check.
    """

    problem: Problem
    contact_times: FloatArray
    a: FloatArray
    b: FloatArray
    jumps: FloatArray
    scaled: Scaled | None = None
    z_scaled: FloatArray | None = None

    # --- trajectory -------------------------------------------------------------------
    def _ramps(self, t: FloatArray, power: int, side: str = "right") -> FloatArray:
        d = t[:, None] - self.contact_times[None, :]
        if power == 0:
            return (d > 0).astype(float) if side == "left" else (d >= 0).astype(float)
        out: FloatArray = np.maximum(d, 0.0) ** power
        return out

    def inputs(self, t: Any) -> FloatArray:
        """``(u_x, u_y)`` at times ``t`` → shape ``(len(t), 2)``."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        out: FloatArray = self.a[None, :] + self.b[None, :] * t[:, None] - self._ramps(t, 1) @ self.jumps
        return out

    def states(self, t: Any) -> FloatArray:
        """``(s_x, v_x, s_y, v_y)`` at times ``t`` → shape ``(len(t), 4)``."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        ego = self.problem.ego
        s0 = np.array([ego.x0, ego.y0])
        v0 = np.array([ego.vx0, ego.vy0])
        tt = t[:, None]
        v = v0 + self.a * tt + self.b * tt**2 / 2 - self._ramps(t, 2) @ self.jumps / 2
        s = s0 + v0 * tt + self.a * tt**2 / 2 + self.b * tt**3 / 6 - self._ramps(t, 3) @ self.jumps / 6
        return np.stack([s[:, 0], v[:, 0], s[:, 1], v[:, 1]], axis=1)

    def costates(self, t: Any, side: str = "right") -> FloatArray:
        """``(p1, p2, p3, p4)`` at ``t``; ``side`` picks the one-sided limit at a contact time.
        ``p1, p3`` from the jump rule; ``p2, p4`` by integrating ``ṗ2 = −p1`` from
        ``p2(0) = −a`` (not from ``u``), so ``∂H/∂u = u + p2`` is a real check."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        p13 = self.b[None, :] - self._ramps(t, 0, side) @ self.jumps
        p24 = -self.a[None, :] - self.b[None, :] * t[:, None] + self._ramps(t, 1) @ self.jumps
        return np.stack([p13[:, 0], p24[:, 0], p13[:, 1], p24[:, 1]], axis=1)

    def hamiltonian(self, t: Any, side: str = "right") -> FloatArray:
        """``H = ½|u|² + p1 v_x + p2 u_x + p3 v_y + p4 u_y`` (one-sided at contact times)."""
        X = self.states(t)
        U = self.inputs(t)
        p = self.costates(t, side)
        out: FloatArray = (0.5 * np.sum(U**2, axis=1) + p[:, 0] * X[:, 1] + p[:, 1] * U[:, 0]
                           + p[:, 2] * X[:, 3] + p[:, 3] * U[:, 1])
        return out

    # --- the conditions -----------------------------------------------------------------
    def system_residual(self) -> float:
        """max |M z − rhs| of the physical jump system at this solution."""
        M, rhs = jump_system(self.problem, self.contact_times)
        z = np.vstack([self.a, self.b, self.jumps])
        return float(np.max(np.abs(M @ z - rhs)))

    def cost(self) -> float:
        """Exact ``J = ½∫|u|²``: ``u`` is linear between breakpoints, so each piece
        contributes ``h/3·(u_0² + u_0u_1 + u_1²)``."""
        bp = np.sort(np.r_[0.0, self.contact_times, self.problem.tf])
        U = self.inputs(bp)
        h = np.diff(bp)[:, None]
        return float(0.5 * np.sum(h / 3 * (U[:-1] ** 2 + U[:-1] * U[1:] + U[1:] ** 2)))

    def hamiltonian_jump_terms(self) -> tuple[FloatArray, FloatArray]:
        r"""``(r, size)``: ``r_i = H⁻(t_i) − H⁺(t_i) − ẋ_s,i(t_i)Φ_i,x`` (= ``∂J/∂t_i``) and the
        size of its terms, :math:`|\Phi_{i,x}|(|v_x|+|\dot x_{s,i}|) + |\Phi_{i,y}||v_y|`."""
        t = self.contact_times
        Hm = self.hamiltonian(t, "left")
        Hp = self.hamiltonian(t, "right")
        xdot = np.array([float(v.speed(ti)) for v, ti in zip(self.problem.vehicles, t)])
        X = self.states(t)
        size = np.abs(self.jumps[:, 0]) * (np.abs(X[:, 1]) + np.abs(xdot)) + np.abs(self.jumps[:, 1]) * np.abs(X[:, 3])
        r: FloatArray = Hm - Hp - xdot * self.jumps[:, 0]
        return r, size

    def hamiltonian_jump_residual(self) -> FloatArray:
        """``r_i = H⁻(t_i) − H⁺(t_i) − ẋ_s,i(t_i)·Φ_i,x`` (= ``∂J/∂t_i``)."""
        return self.hamiltonian_jump_terms()[0]

    def residuals(self) -> dict[str, float]:
        """Max-abs residual (physical units) of every condition solved; the dimensionless
        checks are :func:`iamp.planners.pmp.verify.verify`."""
        prob = self.problem
        t = self.contact_times
        ends = self.states(np.array([0.0, prob.tf]))
        boundary = max(np.max(np.abs(ends[0] - prob.ego.initial)), np.max(np.abs(ends[1] - prob.ego.final)))
        X = self.states(t)
        interior = np.max(np.abs(X[:, [0, 2]] - prob.corners(t)))
        ts = np.linspace(0.0, prob.tf, 201)
        U, p = self.inputs(ts), self.costates(ts)
        h_min = np.max(np.abs(U + p[:, [1, 3]]))
        pl, pr = self.costates(t, "left"), self.costates(t, "right")
        jump = max(np.max(np.abs(pl[:, [0, 2]] - pr[:, [0, 2]] - self.jumps)),
                   np.max(np.abs(pl[:, [1, 3]] - pr[:, [1, 3]])))
        return {
            "linear_system": self.system_residual(),
            "boundary": float(boundary),
            "interior_constraint": float(interior),
            "h_minimisation": float(h_min),
            "costate_jump": float(jump),
            "hamiltonian_jump": float(np.max(np.abs(self.hamiltonian_jump_residual()))),
        }


class _FromKernel:
    """Non-data descriptor of :class:`OneVehicleSolution`: ``a``, ``b`` and ``z_scaled`` are
    made together on the first read of any of them and stored in the instance (later reads,
    and values set by the dataclass constructor, never reach the descriptor)."""

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    def __get__(self, obj: OneVehicleSolution | None, objtype: type | None = None) -> Any:
        if obj is None:
            return self
        d = obj.__dict__
        k, T, L = d.pop("_kernel")
        z = np.array([[k[1], k[2]], [k[3], k[4]], [k[5], k[6]]])
        d["z_scaled"] = z
        d["a"] = z[0] * (L / (T * T))
        d["b"] = z[1] * (L / (T * T * T))
        return d[self.name]


class OneVehicleSolution(PMPSolution):
    """A :class:`PMPSolution` of the one-vehicle kernel (:mod:`iamp.planners.pmp.one`) whose
    ``a``, ``b`` and ``z_scaled`` are built from the kernel's scaled numbers on first access.

    The planner's fast path returns plans whose callers mostly read only the contact time,
    the jumps and the cost; the arrays the trajectory needs are made when it is first
    evaluated, with the same products as an eager build (``ã·L/T²``, ``b̃·L/T³``), so the
    numbers do not depend on when they are made.  Constructed by :meth:`from_kernel`; the
    inherited dataclass constructor (used by :func:`dataclasses.replace`) sets every field
    and builds an ordinary, eager instance.
    """

    a = _FromKernel()
    b = _FromKernel()
    z_scaled = _FromKernel()

    @classmethod
    def from_kernel(cls, problem: Problem, contact_times: FloatArray, jumps: FloatArray,
                    kernel_out: Sequence[float], T: float, L: float) -> OneVehicleSolution:
        """The solution with contact times and jumps (physical units) given and ``ã, b̃, Φ̃``
        from ``kernel_out[1:7]`` (:func:`~iamp.planners.pmp.one.one_vehicle_kernel`)."""
        sol = cls.__new__(cls)
        d = sol.__dict__
        d["problem"] = problem
        d["contact_times"] = contact_times
        d["jumps"] = jumps
        d["scaled"] = None
        d["_kernel"] = (kernel_out, T, L)
        return sol
