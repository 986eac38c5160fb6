r"""A road-frame plan as a steered car: the kinematic single-track model ``KS`` of
``commonroad-vehicle-models`` (vehicle types 1-3), as CommonRoad's feasibility checker tests it.

The ``KS`` state is :math:`x = (p_x, p_y, \delta, v, \psi)` at the **rear axle** (steering angle
:math:`\delta`, speed :math:`v`, heading :math:`\psi`), the input :math:`u = (\dot\delta, a)`, held
constant over a time step :math:`\Delta t`:

.. math:: \dot p = v\,(\cos\psi, \sin\psi), \quad \dot\psi = \frac{v}{l}\tan\delta, \quad
          \dot\delta = u_1, \quad \dot v = u_2, \qquad l = a + b,

with :math:`u_1 \in [\dot\delta_{min}, \dot\delta_{max}]`, :math:`|u_2| \le a_{max}` (above
:math:`v_{switch}` at most :math:`a_{max} v_{switch}/v`), and the friction circle
:math:`u_2^2 + (v\dot\psi)^2 \le a_{max}^2`.  A CommonRoad ``KS`` state stores the **centre**
:math:`p + b(\cos\psi, \sin\psi)`.  The checker (``commonroad_dc.feasibility.feasibility_checker.
trajectory_feasibility``) reconstructs one input per step by SLSQP from :math:`u = 0` and accepts
the step when the simulated centre is within 2 cm and the heading within 0.03 rad.

Conversion (:func:`track`):

1. **Flatness.**  The rear axle is the model's flat output.  From the plan's centre path
   :math:`c(t)` (sampled at :math:`\Delta t / 10`, continued at constant velocity beyond its
   ends) the rear axle :math:`r = c - b(\cos\psi, \sin\psi)` must move along its heading, so
   :math:`\dot\psi = \dot c \cdot n(\psi) / b` (:math:`n` the left normal; the trailer
   equation, stable forward in time), integrated (RK4) from the initial orientation; this gives
   :math:`\psi_{ref}`, :math:`v_{ref} = \dot c \cdot (\cos\psi, \sin\psi)`, the curvature
   :math:`\kappa_{ref} = \dot\psi / v_{ref}` and the steering
   :math:`\delta_{ref} = \arctan(l\kappa_{ref})`.
2. **Tracking by forward simulation.**  The ``KS`` model is simulated step by step with the
   checker's own integrator (``VehicleDynamics.forward_simulation``, ``odeint``) from the
   planning problem's initial state (the initial steering angle, which the planning problem does
   not fix, is :math:`\delta_{ref}(0)`), each step's input chosen by a tracking controller and
   clipped into the model's bounds with a margin (:data:`INPUT_MARGIN`):
   longitudinal :math:`a = a_{ref} + k_v (v_{ref} - v) - k_s e_s`, lateral (the linearised
   path error :math:`\ddot e_d \approx v^2(\kappa - \kappa_{ref})` placed at a double pole
   :math:`-\omega`) :math:`\kappa = \kappa_{ref} - (\omega^2 e_d + 2\omega v \sin e_\psi)/v^2`,
   the steering rate reaching :math:`\arctan(l\kappa)` at the end of the step.
3. **Learning passes** (:data:`LEARNING_PASSES`, a fixed count): the reference is shifted along
   the path by the last pass's along-path error and the simulation repeated; the best pass is
   kept.  On the 18 US-101 problems (``reports/commonroad``) the default planner's largest
   deviation is 0.48 cm (median 0.13 cm); the paper's all-vehicle PMP plans accelerate beyond the
   ``KS`` limit :math:`a_{max} v_{switch} / v` and are followed up to 82 cm off (still valid).

Every written state is therefore exactly the checker's simulation of an admissible input, so its
feasibility test accepts it; the price is the tracking error, reported as the largest distance
between the ``KS`` centre and the plan's centre at the time steps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from iamp.commonroad import require
from iamp.commonroad.convert import CommonRoadProblem
from iamp.core.errors import ScenarioError
from iamp.core.plan import Trajectory

FloatArray = npt.NDArray[np.float64]

#: The vehicle types of ``commonroad-vehicle-models`` whose ``KS`` parameters CommonRoad's
#: checker knows (1: Ford Escort, 2: BMW 320i, 3: VW Vanagon).
VEHICLE_TYPES = (1, 2, 3)
#: Fraction of each input bound (steering rate, acceleration, friction circle) the controller uses:
#: the checker rounds inputs to 4 decimals and its minimiser must find the input inside the bounds.
INPUT_MARGIN = 0.95
#: Samples of the plan per time step for the flatness reference.
SUBSTEPS = 10
#: Samples the plan is continued by (constant velocity) at both ends for the differences.
EDGE = 20
#: Tracking gains: speed [1/s], along-track position [1/s^2], lateral pole [rad/s].
K_V = 2.0
K_S = 1.0
OMEGA = 1.2
#: Speed below which the lateral law uses this speed (its gain grows as 1/v^2) [m/s].
V_FLOOR = 2.0
#: Tracking passes after the first, each on the reference shifted by the last pass's error.
LEARNING_PASSES = 2


@dataclass
class KSTrajectory:
    """A ``KS`` trajectory at the scenario's time steps.

    Attributes
    ----------
    states : ndarray, shape (K+1, 5)
        Rear-axle states ``(p_x, p_y, delta, v, psi)``.
    inputs : ndarray, shape (K, 2)
        ``(steering rate, acceleration)`` held over each step.
    centre : ndarray, shape (K+1, 2)
        The centre positions CommonRoad stores.
    deviation_m : float
        Largest distance between ``centre`` and the plan's centre at the time steps.
    vehicle_type : int
        1, 2 or 3.
    """

    states: FloatArray
    inputs: FloatArray
    centre: FloatArray
    deviation_m: float
    vehicle_type: int


def _wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def _params(vehicle_type: int) -> Any:
    from commonroad.common.solution import VehicleType
    from commonroad_dc.feasibility.vehicle_dynamics import VehicleParameterMapping

    if vehicle_type not in VEHICLE_TYPES:
        raise ScenarioError(f"vehicle type {vehicle_type} has no KS parameters (choose 1, 2 or 3)", "--vehicle-type")
    return VehicleParameterMapping.from_vehicle_type(VehicleType(vehicle_type))


def reference(cr: CommonRoadProblem, trajectory: Trajectory, steps: int, b: float,
              l_wb: float, shift: FloatArray | None = None) -> dict[str, FloatArray]:
    """The flat-output reference of the module docstring on the grid ``t = j Δt / SUBSTEPS``.

    Parameters
    ----------
    cr : CommonRoadProblem
        The problem (road frame, ``dt``, initial state).
    trajectory : Trajectory
        The road-frame plan.
    steps : int
        Number of time steps ``K`` of the solution.
    b : float
        Distance from the centre to the rear axle [m].
    l_wb : float
        Wheelbase ``a + b`` [m].
    shift : ndarray, shape (n, 2), optional
        Added to the plan's centre path before the reference is derived (the learning passes of
        :func:`track`); the returned ``centre`` is the plan's own.

    Returns
    -------
    dict
        Arrays ``t``, ``centre`` (n, 2), ``rear`` (n, 2), ``psi``, ``v``, ``kappa``, ``delta``, ``a``.
    """
    h = cr.dt / SUBSTEPS
    t = np.arange(steps * SUBSTEPS + 1) * h
    X = trajectory.states(t)
    C = cr.frame.to_world(X[:, 0], X[:, 2])
    V = cr.frame.velocity_to_world(X[:, 0], X[:, 2], X[:, 1], X[:, 3])
    n = len(t)
    # continued at constant velocity for EDGE samples on both sides, so that the differences below
    # are central at the plan's ends (one-sided ones put spurious curvature there)
    j = np.arange(1, EDGE + 1)[:, None] * h
    C = np.vstack([C[0] + V[0] * -j[::-1], C, C[-1] + V[-1] * j])
    V = np.vstack([np.repeat(V[:1], EDGE, 0), V, np.repeat(V[-1:], EDGE, 0)])
    psi0 = float(cr.planning_problem.initial_state.orientation)
    Cs = C if shift is None else C + np.pad(shift, ((EDGE, EDGE), (0, 0)), mode="edge")
    Vs = V if shift is None else V + np.gradient(Cs - C, h, axis=0, edge_order=2)
    # the rear axle r = c - b (cos psi, sin psi) moves along its heading psi: the component of its
    # velocity c' - b psi' n(psi) normal to the heading vanishes, psi' = (c' . n(psi)) / b; integrated
    # (RK4, c' linear between samples) from the initial orientation: a flat output consistent with
    # the plan's centre and the initial state (the trailer equation; stable forward in time)
    psi = np.full(len(Cs), psi0)

    def rate(q: float, w: FloatArray) -> float:
        return float(-w[0] * math.sin(q) + w[1] * math.cos(q)) / b

    for i in range(EDGE, len(Cs) - 1):
        w0, w1 = Vs[i], Vs[i + 1]
        wm = 0.5 * (w0 + w1)
        k1 = rate(psi[i], w0)
        k2 = rate(psi[i] + 0.5 * h * k1, wm)
        k3 = rate(psi[i] + 0.5 * h * k2, wm)
        k4 = rate(psi[i] + h * k3, w1)
        psi[i + 1] = psi[i] + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
    e = np.column_stack([np.cos(psi), np.sin(psi)])
    R = Cs - b * e
    v = np.einsum("ij,ij->i", Vs, e)
    dpsi = (-Vs[:, 0] * np.sin(psi) + Vs[:, 1] * np.cos(psi)) / b
    kappa = np.where(np.abs(v) > 0.1, dpsi / np.where(np.abs(v) > 0.1, v, 1.0), 0.0)
    acc = np.gradient(v, h, edge_order=2)
    inner = slice(EDGE, EDGE + n)
    return {"t": t, "centre": C[inner], "rear": R[inner], "psi": psi[inner], "v": v[inner],
            "kappa": kappa[inner], "delta": np.arctan(l_wb * kappa[inner]), "a": acc[inner]}


def _simulate(dyn: Any, p: Any, ref: dict[str, FloatArray], x0: FloatArray, steps: int,
              dt: float) -> tuple[FloatArray, FloatArray]:
    """One closed-loop pass of the tracking controller (module docstring): states and inputs."""
    l_wb = float(p.a + p.b)
    st, lon = p.steering, p.longitudinal
    dd_lo, dd_hi = INPUT_MARGIN * float(st.v_min), INPUT_MARGIN * float(st.v_max)
    d_lo, d_hi = INPUT_MARGIN * float(st.min), INPUT_MARGIN * float(st.max)
    a_max = INPUT_MARGIN * float(lon.a_max)
    x = x0.copy()
    states = [x.copy()]
    inputs = []
    for k in range(steps):
        j, j1 = k * SUBSTEPS, (k + 1) * SUBSTEPS
        jm = j + SUBSTEPS // 2
        psi_r = float(ref["psi"][j])
        tang = np.array([math.cos(psi_r), math.sin(psi_r)])
        e = x[:2] - ref["rear"][j]
        e_s = float(e @ tang)
        e_d = float(e[1] * tang[0] - e[0] * tang[1])
        e_psi = _wrap(float(x[4]) - psi_r)
        v = float(x[3])
        # longitudinal
        acc = float(ref["a"][jm]) + K_V * (float(ref["v"][jm]) - v) - K_S * e_s
        pos_limit = a_max * float(lon.v_switch) / v if v > float(lon.v_switch) else a_max
        # lateral: the curvature wanted at the end of the step
        ve = max(v, V_FLOOR)
        kappa = float(ref["kappa"][j1]) - (OMEGA**2 * e_d + 2.0 * OMEGA * ve * math.sin(e_psi)) / ve**2
        # within the friction circle at the next step's start (its speed at most v + a_max dt): a
        # steering angle whose lateral acceleration alone exceeds a_max leaves no admissible input
        v_next = max(v + a_max * dt, 0.1)
        kappa = float(np.clip(kappa, -a_max / v_next**2, a_max / v_next**2))
        delta_cmd = float(np.clip(math.atan(l_wb * kappa), d_lo, d_hi))
        ddelta = float(np.clip((delta_cmd - float(x[2])) / dt, dd_lo, dd_hi))
        # friction circle at the step's start (as the checker tests it): a^2 + (v psi_dot)^2 <= a_max^2
        lat = v * v * math.tan(float(x[2])) / l_wb
        room = math.sqrt(max(a_max**2 - lat**2, 0.0))
        acc = float(np.clip(acc, -min(room, a_max), min(room, pos_limit)))
        if v + acc * dt < 0.0:  # no reversing: stop at v = 0
            acc = -v / dt
        u = np.array([ddelta, acc])
        nxt = dyn.forward_simulation(x, u, dt, throw=False)
        if nxt is None:  # cannot happen with the margins above; refuse rather than write it
            raise ScenarioError(f"the KS tracking input {u.tolist()} at step {k} is outside the model's bounds",
                                "vehicle_model")
        x = np.asarray(nxt, dtype=float)
        inputs.append(u)
        states.append(x.copy())
    return np.array(states), np.array(inputs).reshape(-1, 2)


def track(cr: CommonRoadProblem, trajectory: Trajectory, steps: int, vehicle_type: int = 2) -> KSTrajectory:
    """The ``KS`` trajectory that tracks the plan (module docstring).

    After the first pass, :data:`LEARNING_PASSES` more passes each shift the reference along the
    path by the previous pass's along-path error at the time steps (iterative learning control:
    the speed loop's systematic lag is taken out); the pass with the smallest largest deviation
    is kept.  The
    number of passes is fixed, so the result is the same on any machine.  A plan that is a
    steered solution already (:class:`iamp.commonroad.ks_refine.SteeredTrajectory`, the inputs
    optimised on the model) is that solution.

    Parameters
    ----------
    cr : CommonRoadProblem
        The problem the plan solves.
    trajectory : Trajectory
        The road-frame plan.
    steps : int
        Number of time steps ``K``.
    vehicle_type : int
        CommonRoad vehicle type 1, 2 or 3.

    Returns
    -------
    KSTrajectory
        States, inputs, centre positions and the largest deviation from the plan.

    Raises
    ------
    ScenarioError
        For a vehicle type without ``KS`` parameters.
    """
    require()
    from commonroad.common.solution import VehicleType
    from commonroad_dc.feasibility.vehicle_dynamics import VehicleDynamics

    # a plan that is a steered solution already (iamp.commonroad.ks_refine.SteeredTrajectory)
    steered = getattr(trajectory, "steered", None)
    if (isinstance(steered, KSTrajectory) and steered.vehicle_type == vehicle_type
            and len(steered.states) == steps + 1):
        return steered
    p: Any = _params(vehicle_type)
    dyn = VehicleDynamics.KS(VehicleType(vehicle_type))
    b = float(p.b)
    l_wb = float(p.a + p.b)
    d_max = INPUT_MARGIN * float(p.steering.max)
    init = cr.planning_problem.initial_state
    psi0 = float(init.orientation)
    c0 = np.asarray(init.position, dtype=float)
    shift = None
    best: KSTrajectory | None = None
    for _ in range(1 + LEARNING_PASSES):
        ref = reference(cr, trajectory, steps, b, l_wb, shift)
        x0 = np.array([c0[0] - b * math.cos(psi0), c0[1] - b * math.sin(psi0),
                       float(np.clip(ref["delta"][0], -d_max, d_max)), float(init.velocity), psi0])
        S, U = _simulate(dyn, p, ref, x0, steps, cr.dt)
        centre = S[:, :2] + b * np.column_stack([np.cos(S[:, 4]), np.sin(S[:, 4])])
        plan_centre = ref["centre"][::SUBSTEPS].copy()
        plan_centre[0] = c0
        err = centre - plan_centre
        dev = float(np.max(np.linalg.norm(err, axis=1)))
        if best is None or dev < best.deviation_m:
            best = KSTrajectory(states=S, inputs=U, centre=centre, deviation_m=dev, vehicle_type=vehicle_type)
        # along the path only: the lateral error is the initial heading's (a state the solution must
        # keep), which a shifted reference cannot take out (the learning diverges laterally)
        psi = ref["psi"][::SUBSTEPS]
        along = err[:, 0] * np.cos(psi) + err[:, 1] * np.sin(psi)
        fine = np.interp(ref["t"], ref["t"][::SUBSTEPS], along)[:, None] * np.column_stack(
            [np.cos(ref["psi"]), np.sin(ref["psi"])])
        shift = -fine if shift is None else shift - fine
    assert best is not None
    return best
