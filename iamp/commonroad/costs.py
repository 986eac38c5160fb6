r"""CommonRoad's official cost functions (``WX1``, ``SM1``, ``TR1``, ...) on a solution.

The definitions are those of the drivability checker's evaluator
(``commonroad_dc.costs.evaluation.CostFunctionEvaluator`` with
``commonroad_dc.costs.partial_cost_functions``, 2025.4; the published document
``costFunctions_commonRoad.pdf``): a cost function is a weighted sum of partial costs, each the
Simpson integral (``scipy.integrate.simpson``, spacing :math:`\Delta t`) of a squared signal
over the trajectory's time steps:

=====  =============================================================================
``A``  :math:`\int a^2`, :math:`a = \Delta v/\Delta t` of the states' ``velocity``
``J``  :math:`\int j^2`, :math:`j = \Delta a/\Delta t`
``SA`` :math:`\int \delta^2` (steering angle; a ``KS`` state's)
``SR`` :math:`\int \dot\delta^2`, :math:`\dot\delta = \Delta\delta/\Delta t`
``Y``  :math:`\int \dot\psi^2`
``L``  :math:`\int v` (path length)
``T``  duration :math:`(k_{end} - k_0)\Delta t`
``ID`` :math:`1/\min(T, 0.1)` (as the evaluator writes it)
``V``  :math:`\int (v_{goal} - v)^2`, :math:`v_{goal}` the smallest lower end of the goal's
       velocity intervals (0 when the goal has none)
``O``  :math:`\int \Delta\psi^2`, heading relative to the lane's tangent
``LC`` :math:`\int d^2`, lateral offset from the centre line of the lane the ego is in
``D``  :math:`\int e^{-0.2\,\Delta s}`, :math:`\Delta s` the longitudinal distance to the nearest
       vehicle ahead within 2.8 m laterally, less the ego's radius :math:`w/2.5` (no vehicle:
       :math:`e^{-\infty} = 0`)
``Jlon`` :math:`\int j_{lon}^2`, the third derivative (``np.gradient``) of the longitudinal
       position smoothed by a cubic Savitzky-Golay filter (window: the evaluator's rule)
=====  =============================================================================

with the evaluator's weights (:data:`COST_FUNCTIONS`).  The evaluator matches the trajectory to
a lanelet route and projects it with ``commonroad-clcs``, which pins ``osqp < 1`` and cannot
live in iamp's environment (cvxpy needs ``osqp >= 1``).  Here the lane-relative signals come
from the scenario itself: ``O`` and ``LC`` from the centre polyline of the lanelet containing
the ego with the smallest offset, the longitudinal position and ``D`` from the road frame
(:class:`~iamp.commonroad.frame.RoadFrame`, arc length and offset).  The two are compared on
every bench solution by ``scripts/commonroad_costs.py`` run in the peer's environment (on the
117 solutions of ``reports/commonroad/``: ``WX1`` to 0.001 %, ``SM1`` to 0.09 %, ``TR1`` median
0.46 %, up to 19 % on a lane change, where the evaluator keeps measuring the lane-centre offset
from the old lane while the ego's disk touches it); the result never depends on which packages
are importable.

As in the evaluator, a point-mass (``PM``) state's ``velocity`` is its *x* component
:math:`v_x` (so ``A``, ``J``, ``L``, ``V`` of a ``PM`` solution use :math:`v_x`), its heading
:math:`\operatorname{atan2}(v_y, v_x)`, and the steering terms (``SA``, ``SR``) do not exist:
``SM1``, ``SM2``, ``SM3``, ``SA1`` and ``TR1`` are not defined for ``PM`` (``None`` with the
reason).  ``MW1`` (lateral jerk, longitudinal speed offset) is not implemented.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, TypedDict

import numpy as np
import numpy.typing as npt

from iamp.commonroad.convert import CommonRoadProblem

FloatArray = npt.NDArray[np.float64]

#: The evaluator's weights (``commonroad_dc.costs.evaluation.cost_function_mapping``).
COST_FUNCTIONS: dict[str, tuple[tuple[str, float], ...]] = {
    "JB1": (("T", 1.0),),
    "SA1": (("SA", 0.1), ("SR", 0.1), ("D", 100000.0)),
    "SM1": (("A", 50.0), ("SA", 50.0), ("SR", 50.0), ("L", 1.0), ("V", 20.0), ("O", 50.0)),
    "SM2": (("A", 50.0), ("SA", 50.0), ("SR", 50.0), ("L", 1.0), ("O", 50.0)),
    "SM3": (("A", 50.0), ("SA", 50.0), ("SR", 50.0), ("V", 20.0), ("O", 50.0)),
    "WX1": (("T", 10.0), ("V", 1.0), ("A", 0.1), ("J", 0.1), ("D", 0.1), ("L", 10.0)),
    "TR1": (("Jlon", 0.01), ("SR", 22.0), ("D", 8.0), ("LC", 0.5)),
}
#: The cost functions the bench reports (those of the recent competitions).
REPORTED = ("WX1", "SM1", "TR1")
#: ``D``: vehicles within this lateral distance count as ahead in the ego's lane [m].
D_LATERAL_M = 2.8
#: ``D``: the exponent's factor [1/m].
D_DECAY = 0.2
#: Lanelet centre polylines are extended by this much at both ends before projecting [m].
EXTEND_M = 10.0


class CostJSON(TypedDict):
    """One cost function's value on one solution."""

    total: float | None
    partial: dict[str, float]
    error: str | None


@dataclass
class _Signals:
    dt: float
    k: FloatArray
    position: FloatArray
    velocity: FloatArray
    orientation: FloatArray
    steering: FloatArray | None
    goal_v: float | None
    lon: FloatArray = field(default_factory=lambda: np.zeros(0))
    lat_lane: FloatArray = field(default_factory=lambda: np.zeros(0))
    dpsi_lane: FloatArray = field(default_factory=lambda: np.zeros(0))
    dist_ahead: FloatArray = field(default_factory=lambda: np.zeros(0))


def _simpson(y: FloatArray, dt: float) -> float:
    from scipy.integrate import simpson

    return float(simpson(np.asarray(y, dtype=float), dx=dt))


def _wrap(a: FloatArray) -> FloatArray:
    return np.asarray((a + np.pi) % (2.0 * np.pi) - np.pi, dtype=float)


def _project(poly: FloatArray, p: FloatArray) -> tuple[float, float]:
    """Signed offset (left positive) of ``p`` from ``poly`` and the tangent heading there."""
    a, b = poly[:-1], poly[1:]
    ab = b - a
    L2 = np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-12)
    t = np.clip(np.einsum("ij,ij->i", p - a, ab) / L2, 0.0, 1.0)
    foot = a + t[:, None] * ab
    dist = np.linalg.norm(p - foot, axis=1)
    i = int(np.argmin(dist))
    side = ab[i, 0] * (p[1] - a[i, 1]) - ab[i, 1] * (p[0] - a[i, 0])
    return float(math.copysign(dist[i], side)), float(math.atan2(ab[i, 1], ab[i, 0]))


def _extended(v: FloatArray) -> FloatArray:
    d0 = (v[0] - v[1]) / np.linalg.norm(v[0] - v[1])
    d1 = (v[-1] - v[-2]) / np.linalg.norm(v[-1] - v[-2])
    return np.vstack([v[0] + EXTEND_M * d0, v, v[-1] + EXTEND_M * d1])


def _lane_signals(cr: CommonRoadProblem, s: _Signals, ego_radius: float) -> None:
    """``lat_lane``, ``dpsi_lane`` (lanelet centre lines), ``lon`` and ``dist_ahead`` (road frame)."""
    from shapely.geometry import Point  # type: ignore[import-untyped]  # commonroad-io's dependency

    network = cr.scenario.lanelet_network
    polys = {ll.lanelet_id: (ll.polygon.shapely_object, _extended(np.asarray(ll.center_vertices, dtype=float)))
             for ll in network.lanelets}
    lat, dpsi = [], []
    for p, psi in zip(s.position, s.orientation):
        disk = Point(float(p[0]), float(p[1])).buffer(ego_radius, 8)
        best: tuple[float, float] | None = None
        for shape, centre in polys.values():
            if shape.intersects(disk):
                d, tang = _project(centre, p)
                if best is None or abs(d) < abs(best[0]):
                    best = (d, tang)
        if best is None:  # off every lanelet: the nearest centre line
            best = min((_project(c, p) for _, c in polys.values()), key=lambda x: abs(x[0]))
        lat.append(best[0])
        dpsi.append(float(_wrap(np.array(psi - best[1]))))
    s.lat_lane, s.dpsi_lane = np.array(lat), np.array(dpsi)
    road = cr.frame.to_road(s.position)
    s.lon = road[:, 0]
    # every nearby obstacle centre at every step, projected in one call
    owner, pts = [], []
    from commonroad.prediction.prediction import SetBasedPrediction

    for i, k in enumerate(s.k.astype(int)):
        for ob in cr.scenario.dynamic_obstacles:
            if int(k) != ob.initial_state.time_step and isinstance(ob.prediction, SetBasedPrediction):
                continue  # a set, not a state (commonroad-io returns None for it, with a warning)
            st = ob.state_at_time(int(k))
            if st is None:
                continue
            q = np.asarray(st.position, dtype=float)
            if np.max(np.abs(q - s.position[i])) <= 100.0 + 0.5 * float(ob.obstacle_shape.length):
                owner.append(i)
                pts.append(q)
    ahead = np.full(len(s.k), math.inf)
    if pts:
        obs = cr.frame.to_road(np.array(pts))
        idx = np.array(owner)
        dist = obs[:, 0] - road[idx, 0]
        near = (np.abs(road[idx, 1] - obs[:, 1]) < D_LATERAL_M) & (dist > 0.0)
        np.minimum.at(ahead, idx[near], dist[near] - ego_radius)
    s.dist_ahead = ahead


def _lon_jerk(lon: FloatArray, dt: float) -> FloatArray:
    """The evaluator's longitudinal jerk: Savitzky-Golay (cubic) smoothing, then ``np.gradient`` x3."""
    from scipy.signal import savgol_filter

    window = min(math.floor(len(lon) / 1.5), 13)
    window -= window % 2 + 1
    x = savgol_filter(lon, window, 3) if window > 4 else lon
    v = np.gradient(x, dt)
    a = np.gradient(v, dt)
    return np.asarray(np.gradient(a, dt), dtype=float)


def _partial(name: str, s: _Signals) -> float:
    dt = s.dt
    if name == "T":
        return float((s.k[-1] - s.k[0]) * dt)
    if name == "ID":
        return 1.0 / min(float((s.k[-1] - s.k[0]) * dt), 0.1)
    if name == "A":
        return _simpson(np.square(np.diff(s.velocity) / dt), dt)
    if name == "J":
        return _simpson(np.square(np.diff(np.diff(s.velocity) / dt) / dt), dt)
    if name == "L":
        return _simpson(s.velocity, dt)
    if name == "Y":
        return _simpson(np.square(np.diff(s.orientation) / dt), dt)
    if name == "V":
        diff = (s.goal_v - s.velocity) if s.goal_v else np.zeros_like(s.velocity)
        return _simpson(np.square(diff), dt)
    if name in ("SA", "SR"):
        if s.steering is None:
            raise ValueError(f"{name} needs a steering angle, which a point-mass (PM) state has not")
        sig = s.steering if name == "SA" else np.diff(s.steering) / dt
        return _simpson(np.square(sig), dt)
    if name == "O":
        return _simpson(np.square(s.dpsi_lane), dt)
    if name == "LC":
        return _simpson(np.square(s.lat_lane), dt)
    if name == "D":
        return _simpson(np.exp(-D_DECAY * s.dist_ahead), dt)
    if name == "Jlon":
        return _simpson(np.square(_lon_jerk(s.lon, dt)), dt)
    raise ValueError(f"partial cost {name} is not implemented")


def signals(cr: CommonRoadProblem, solution: Any) -> _Signals:
    """The signals of the first planning-problem solution of ``solution`` (module docstring)."""
    from commonroad.common.util import Interval
    from commonroad_dc.feasibility.vehicle_dynamics import VehicleParameterMapping

    pps = solution.planning_problem_solutions[0]
    sl = pps.trajectory.state_list
    pm = pps.vehicle_model.name == "PM"
    vel = np.array([float(st.velocity) for st in sl])
    if pm:
        ori = np.array([math.atan2(float(st.velocity_y), float(st.velocity)) for st in sl])
    else:
        ori = np.array([float(st.orientation) for st in sl])
    steer = None if pm or not hasattr(sl[0], "steering_angle") else np.array([float(st.steering_angle) for st in sl])
    goals = [g.velocity.start if isinstance(g.velocity, Interval) else g.velocity
             for g in cr.planning_problem.goal.state_list if getattr(g, "velocity", None) is not None]
    s = _Signals(dt=cr.dt, k=np.array([float(st.time_step) for st in sl]),
                 position=np.array([np.asarray(st.position, dtype=float) for st in sl]), velocity=vel,
                 orientation=ori, steering=steer, goal_v=float(min(goals)) if goals else None)
    radius = float(VehicleParameterMapping.from_vehicle_type(pps.vehicle_type).w) / 2.5
    _lane_signals(cr, s, radius)
    return s


def evaluate(cr: CommonRoadProblem, solution: Any, cost_functions: tuple[str, ...] = REPORTED) -> dict[str, CostJSON]:
    """Every cost function of ``cost_functions`` on ``solution`` (module docstring).

    Parameters
    ----------
    cr : CommonRoadProblem
        The problem the solution solves (its scenario, goal and road frame).
    solution : commonroad.common.solution.Solution
        A ``PM`` or ``KS`` trajectory solution.
    cost_functions : tuple of str
        IDs of :data:`COST_FUNCTIONS`.

    Returns
    -------
    dict
        Per cost function: ``total`` (``None`` where a partial cost is undefined), the unweighted
        partial costs, and ``error`` (the reason, else ``None``).
    """
    s = signals(cr, solution)
    out: dict[str, CostJSON] = {}
    for cf in cost_functions:
        spec = COST_FUNCTIONS.get(cf)
        if spec is None:
            out[cf] = {"total": None, "partial": {},
                       "error": f"{cf} is not implemented (only {', '.join(COST_FUNCTIONS)})"}
            continue
        partial: dict[str, float] = {}
        try:
            for name, _ in spec:
                partial[name] = _partial(name, s)
        except ValueError as exc:
            out[cf] = {"total": None, "partial": partial, "error": str(exc)}
            continue
        bad = [n for n, v in partial.items() if not math.isfinite(v)]
        if bad:  # e.g. a trajectory that leaves the road: reported, never a NaN in a table
            out[cf] = {"total": None, "partial": partial, "error": f"partial cost {', '.join(bad)} is not finite"}
            continue
        out[cf] = {"total": float(sum(w * partial[n] for n, w in spec)), "partial": partial, "error": None}
    return out
