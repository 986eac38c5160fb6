r"""Avoidance on the PMP side (SPEC §10, continuous time), for the cases with at most one
touch point per vehicle; verified against the avoidance QP.

The continuous avoidance problem keeps the ego in vehicle ``i``'s first half-plane for
:math:`t \le \tau_i` and in its second for :math:`t \ge \tau_i` (state constraints).  Its
candidates here, in order:

1. **No touch**: the unconstrained optimum (per axis the cubic with
   :math:`J = (6e_1^2 - 6Te_1e_2 + 2T^2e_2^2)/T^3`, :math:`e_1 = s_f - s_0 - v_0T`,
   :math:`e_2 = v_f - v_0`).  If it satisfies every vehicle's crossing constraint it is the
   global optimum (a lower bound attained): ``optimal``.
2. **One touch per vehicle, at the corner**: the paper's equality plan
   (:class:`~iamp.planners.pmp.planner.PMPPlanner`, global :math:`t^*`).  At :math:`t^*` the ego is on
   both half-planes' boundaries, so it is a KKT point of the avoidance problem when (a) it
   satisfies the crossing constraints everywhere else and (b) its jumps have the sign of
   inequality multipliers, :math:`\sigma_x \Phi_{i,x} \ge 0` and :math:`\sigma_y \Phi_{i,y} \ge 0`
   (with :math:`L = J + \Phi_i^\top(s - \text{corner}_i)` and :math:`\sigma` the half-plane
   orientation of :class:`~iamp.planners.avoid.data.HalfPlane`, an inequality multiplier
   :math:`\mu \ge 0` enters as :math:`\Phi = \sigma\mu`), while the free-time condition is the
   Hamiltonian jump the PMP already solved.  For fixed :math:`\tau = t^*` the problem is convex,
   so it is that problem's optimum; other touch structures are not searched, so the plan is
   reported ``local`` (the tests check it against the QP's global sweep).
3. Otherwise the optimum needs several touch points or boundary arcs, which this planner does
   not construct: status ``solver_error`` with the reason (use ``--planner qp --constraint avoid``).

Feasibility of a continuous trajectory is checked on a 1 ms grid with a 1e-9 m tolerance.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from iamp.core import status as st
from iamp.core.free import FreeTrajectory
from iamp.core.plan import Plan
from iamp.core.problem import Problem

from .check import crossing_orders, leave_time
from .data import HalfPlane
from .diagnostics import AvoidDiagnostics

FloatArray = NDArray[np.float64]


def crossing_feasible(problem: Problem, traj: Any, orders: list[list[tuple[int, int]]]) -> list[bool]:
    """Per vehicle: does ``traj`` keep the crossing constraint for some ``τ`` and order?"""
    t = np.linspace(0.0, problem.tf, max(2, int(np.ceil(problem.tf / 1e-3)) + 1))
    X = traj.states(t)
    out = []
    for v, vehicle_orders in zip(problem.vehicles, orders):
        planes = (HalfPlane(v, "x"), HalfPlane(v, "y"))
        inside = [planes[a].margin(t, X[:, 2 * a]) >= -1e-9 for a in (0, 1)]
        ok = False
        for f, s in vehicle_orders:
            bad_f, bad_s = np.flatnonzero(~inside[f]), np.flatnonzero(~inside[s])
            prefix_end = int(bad_f[0]) if bad_f.size else t.size  # first sample not in the first
            suffix_start = int(bad_s[-1]) + 1 if bad_s.size else 0  # after the last not in the second
            ok = ok or suffix_start <= prefix_end
        out.append(ok)
    return out


@dataclass
class PMPAvoidPlanner:
    """Continuous-time avoidance with at most one touch per vehicle (module docstring)."""

    def plan(self, problem: Problem) -> Plan:
        from iamp.planners.pmp.planner import PMPPlanner

        start = time.perf_counter()
        m = problem.m
        orders, reason = crossing_orders(problem)
        nan_t, nan_j = np.full(m, np.nan), np.full((m, 2), np.nan)

        def done(status: str, cost: float | None, times: FloatArray, jumps: FloatArray, traj: Any,
                 info: dict[str, Any]) -> Plan:
            return Plan(problem=problem, planner="pmp", status=status, cost=cost, contact_times=times, jumps=jumps,
                        trajectory=traj, solve_time_s=time.perf_counter() - start,
                        diagnostics=AvoidDiagnostics.from_info({"constraint": "avoid", **info}))

        if reason is not None:
            return done(st.INFEASIBLE, None, nan_t, nan_j, None, {"reason": reason})
        free = FreeTrajectory.of(problem.ego)
        if all(crossing_feasible(problem, free, orders)):
            # crossing time: the last instant in the first half-plane (as the QP reports it)
            taus = np.array([leave_time(free, HalfPlane(v, "xy"[o[0][0]]), problem.tf)
                             for v, o in zip(problem.vehicles, orders)])
            return done(st.OPTIMAL, free.cost(problem.tf), taus, np.zeros((m, 2)), free,
                        {"touches": "none", "certificate": "the unconstrained optimum keeps every crossing "
                         "constraint: a lower bound attained"})
        eq = PMPPlanner().plan(problem)
        if eq.ok and eq.trajectory is not None:
            feasible = all(crossing_feasible(problem, eq.trajectory, orders))
            signs = [(HalfPlane(v, "x").sigma * j[0] >= -1e-9, HalfPlane(v, "y").sigma * j[1] >= -1e-9)
                     for v, j in zip(problem.vehicles, eq.jumps)]
            if feasible and all(a and b for a, b in signs):
                return done(st.LOCAL, eq.cost, eq.contact_times, eq.jumps, eq.trajectory,
                            {"touches": "one per vehicle, at the corner", "residuals": eq.residuals,
                             "note": "KKT point of the avoidance problem at tau = t* (jumps have the inequality "
                                     "multipliers' sign); other touch structures are not searched"})
            why = ("the equality plan leaves the crossing constraint" if not feasible else
                   "the equality plan's jumps have the wrong sign for inequality multipliers")
        else:
            why = f"the equality plan failed ({eq.status})"
        return done(st.SOLVER_ERROR, None, nan_t, nan_j, None,
                    {"reason": f"the avoidance optimum needs several touch points or boundary arcs ({why}); "
                               "use --planner qp --constraint avoid"})
