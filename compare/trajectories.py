"""Typed views of a plan's trajectory for the comparison (the planners' own trajectory classes).

``Plan.trajectory`` is any object with ``states(t)``/``inputs(t)``
(:class:`iamp.core.plan.Trajectory`); the comparison also reads what only some planners carry:
the QP's nodes and nodal inputs (:class:`~iamp.planners.qp.hold.HoldTrajectory`) and the PMP's
co-states (:class:`~iamp.planners.pmp.solution.PMPSolution`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from iamp.core.plan import Plan
from iamp.planners.pmp.bounded import BoundedSolution
from iamp.planners.pmp.solution import PMPSolution
from iamp.planners.qp.hold import HoldTrajectory


def hold_trajectory(plan: Plan) -> HoldTrajectory:
    """The QP plan's exact hold trajectory (``TypeError`` for another planner's plan)."""
    traj = plan.trajectory
    if not isinstance(traj, HoldTrajectory):
        raise TypeError(f"a {plan.planner} plan with status {plan.status} has no QP hold trajectory "
                        f"(got {type(traj).__name__})")
    return traj


def pmp_solution(plan: Plan) -> PMPSolution:
    """The PMP plan's solution (co-states, jumps; ``TypeError`` for another planner's plan)."""
    traj = plan.trajectory
    if not isinstance(traj, PMPSolution):
        raise TypeError(f"a {plan.planner} plan with status {plan.status} has no PMP solution "
                        f"(got {type(traj).__name__})")
    return traj


def hamiltonian_jump_residuals(plan: Plan) -> NDArray[np.float64]:
    """The Hamiltonian-jump residual at each contact time of a PMP plan, bounded or not
    (:class:`~iamp.planners.pmp.solution.PMPSolution` or
    :class:`~iamp.planners.pmp.bounded.BoundedSolution`; ``TypeError`` for another planner's plan)."""
    traj = plan.trajectory
    if isinstance(traj, BoundedSolution):
        return np.asarray(traj.hamiltonian_jump_residual(), dtype=float)
    return np.asarray(pmp_solution(plan).hamiltonian_jump_residual(), dtype=float)
