r"""The peer a user would write by hand: the free-contact-time problem in CasADi ``Opti`` with
IPOPT (``iamp bench`` runs it when ``casadi`` is installed: ``pip install casadi``).

Formulation (one vehicle, two phases split at the free contact time ``t_1``, the way the
problem is usually typed in): ``N/2`` zero-order-hold steps of length :math:`h_1 = t_1/(N/2)`
on :math:`[0, t_1]` and ``N/2`` of :math:`h_2 = (t_f - t_1)/(N/2)` on :math:`[t_1, t_f]`; per
axis the exact double-integrator step

.. math::  s_{k+1} = s_k + h v_k + \tfrac{h^2}{2} u_k,\qquad v_{k+1} = v_k + h u_k ,

cost :math:`\tfrac12\sum_k h_k (u_{x,k}^2 + u_{y,k}^2)`, start and end states fixed, and the
interior-point constraint at node ``N/2``: :math:`x = \text{corner}_x(t_1)`,
:math:`y = \text{corner}_y`, with :math:`t_1 \in [10^{-3} t_f, (1 - 10^{-3}) t_f]`.  The
decision variables are ``t_1``, the states and the inputs (``4(N+1) + 2N + 1`` of them); IPOPT
gets exact derivatives from CasADi's automatic differentiation.

It is a *discretisation* of the continuous problem the PMP solves exactly, so its contact
time and cost differ from the PMP's by the ZOH error (``O(h)``): the bench reports both
differences beside the times.  Timed: ``build`` = construct the ``Opti`` problem (symbolic,
once per problem); ``cold`` = solve it from a straight-line guess with ``t_1 = t_f/2``;
``warm`` = solve the built problem again from the previous solution (IPOPT has no true warm
start of its barrier; re-solving from the last solution is what users do).

With ``box=True`` the input box of ``problem.limits`` (``ax``, ``ay``) is imposed on every
``u_k`` (:math:`\ell \le u_k \le h`): the bounded problem the saturated PMP
(:mod:`iamp.planners.pmp.bounded`) solves exactly, typed in as a user would.
"""

from __future__ import annotations

import statistics
import time
from typing import Any, TypedDict

import numpy as np

from iamp.core.problem import Problem


class CasadiFreeTime(TypedDict):
    """:func:`casadi_free_time`: medians [s] of the build and the cold and warm solves, and the solution."""

    build_s: float
    cold_s: float
    warm_s: float
    contact_time: float
    cost: float
    iterations_cold: int
    iterations_warm: int
    return_status: str
    steps: int
    variables: int


def _build(problem: Problem, steps: int, box: bool = False) -> tuple[Any, Any]:
    """``(opti, t1)`` for :func:`casadi_free_time` (one vehicle); ``box``: impose
    ``problem.limits``' ``ax``/``ay`` on every input (the bounded problem of SPEC §14)."""
    import casadi as ca

    ego, veh = problem.ego, problem.vehicles[0]
    n1 = steps // 2
    n2 = steps - n1
    opti = ca.Opti()
    X = opti.variable(4, steps + 1)  # x, vx, y, vy
    U = opti.variable(2, steps)
    t1 = opti.variable()
    tf = float(problem.tf)
    cost: Any = 0
    for k in range(steps):
        h = t1 / n1 if k < n1 else (tf - t1) / n2
        for ax in range(2):
            s, v, u = X[2 * ax, k], X[2 * ax + 1, k], U[ax, k]
            opti.subject_to(X[2 * ax, k + 1] == s + h * v + h * h / 2 * u)
            opti.subject_to(X[2 * ax + 1, k + 1] == v + h * u)
        cost = cost + 0.5 * h * (U[0, k] ** 2 + U[1, k] ** 2)
    opti.minimize(cost)
    lim = problem.limits
    if box and lim is not None:
        for ax, rng in enumerate((lim.ax, lim.ay)):
            if rng is not None:
                opti.subject_to(opti.bounded(float(rng[0]), U[ax, :], float(rng[1])))
    opti.subject_to(X[:, 0] == ca.DM([ego.x0, ego.vx0, ego.y0, ego.vy0]))
    opti.subject_to(X[:, steps] == ca.DM([ego.xf, ego.vxf, ego.yf, ego.vyf]))
    corner_x: Any = 0
    for c in reversed([float(a) for a in veh.x_poly]):
        corner_x = corner_x * t1 + c
    opti.subject_to(X[0, n1] == corner_x + float(veh.offset_x))
    opti.subject_to(X[2, n1] == float(veh.corner_y))
    opti.subject_to(opti.bounded(1e-3 * tf, t1, (1 - 1e-3) * tf))
    opti.set_initial(t1, 0.5 * tf)
    frac = np.linspace(0.0, 1.0, steps + 1)
    start = np.array([ego.x0, ego.vx0, ego.y0, ego.vy0])
    end = np.array([ego.xf, ego.vxf, ego.yf, ego.vyf])
    opti.set_initial(X, np.outer(start, 1 - frac) + np.outer(end, frac))
    opti.solver("ipopt", {"print_time": False}, {"print_level": 0, "sb": "yes", "tol": 1e-10})
    return opti, t1


def casadi_free_time(problem: Problem, steps: int = 100, repeats: int = 5, box: bool = False) -> CasadiFreeTime:
    """Medians of ``repeats`` cold and warm IPOPT solves (module docstring) and the solution
    (``box``: with the input box of ``problem.limits``, the bounded PMP's peer):
    ``{"build_s", "cold_s", "warm_s", "contact_time", "cost", "iterations_cold", "iterations_warm",
    "return_status"}``.  Raises ``ValueError`` unless the problem has one vehicle."""
    if problem.m != 1:
        raise ValueError("the CasADi peer is written for one vehicle")
    build, cold, warm = [], [], []
    sol: Any = None
    opti: Any = None
    for _ in range(max(1, repeats)):
        t0 = time.perf_counter()
        opti, t1 = _build(problem, steps, box)
        t_built = time.perf_counter()
        sol = opti.solve()
        cold.append(time.perf_counter() - t_built)
        build.append(t_built - t0)
    it_cold = int(sol.stats()["iter_count"])
    for _ in range(max(1, repeats)):
        opti.set_initial(sol.value_variables())
        t0 = time.perf_counter()
        sol = opti.solve()
        warm.append(time.perf_counter() - t0)
    return {"build_s": float(statistics.median(build)), "cold_s": float(statistics.median(cold)),
            "warm_s": float(statistics.median(warm)),
            "contact_time": float(sol.value(t1)), "cost": float(sol.value(opti.f)),
            "iterations_cold": it_cold, "iterations_warm": int(sol.stats()["iter_count"]),
            "return_status": str(sol.stats()["return_status"]), "steps": steps,
            "variables": int(opti.nx)}
