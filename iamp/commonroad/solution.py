r"""A road-frame plan as a CommonRoad solution: point-mass model ``PM`` (below) or kinematic single
track ``KS`` (:mod:`iamp.commonroad.ks`), a named cost function; the benchmark ID
(``KS2:WX1:<scenario>:2020a``) names model, vehicle type, cost function and scenario.

The plan's states at the scenario's time steps :math:`t_k = k\,\Delta t` map to the world by
:meth:`~iamp.commonroad.frame.RoadFrame.to_world` and
:meth:`~iamp.commonroad.frame.RoadFrame.velocity_to_world`.  CommonRoad's feasibility check
reconstructs one constant input per step (``PM``: :math:`\ddot p = u`, :math:`|u| \le a_{max}`)
and accepts a step when the simulated position is within 2 cm; the written trajectory is
therefore the exact zero-order-hold simulation

.. math::  u_k = \frac{v(t_{k+1}) - v(t_k)}{\Delta t}, \qquad
           p_{k+1} = p_k + v_k\,\Delta t + \tfrac12 u_k\,\Delta t^2,

which matches the plan's velocities at every step and its positions to the integral of
the plan's velocity error inside a step (millimetres per step; the largest drift is reported).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from iamp.commonroad import require
from iamp.commonroad.convert import CommonRoadProblem
from iamp.core.atomic import write_text
from iamp.core.plan import Trajectory

if TYPE_CHECKING:
    from commonroad.scenario.state import KSState

    from iamp.commonroad.ks import KSTrajectory

FloatArray = npt.NDArray[np.float64]

#: The cost function named in the solution (CommonRoad's ``WX1`` by default).
DEFAULT_COST_FUNCTION = "WX1"


#: A plan's mapped start within this of the planning problem's initial position starts there
#: exactly (the road frame's round trip is far finer) [m].
START_SNAP_M = 0.01


def world_states(cr: CommonRoadProblem, trajectory: Trajectory, steps: int) -> tuple[FloatArray, FloatArray, float]:
    """Positions ``(K+1, 2)`` and velocities ``(K+1, 2)`` of the ZOH trajectory, and the largest
    distance between its positions and the plan's mapped positions [m].

    The integration starts at the plan's own first state: the planning problem's initial
    position itself when the plan starts there (within :data:`START_SNAP_M`, the solution's
    first state), else its mapped position (a replan of the closed loop, whose ``cr.x0`` is the
    ego's state then: the problem's initial position would shift every later body by the
    distance driven since)."""
    t = np.arange(steps + 1) * cr.dt
    X = trajectory.states(t)
    P = cr.frame.to_world(X[:, 0], X[:, 2])
    V = cr.frame.velocity_to_world(X[:, 0], X[:, 2], X[:, 1], X[:, 3])
    p_init = np.asarray(cr.planning_problem.initial_state.position, dtype=float)
    if float(np.linalg.norm(P[0] - p_init)) <= START_SNAP_M:
        P[0] = p_init
    U = np.diff(V, axis=0) / cr.dt
    Z = np.empty_like(P)
    Z[0] = P[0]
    for k in range(steps):
        Z[k + 1] = Z[k] + V[k] * cr.dt + 0.5 * U[k] * cr.dt**2
    return Z, V, float(np.max(np.linalg.norm(Z - P, axis=1)))


def ks_states(ks: KSTrajectory) -> list[KSState]:
    """The CommonRoad ``KSState`` of every time step of a tracked ``KS`` trajectory (the centre's
    position, steering angle, speed, the rear axle's heading), as a solution stores them.

    Parameters
    ----------
    ks : iamp.commonroad.ks.KSTrajectory

    Returns
    -------
    list of commonroad.scenario.state.KSState
    """
    from commonroad.scenario.state import KSState

    return [KSState(time_step=k, position=ks.centre[k].copy(), steering_angle=float(ks.states[k, 2]),
                    velocity=float(ks.states[k, 3]), orientation=float(ks.states[k, 4]))
            for k in range(len(ks.states))]


#: The vehicle models a solution can be written in: point mass, kinematic single track.
VEHICLE_MODELS = ("PM", "KS")


def build_solution(cr: CommonRoadProblem, trajectory: Trajectory, steps: int,
                   cost_function: str = DEFAULT_COST_FUNCTION, vehicle_type: int = 2,
                   vehicle_model: str = "PM") -> tuple[object, float]:
    """The CommonRoad :class:`Solution` of a plan and how far its states are from the plan.

    Parameters
    ----------
    cr : CommonRoadProblem
        The problem the plan solves.
    trajectory : Trajectory
        The road-frame plan.
    steps : int
        Number of time steps ``K`` (``K + 1`` states from time step 0).
    cost_function : str
        CommonRoad cost function ID named in the benchmark ID (``WX1``, ``SM1``, ``TR1``, ...).
    vehicle_type : int
        CommonRoad vehicle type (1-3 for ``KS``).
    vehicle_model : str
        ``"PM"`` (the ZOH point mass of the module docstring) or ``"KS"``
        (:func:`iamp.commonroad.ks.track`).

    Returns
    -------
    tuple
        The solution and the largest distance [m] between its positions and the plan's (the ZOH
        drift for ``PM``, the tracking deviation for ``KS``).

    Raises
    ------
    ScenarioError
        For an unknown vehicle model or a vehicle type without ``KS`` parameters.
    """
    require()
    from commonroad.common.solution import (
        CostFunction,
        PlanningProblemSolution,
        Solution,
        VehicleModel,
        VehicleType,
    )
    from commonroad.scenario.state import PMState, TraceState
    from commonroad.scenario.trajectory import Trajectory

    from iamp.core.errors import ScenarioError

    if vehicle_model not in VEHICLE_MODELS:
        raise ScenarioError(f"unknown vehicle model {vehicle_model!r} (choose {' or '.join(VEHICLE_MODELS)})",
                            "--vehicle-model")
    states: list[TraceState]
    if vehicle_model == "KS":
        from iamp.commonroad.ks import track

        ks = track(cr, trajectory, steps, vehicle_type)
        states = list(ks_states(ks))
        drift = ks.deviation_m
    else:
        Z, V, drift = world_states(cr, trajectory, steps)
        states = [PMState(time_step=k, position=Z[k].copy(), velocity=float(V[k, 0]), velocity_y=float(V[k, 1]))
                  for k in range(steps + 1)]
    pps = PlanningProblemSolution(planning_problem_id=cr.planning_problem.planning_problem_id,
                                  vehicle_type=VehicleType(vehicle_type), vehicle_model=VehicleModel[vehicle_model],
                                  cost_function=CostFunction[cost_function],
                                  trajectory=Trajectory(initial_time_step=0, state_list=states))
    return Solution(cr.scenario.scenario_id, [pps]), drift


def write_solution(solution: object, path: str | Path, force: bool = False) -> Path:
    """Write ``solution`` as CommonRoad XML atomically (refuses to overwrite without ``force``)."""
    from commonroad.common.solution import CommonRoadSolutionWriter

    from iamp.core.outputs import check_output

    out = check_output(path, force=force)
    text = CommonRoadSolutionWriter(solution).dump()
    write_text(out, text)
    return out
