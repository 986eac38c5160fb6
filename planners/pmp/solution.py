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

from iamp.core.contact import corners_and_speeds
from iamp.core.jump_trajectory import JumpSamples, JumpTrajectory
from iamp.core.problem import Problem

from .jumps import jump_system

if TYPE_CHECKING:
    from .scale import Scaled

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class Evaluation:
    """What the checks read of a solution (:meth:`PMPSolution.evaluate`): the corners and the
    vehicles' speeds at the contact times, the sorted breakpoints ``0, t_i, t_f`` and the
    trajectory's samples at ``0, t_f``, the contact times, those breakpoints and (dense) 201
    uniform times, in that order."""

    corners: FloatArray
    xdot: FloatArray
    breakpoints: FloatArray
    samples: JumpSamples


@dataclass
class PMPSolution(JumpTrajectory):
    """Solution of the necessary + co-state jump conditions for fixed contact times.

    Its trajectory (``inputs``, ``states``, ``costates``, ``hamiltonian``) is evaluated by
    :class:`iamp.core.jump_trajectory.JumpTrajectory`, in the core.

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

    # --- the conditions -----------------------------------------------------------------
    def system_residual(self, corners: FloatArray | None = None) -> float:
        """max |M z − rhs| of the physical jump system at this solution (``corners``: the
        problem's corners at the contact times, if the caller has them)."""
        M, rhs = jump_system(self.problem, self.contact_times, corners)
        z = np.vstack([self.a, self.b, self.jumps])
        return float(np.max(np.abs(M @ z - rhs)))

    def cost(self) -> float:
        """Exact ``J = ½∫|u|²``: ``u`` is linear between breakpoints, so each piece
        contributes ``h/3·(u_0² + u_0u_1 + u_1²)``."""
        bp = np.sort(np.r_[0.0, self.contact_times, self.problem.tf])
        U = self.inputs(bp)
        h = np.diff(bp)[:, None]
        return float(0.5 * np.sum(h / 3 * (U[:-1] ** 2 + U[:-1] * U[1:] + U[1:] ** 2)))

    def hamiltonian_jump_terms(self, xdot: FloatArray | None = None) -> tuple[FloatArray, FloatArray]:
        r"""``(r, size)``: ``r_i = H⁻(t_i) − H⁺(t_i) − ẋ_s,i(t_i)Φ_i,x`` (= ``∂J/∂t_i``) and the
        size of its terms, :math:`|\Phi_{i,x}|(|v_x|+|\dot x_{s,i}|) + |\Phi_{i,y}||v_y|`
        (``xdot``: the vehicles' speeds at the contact times, if the caller has them)."""
        t = self.contact_times
        Hm = self.hamiltonian(t, "left")
        Hp = self.hamiltonian(t, "right")
        if xdot is None:
            xdot = np.array([float(v.speed(ti)) for v, ti in zip(self.problem.vehicles, t)])
        X = self.states(t)
        size = np.abs(self.jumps[:, 0]) * (np.abs(X[:, 1]) + np.abs(xdot)) + np.abs(self.jumps[:, 1]) * np.abs(X[:, 3])
        r: FloatArray = Hm - Hp - xdot * self.jumps[:, 0]
        return r, size

    def hamiltonian_jump_residual(self) -> FloatArray:
        """``r_i = H⁻(t_i) − H⁺(t_i) − ẋ_s,i(t_i)·Φ_i,x`` (= ``∂J/∂t_i``)."""
        return self.hamiltonian_jump_terms()[0]

    def evaluate(self, dense: bool = False) -> Evaluation:
        """The problem's corners and speeds at the contact times (one read) and the trajectory
        at ``0, t_f``, the contact times, the sorted breakpoints ``0, t_i, t_f`` and, with
        ``dense``, 201 uniform times (one call of
        :meth:`~iamp.core.jump_trajectory.JumpTrajectory.samples`; every row is computed on its
        own, so the numbers do not depend on which points are asked together)."""
        prob = self.problem
        t = self.contact_times
        corners, xdot = corners_and_speeds(prob, t)
        bp = np.sort(np.r_[0.0, t, prob.tf])
        pts = [np.array([0.0, prob.tf]), t, bp]
        if dense:
            pts.append(np.linspace(0.0, prob.tf, 201))
        return Evaluation(corners, xdot, bp, self.samples(np.concatenate(pts)))

    def residuals(self) -> dict[str, float]:
        """Max-abs residual (physical units) of every condition solved; the dimensionless
        checks are :func:`iamp.planners.pmp.verify.verify`."""
        return self.residuals_and_jumps()[0]

    def residuals_and_jumps(self, ev: Evaluation | None = None) -> tuple[dict[str, float], FloatArray]:
        """``(residuals(), hamiltonian_jump_residual())`` from one :meth:`evaluate` (``dense``;
        ``ev`` if the caller has it): the problem's corners and speeds read once and the
        trajectory evaluated once (the same numbers)."""
        prob = self.problem
        ev = self.evaluate(dense=True) if ev is None else ev
        at, corners, xdot = ev.samples, ev.corners, ev.xdot
        m = self.contact_times.shape[0]
        hj: FloatArray = at.h_left - at.h_right - xdot * self.jumps[:, 0]
        ends = at.states[:2]
        boundary = max(np.max(np.abs(ends[0] - prob.ego.initial)), np.max(np.abs(ends[1] - prob.ego.final)))
        X = at.states[2:2 + m]
        interior = np.max(np.abs(X[:, [0, 2]] - corners))
        U, p = at.inputs[4 + 2 * m:], at.costates[4 + 2 * m:]
        h_min = np.max(np.abs(U + p[:, [1, 3]]))
        pl, pr = at.costates_left, at.costates[2:2 + m]
        jump = max(np.max(np.abs(pl[:, [0, 2]] - pr[:, [0, 2]] - self.jumps)),
                   np.max(np.abs(pl[:, [1, 3]] - pr[:, [1, 3]])))
        return {
            "linear_system": self.system_residual(corners),
            "boundary": float(boundary),
            "interior_constraint": float(interior),
            "h_minimisation": float(h_min),
            "costate_jump": float(jump),
            "hamiltonian_jump": float(np.max(np.abs(hj))),
        }, hj


class _FromKernel:
    """Non-data descriptor of :class:`OneVehicleSolution`: ``a``, ``b`` and ``z_scaled`` are
    made together on the first read of any of them and stored in the instance (later reads,
    and values set by the dataclass constructor, never reach the descriptor)."""

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    def __get__(self, obj: OneVehicleSolution | None, objtype: type | None = None) -> Any:
        if obj is None:
            return self
        _fill(obj)
        return obj.__dict__[self.name]


def _fill(obj: OneVehicleSolution) -> None:
    """Make ``a``, ``b`` and ``z_scaled`` from the kernel's numbers (once)."""
    d = obj.__dict__
    if "_kernel" not in d:
        return
    k, T, L = d.pop("_kernel")
    z = np.array([[k[1], k[2]], [k[3], k[4]], [k[5], k[6]]])
    d["z_scaled"] = z
    d["a"] = z[0] * (L / (T * T))
    d["b"] = z[1] * (L / (T * T * T))


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

    @classmethod
    def checked_from_kernel(cls, problem: Problem, contact_times: FloatArray, jumps: FloatArray,
                            kernel_out: Sequence[float], T: float, L: float
                            ) -> tuple[OneVehicleSolution, dict[str, float], FloatArray, Evaluation]:
        """:meth:`from_kernel` with its :meth:`residuals_and_jumps` and the :meth:`evaluate` they
        read (the planner's diagnostics, one call: the solution's arrays are made here)."""
        sol = cls.from_kernel(problem, contact_times, jumps, kernel_out, T, L)
        _fill(sol)  # here, not on the core's first evaluation of the trajectory
        with np.errstate(all="ignore"):
            ev = sol.evaluate(dense=True)
            residuals, hj = sol.residuals_and_jumps(ev)
        return sol, residuals, hj, ev
