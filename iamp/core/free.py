r"""The unconstrained minimum-energy transfer: one cubic per axis (the one place it is written).

With :math:`\dot s = v,\ \dot v = u` and :math:`J = \tfrac12\int_0^{t_f} u^2\,dt`, the minimiser
with fixed end states :math:`(s_0, v_0) \to (s_f, v_f)` has a linear input, so a cubic position

.. math::  s(t) = s_0 + v_0 t + c_2 t^2 + c_3 t^3,\quad
           c_2 = \frac{3e - g t_f}{t_f^2},\ c_3 = \frac{-2e + g t_f}{t_f^3},\quad
           e = s_f - s_0 - v_0 t_f,\ g = v_f - v_0,

with cost :math:`J = 6 e^2/t_f^3 - 6 e g/t_f^2 + 2 g^2/t_f` per axis.  The PMP uses it as the
reference path (in physical and in scaled time, :math:`t_f = 1`), the closed loop as the plan when
no vehicle is constrained, and a :class:`~iamp.core.problem.Problem` with zero vehicles is solved
by it exactly (:func:`free_plan`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from iamp.core.diagnostics import Diagnostics
from iamp.core.plan import Plan
from iamp.core.problem import EgoBoundary, Problem
from iamp.core.status import NUMERICAL_ERROR, OPTIMAL
from iamp.core.tolerances import tol

FloatArray = NDArray[np.float64]
#: A float or an array of floats (the formulas are elementwise).
Num = TypeVar("Num", float, FloatArray, Any)


def min_energy_cubic(s0: Num, v0: Num, sf: Num, vf: Num, tf: float = 1.0) -> tuple[Num, Num, Num, Num]:
    """Ascending coefficients ``(s0, v0, c2, c3)`` of the minimum-energy path (module docstring).

    Elementwise: floats give floats, arrays give arrays of coefficients.  ``tf = 1`` is the
    scaled-time form (:math:`c_2 = 3e - g`, :math:`c_3 = -2e + g`, bit for bit).
    """
    e = sf - s0 - v0 * tf
    g = vf - v0
    return s0, v0, (3 * e - g * tf) / tf**2, (-2 * e + g * tf) / tf**3


def transfer_cost(s0: Any, v0: Any, sf: Any, vf: Any, T: Any) -> Any:
    r"""Minimum of :math:`\tfrac12\int_0^T u^2` taking ``(s0, v0)`` to ``(sf, vf)`` in ``T``:
    :math:`6e^2/T^3 - 6eg/T^2 + 2g^2/T` with :math:`e = s_f - s_0 - v_0T`, :math:`g = v_f - v_0`."""
    e = sf - s0 - v0 * T
    g = vf - v0
    return 6 * e**2 / T**3 - 6 * e * g / T**2 + 2 * g**2 / T


@dataclass(frozen=True)
class FreeTrajectory:
    """The unconstrained minimum-energy trajectory: the cubic of each axis.

    Attributes
    ----------
    cx, cy : ndarray, shape (4,)
        Ascending coefficients of :math:`s_x(t)` and :math:`s_y(t)`.
    """

    cx: FloatArray
    cy: FloatArray

    @classmethod
    def of(cls, ego: EgoBoundary) -> FreeTrajectory:
        """The trajectory between the ego's boundary states."""
        return cls(np.array(min_energy_cubic(ego.x0, ego.vx0, ego.xf, ego.vxf, ego.tf)),
                   np.array(min_energy_cubic(ego.y0, ego.vy0, ego.yf, ego.vyf, ego.tf)))

    def states(self, t: ArrayLike) -> FloatArray:
        """``(s_x, v_x, s_y, v_y)`` at ``t``, shape ``(n, 4)``."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        P = np.polynomial.polynomial
        dx, dy = P.polyder(self.cx), P.polyder(self.cy)
        return np.stack([P.polyval(t, self.cx), P.polyval(t, dx), P.polyval(t, self.cy), P.polyval(t, dy)], axis=1)

    def inputs(self, t: ArrayLike) -> FloatArray:
        """``(u_x, u_y)`` at ``t`` (linear in ``t``), shape ``(n, 2)``."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        P = np.polynomial.polynomial
        return np.stack([P.polyval(t, P.polyder(self.cx, 2)), P.polyval(t, P.polyder(self.cy, 2))], axis=1)

    def breakpoints(self) -> FloatArray:
        """No interior piece ends: one cubic on ``[0, t_f]`` (so that the §9 report of
        :func:`iamp.core.safety.safety_report` is exact on one piece instead of cutting the
        trajectory into 1 ms pieces; that cost ~80 % of a closed-loop episode)."""
        return np.zeros(0)

    def cost(self, tf: float) -> float:
        """``½∫(u_x² + u_y²)dt`` (``u`` is linear, so Simpson's rule is exact)."""
        U = self.inputs(np.array([0.0, tf / 2, tf]))
        sq = np.sum(U**2, axis=1)
        return float(0.5 * tf / 6 * (sq[0] + 4 * sq[1] + sq[2]))


def free_plan(problem: Problem | EgoBoundary, planner: str) -> Plan:
    """The unconstrained optimum as a :class:`Plan` (status ``optimal``: exact, nothing to search).

    ``problem`` may be an :class:`EgoBoundary` (a problem with zero vehicles is made of it).
    """
    start = time.perf_counter()
    prob = problem if isinstance(problem, Problem) else Problem(problem, (), "free")
    traj = FreeTrajectory.of(prob.ego)
    plan = Plan(problem=prob, planner=planner, status=OPTIMAL, cost=traj.cost(prob.tf), contact_times=np.zeros(0),
                jumps=np.zeros((0, 2)), trajectory=traj, diagnostics=Diagnostics(free=True, order=("free",)))
    # the self-check: the boundary conditions recomputed (the input is linear: nothing else to meet)
    scale = max(1.0, float(np.max(np.abs(np.r_[prob.ego.initial, prob.ego.final]))))
    plan.residuals = {"boundary": plan.boundary_residual()}
    if plan.residuals["boundary"] > tol("cmp_residual_rel_clarabel") * scale:
        plan.status, plan.cost = NUMERICAL_ERROR, None
        plan.annotate(failed_check="boundary")
    plan.solve_time_s = time.perf_counter() - start
    return plan
