r"""The paper's equality only where it is needed: ``--constraint active`` (SPEC §14).

Imposing every vehicle's corner drags the ego towards vehicles that are not in its way.  The
active-set mode starts from the unconstrained plan (per axis the minimum-energy cubic,
:class:`~iamp.planners.avoid.pmp.FreeTrajectory`) and repeats:

1. measure the plan's safety (SPEC §9, exact roots) against **every** vehicle of the problem;
2. if it is intrusion-free and every imposed corner is a real safety constraint: done
   (``optimal`` when the plan of the imposed corners is, else that plan's status);
3. else impose the corner of the vehicle whose safety region the plan enters most deeply
   (among those neither imposed nor dropped) and re-plan with the base planner (the PMP or
   the equality QP) on the imposed vehicles only;
4. drop every imposed vehicle whose jump has the *dragging* sign (SPEC §2 identity 4, via
   identity 2 :math:`\partial J/\partial\,\text{corner}_{i,x} = -\Phi_{i,x}`): for a ``front``
   corner :math:`\Phi_{i,x} > 0` (the ego left to itself would already be ahead of the corner:
   the equality pulls it back towards the vehicle), for a ``rear`` corner
   :math:`\Phi_{i,x} < 0`; re-plan without them.

A dropped vehicle is never imposed again, so the loop ends after at most ``2m`` plans.  When
the plan still intrudes and no vehicle is left to impose, no change helps: status
``unsafe`` (exit 3) with the plan and its report.  The output lists the imposed and dropped
vehicles and why (``info["active_set"]``, the JSON key ``active_set``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from iamp.core import status as st
from iamp.core.free import FreeTrajectory
from iamp.core.plan import Plan
from iamp.core.problem import Problem, SurroundingVehicle
from iamp.core.safety import safety_report
from iamp.planners.diagnostics import ActiveSetDiagnostics

__all__ = ["ActiveSetPlanner", "drags"]

#: |Φ_x| below this (relative to max(1, |Φ|)) has no sign: neither dragging nor pushing.
SIGN_TOL = 1e-9


def drags(vehicle: SurroundingVehicle, phi_x: float, phi_y: float = 0.0) -> bool:
    """``True`` when the jump ``Φ_x`` has the dragging sign for this corner (module docstring)."""
    if abs(phi_x) <= SIGN_TOL * max(1.0, abs(phi_x), abs(phi_y)):
        return False
    return bool(phi_x > 0) if vehicle.sign_x > 0 else bool(phi_x < 0)


@dataclass
class ActiveSetPlanner:
    """``--constraint active`` around a base planner (module docstring).

    Parameters
    ----------
    base : object
        A planner with ``plan(problem) -> Plan`` imposing the paper's equality on every
        vehicle of the problem it is given (:class:`~iamp.planners.pmp.PMPPlanner` or
        :class:`~iamp.planners.qp.QPPlanner`).
    """

    base: Any
    name: str = field(default="pmp")

    def plan(self, problem: Problem) -> Plan:
        start = time.perf_counter()
        vehicles = problem.vehicles
        imposed: list[int] = []
        dropped: list[dict[str, Any]] = []
        dropped_idx: set[int] = set()
        steps: list[dict[str, Any]] = []
        free_sub, free_traj = self._free(problem)
        if free_traj is None and free_sub is not None:
            return self._result(problem, free_sub, None, [], dropped, steps, 1, start, free_sub.status,
                                f"the plan without any corner failed ({free_sub.status}): "
                                f"{free_sub.diagnostics.reason or ''}".rstrip(": "))
        sub: Plan | None = free_sub
        traj: Any = free_traj
        iterations = 0
        while True:
            iterations += 1
            if imposed:
                sub = self.base.plan(problem.with_vehicles([vehicles[i] for i in imposed]))
                if not sub.ok or sub.trajectory is None:
                    return self._result(problem, sub, None, imposed, dropped, steps, iterations, start,
                                        sub.status, f"the plan of the imposed corners failed ({sub.status})")
                traj = sub.trajectory
                drag = [(k, i) for k, i in enumerate(imposed) if drags(vehicles[i], *sub.jumps[k])]
                if drag:
                    for k, i in drag:
                        v = vehicles[i]
                        phi = sub.jumps[k]
                        dropped.append({"name": v.name, "reason": (
                            f"Φ_x = {phi[0]:.6g} {'>' if phi[0] > 0 else '<'} 0 at its {v.corner.split('-')[0]} "
                            "corner: the equality drags the ego towards the vehicle (SPEC §2 identity 4)")})
                        dropped_idx.add(i)
                    steps.append({"iteration": iterations, "dropped": [vehicles[i].name for _, i in drag]})
                    imposed = [i for i in imposed if i not in dropped_idx]
                    if not imposed:
                        sub, traj = free_sub, free_traj
                        iterations += 1
                    else:
                        continue
            report = safety_report(problem, traj)
            depth = [(vs.max_intrusion_m, i) for i, vs in enumerate(report.vehicles) if vs.intrusion]
            if not depth:
                status = sub.status if sub is not None else st.OPTIMAL
                return self._result(problem, sub, traj, imposed, dropped, steps, iterations, start, status, None)
            options = sorted((d for d in depth if d[1] not in imposed and d[1] not in dropped_idx), reverse=True)
            if not options:
                names = ", ".join(vehicles[i].name for _, i in sorted(depth, reverse=True))
                return self._result(problem, sub, traj, imposed, dropped, steps, iterations, start, st.UNSAFE,
                                    f"the plan still enters the safety region of {names}, whose corner is already "
                                    "imposed or was dropped as dragging: no change of the active set helps")
            d, i = options[0]
            imposed.append(i)
            steps.append({"iteration": iterations, "imposed": vehicles[i].name, "max_intrusion_m": float(d)})

    def _free(self, problem: Problem) -> tuple[Plan | None, Any]:
        """The plan with no corner imposed: the minimum-energy cubic without physical limits;
        with a ``[limits]`` table the bounded plan of the problem with zero vehicles (the PMP:
        its input box imposed exactly, the other bounds judged; the QPs need a vehicle), so that
        the active set never starts from a plan beyond the car's limits.  Returns ``(plan or
        None, trajectory or None)``; a failed bounded plan has no trajectory."""
        lim = problem.limits
        if lim is None or lim.empty:
            return None, FreeTrajectory.of(problem.ego)
        from iamp.planners.pmp.planner import PMPPlanner

        base = self.base if self.name == "pmp" else PMPPlanner()
        free = base.plan(problem.with_vehicles([]))
        if hasattr(free, "judge_limits"):
            free = free.judge_limits()
        if not free.ok or free.trajectory is None:
            return free, None
        return free, free.trajectory

    def _base_attr(self, name: str) -> Any:
        return getattr(self.base, name, None) if self.name == "qp" else None

    def _result(self, problem: Problem, sub: Plan | None, traj: Any, imposed: list[int],
                dropped: list[dict[str, Any]], steps: list[dict[str, Any]], iterations: int, start: float,
                status: str, reason: str | None) -> Plan:
        m = problem.m
        times = np.full(m, np.nan)
        jumps = np.zeros((m, 2))
        cost: float | None = None
        if traj is not None:
            if sub is not None and sub.cost is not None:
                cost = float(sub.cost)
                for k, i in enumerate(imposed):
                    times[i] = sub.contact_times[k]
                    jumps[i] = sub.jumps[k]
            else:
                cost = float(traj.cost(problem.tf))
        else:
            jumps[:] = np.nan
        vehicles = problem.vehicles
        info: dict[str, Any] = sub.diagnostics.as_info() if sub is not None else {}
        info.pop("avoidance", None)
        info["constraint"] = "active"
        info["active_set"] = {
            "imposed": [{"name": vehicles[i].name, "contact_time": float(sub.contact_times[k]) if sub else None,
                         "phi": [float(x) for x in sub.jumps[k]] if sub else None,
                         "reason": "the plan without it entered its safety region; its jump pushes the ego to "
                                   "the safe side (a real safety constraint)"}
                        for k, i in enumerate(imposed)],
            "dropped": dropped, "iterations": iterations, "steps": steps, "base": self.name}
        if reason is not None:
            info["reason"] = reason
            if status == st.UNSAFE:
                info["unsafe_reason"] = reason
        planner = self.name if sub is None or not imposed else (getattr(sub, "planner", None) or self.name)
        plan = Plan(problem=problem, planner=planner, status=status,
                    cost=cost if status in st.SUCCESS or status == st.UNSAFE else None,
                    contact_times=times, jumps=jumps, trajectory=traj,
                    solve_time_s=time.perf_counter() - start,
                    solver=getattr(sub, "solver", None) or self._base_attr("solver"),
                    hold=getattr(sub, "hold", None) or self._base_attr("hold"),
                    steps=getattr(sub, "steps", None) or self._base_attr("steps"),
                    diagnostics=replace(ActiveSetDiagnostics.from_info(info),
                                        base=sub.diagnostics if sub is not None else None))
        if sub is not None:
            plan.residuals = dict(sub.residuals)
        else:
            plan.residuals = {"boundary": plan.boundary_residual()}
        return plan
