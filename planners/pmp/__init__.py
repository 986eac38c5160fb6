"""The paper's indirect planner: Pontryagin's minimum principle with interior-point equality
constraints at free contact times (the fixed-time jump system, the global contact-time search,
its certificates and the self-check).
"""

from __future__ import annotations

from .planner import (
    BatchPlan,
    PMPPlanner,
    PMPSolution,
    ValueFunction,
    bridge_kernel,
    bridge_kernel_ds,
    bridge_variance_dt,
    hamiltonian_jump_residuals,
    hermite_cubic,
    jump_system,
    one_vehicle_contact_time,
    plan_batch,
    solve_fixed_times,
    solve_one_vehicle,
    transfer_cost,
)

__all__ = [
    "BatchPlan",
    "PMPPlanner",
    "PMPSolution",
    "ValueFunction",
    "bridge_kernel",
    "bridge_kernel_ds",
    "bridge_variance_dt",
    "hamiltonian_jump_residuals",
    "hermite_cubic",
    "jump_system",
    "one_vehicle_contact_time",
    "plan_batch",
    "solve_fixed_times",
    "solve_one_vehicle",
    "transfer_cost",
]
