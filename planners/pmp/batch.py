r"""Many one-vehicle problems at once: :func:`plan_batch`.

One implementation: each problem goes through the one-vehicle kernel of
:mod:`iamp.planners.pmp.one` (:func:`~iamp.planners.pmp.one.solve_one`: the exact global contact
time, the jumps, the cost and the kernel's five checks judged), exactly as
:meth:`PMPPlanner.plan <iamp.planners.pmp.planner.PMPPlanner.plan>` plans one vehicle, so a batch
plan equals the single plan bit for bit.  (A vectorised copy of the kernel, with its own batched
root isolation, was removed in issue 32.)
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from iamp.core.problem import Problem
from iamp.core.status import INFEASIBLE, NUMERICAL_ERROR, OPTIMAL

from .one import one_vehicle_kernel, solve_one

FloatArray = npt.NDArray[np.float64]


@dataclass
class BatchPlan:
    """Result of :func:`plan_batch`: arrays over ``K`` one-vehicle problems (physical units)."""

    contact_time: FloatArray  # (K,)
    cost: FloatArray  # (K,)
    jumps: FloatArray  # (K, 2)
    status: npt.NDArray[np.str_]  # (K,)


def plan_batch(problems: Iterable[Problem], kernel: Callable[..., list[float]] = one_vehicle_kernel) -> BatchPlan:
    r"""Plan many one-vehicle problems and return the results as arrays.

    Each problem gets exactly the plan :meth:`PMPPlanner.plan <iamp.planners.pmp.planner.PMPPlanner.plan>`
    makes for one vehicle: the global contact time :math:`t^*`, the minimiser of :math:`J` over
    :math:`(0, t_f)`, the co-state jumps :math:`\Phi = (\Phi_x, \Phi_y)` and the cost, with the
    kernel's five checks judged (the same numbers bit for bit), without building a
    :class:`~iamp.core.plan.Plan` per problem.

    Parameters
    ----------
    problems : iterable of Problem
        One vehicle each; they may differ in every parameter.
    kernel : callable, optional
        The one-vehicle kernel (:func:`~iamp.planners.pmp.one.one_vehicle_kernel`, the default).

    Returns
    -------
    BatchPlan
        Contact time, cost and jumps (NaN where the status is not ``optimal``) and the status
        of each problem, the single plan's.

    Raises
    ------
    ValueError
        A problem with other than one vehicle.

    See Also
    --------
    iamp.PMPPlanner : One problem, any number of vehicles, as a full :class:`~iamp.core.plan.Plan`.

    Examples
    --------
    >>> import dataclasses
    >>> import iamp
    >>> problem = iamp.load_scenario("paper-1-poly")
    >>> sv = problem.vehicles[0]                     # x_s(t) = -15 + 18 t
    >>> behind = problem.with_vehicles([dataclasses.replace(sv, x_poly=(-20.0, 18.0))])
    >>> batch = iamp.plan_batch([problem, behind])
    >>> batch.status.tolist(), batch.contact_time.round(3).tolist()
    (['optimal', 'optimal'], [3.52, 3.039])
    >>> bool(batch.cost[1] == iamp.PMPPlanner().plan(behind).cost)   # the single plan's, bit for bit
    True
    """
    problems = list(problems)
    if any(len(p.vehicles) != 1 for p in problems):
        raise ValueError("plan_batch plans one-vehicle problems; use PMPPlanner for more")
    K = len(problems)
    ct = np.full(K, np.nan)
    cost = np.full(K, np.nan)
    jumps = np.full((K, 2), np.nan)
    status: list[str] = []
    for i, problem in enumerate(problems):
        try:
            T, L, k, judged = solve_one(problem, kernel)
        except (OverflowError, ZeroDivisionError, ValueError):
            status.append(NUMERICAL_ERROR)
            continue
        if judged is None:
            status.append(INFEASIBLE)
            continue
        bad = judged[2]
        status.append(OPTIMAL if bad is None else bad)
        if bad is None:
            jerk = L / (T * T * T)
            ct[i] = k[0] * T
            cost[i] = k[7] * L * L / (T * T * T)
            jumps[i, 0] = k[5] * jerk
            jumps[i, 1] = k[6] * jerk
    return BatchPlan(ct, cost, jumps, np.array(status, dtype=str))
