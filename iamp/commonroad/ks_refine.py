r"""A steered (``KS``) solution refined on the model itself where tracking a point-mass plan fails.

:func:`iamp.commonroad.ks.track` follows a road-frame plan with the ``KS`` model.  Where the plan
turns faster than the steering rate allows (low-speed lane changes that end straight, a plan that
slips between two vehicles late), the tracked car lags it: its heading misses the goal's interval
or its body meets a vehicle the plan cleared.  :func:`refine` then optimises the ``KS`` inputs
directly, starting from the tracked solution:

* **model**: the rear axle in the road frame (Frenet), state :math:`(s, d, \varphi, v, \delta)`
  (:math:`\varphi` the heading relative to the road),
  :math:`\dot s = v\cos\varphi / (1 - \kappa_r d)`, :math:`\dot d = v \sin\varphi`,
  :math:`\dot\varphi = v \tan\delta / l - \kappa_r \dot s`, :math:`\dot v = a`,
  :math:`\dot\delta = u`, inputs held over each step (RK4);
* **variables**: the initial steering angle (the planning problem leaves it free) and the
  inputs :math:`(u_k, a_k)` of every step, inside :data:`~iamp.commonroad.ks.INPUT_MARGIN` of
  the steering-rate and acceleration bounds;
* **residuals** (hinges, zero when met): every recorded vehicle's box at every step out of the
  body's rectangle at its heading grown by :data:`VEHICLE_BUFFER_M` (the separating-axis depth of
  :func:`~iamp.commonroad.planning.body_overlap`); the body's corners inside the road corridor
  and out of its holes; the final centre inside the goal piece's polygon, the final speed and
  heading inside the goal's intervals (with margins); the steering angle, the engine limit
  :math:`a \le a_{max} v_{switch}/v` and the friction circle as the checker tests them at each
  step's start (with the same margin); and a small pull toward the starting inputs;
* **solver**: ``scipy.optimize.least_squares`` (trust region, bounds), the Jacobian by forward
  differences computed for all variables in one batched simulation, at most
  :data:`MAX_EVALUATIONS` evaluations (a count, never a time).

The result is simulated again with the checker's own integrator
(``VehicleDynamics.forward_simulation``) from the planning problem's initial state, so its
states are exactly the checker's simulation of admissible inputs; :func:`refine` returns it only
when that solution clears every vehicle (the body check's buffer), stays on CommonRoad's road
(its own checker) and reaches the goal (CommonRoad's goal test).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from iamp.commonroad.convert import CommonRoadProblem
from iamp.commonroad.goal import Candidate
from iamp.commonroad.ks import INPUT_MARGIN, KSTrajectory, _params

FloatArray = npt.NDArray[np.float64]

#: Body buffer kept from every recorded vehicle's box while optimising [m] (the acceptance test
#: uses the body check's :data:`~iamp.commonroad.planning.CHECK_BUFFER_M`).
VEHICLE_BUFFER_M = 0.1
#: Clearance of the body's corners from the corridor's bounds while optimising [m].
ROAD_BUFFER_M = 0.03
#: Margins inside the goal: position [m], speed [m/s], orientation [rad].
GOAL_POSITION_M = 0.15
GOAL_SPEED_MPS = 0.05
GOAL_HEADING_RAD = 0.01
#: Weights of the residuals: constraints (per metre, m/s, rad, m/s²) and the pull toward the
#: starting inputs.
W_HARD = 10.0
W_PULL = 0.02
#: A vehicle's box farther along the road than this from the starting body at a step is left out.
NEAR_S_M = 15.0
#: Evaluations of the residuals and their Jacobian per optimisation (``least_squares``'s ``max_nfev``).
MAX_EVALUATIONS = 150
#: Final steps tried for each starting solution, relative to its own (inside the goal's window).
STEP_OFFSETS = (0, -4, 4, -2, 2)
#: Evaluations of every optimisation of one problem together (a count, never a time).
PROBLEM_EVALUATIONS = 600
#: Forward-difference step of the Jacobian.
FD_STEP = 1e-5


@dataclass(frozen=True)
class Checks:
    """iamp's own tests of a steered solution, handed in by :mod:`iamp.commonroad.planning` (which
    calls :func:`refine`; this module does not import it, so the two form no import cycle):
    ``step_boxes`` (the vehicles' boxes per step), ``body_overlap`` (a body's depth in a box),
    ``clear``, ``off_road`` and ``reaches_goal`` (a solution's verdicts)."""

    step_boxes: Callable[..., Any]
    body_overlap: Callable[..., Any]
    clear: Callable[..., Any]
    off_road: Callable[..., Any]
    reaches_goal: Callable[..., Any]


class SteeredTrajectory:
    """A road-frame plan that is a ``KS`` solution: the centre of ``ks`` in the road frame
    (linear between the time steps); :func:`iamp.commonroad.ks.track` returns ``ks`` itself."""

    def __init__(self, cr: CommonRoadProblem, ks: KSTrajectory, l_wb: float, b: float) -> None:
        self.steered = ks
        self.dt = cr.dt
        S = ks.states
        sd = np.asarray(cr.frame.to_road(ks.centre), dtype=float)
        psi, v, delta = S[:, 4], S[:, 3], S[:, 2]
        rate = v * np.tan(delta) / l_wb
        vel = np.column_stack([v * np.cos(psi) - b * rate * np.sin(psi), v * np.sin(psi) + b * rate * np.cos(psi)])
        vr = np.asarray(cr.frame.velocity_to_road(sd[:, 0], sd[:, 1], vel), dtype=float)
        self.X = np.column_stack([sd[:, 0], vr[:, 0], sd[:, 1], vr[:, 1]])
        self.t = np.arange(len(S)) * cr.dt
        self.U = np.diff(self.X[:, [1, 3]], axis=0) / cr.dt

    def states(self, t: npt.ArrayLike) -> FloatArray:
        tt = np.atleast_1d(np.asarray(t, dtype=float))
        return np.column_stack([np.interp(tt, self.t, self.X[:, i]) for i in range(4)])

    def inputs(self, t: npt.ArrayLike) -> FloatArray:
        tt = np.atleast_1d(np.asarray(t, dtype=float))
        k = np.clip(np.floor(tt / self.dt + 1e-9).astype(int), 0, len(self.U) - 1)
        return np.asarray(self.U[k], dtype=float)

    def cost(self) -> float:
        return float(0.5 * np.sum(self.U**2) * self.dt)


class _Model:
    """The batched Frenet ``KS`` simulation and the residuals of :func:`refine`."""

    def __init__(self, cr: CommonRoadProblem, cand: Candidate, p: Any, start: KSTrajectory, checks: Checks) -> None:
        self.checks = checks
        self.cr, self.K, self.dt = cr, cand.steps, cr.dt
        self.l = float(p.a + p.b)
        self.b = float(p.b)
        st, lon = p.steering, p.longitudinal
        self.d_max = INPUT_MARGIN * float(st.max)
        self.a_max = INPUT_MARGIN * float(lon.a_max)
        self.v_switch = float(lon.v_switch)
        self.lo = np.concatenate([[-self.d_max], np.full(self.K, INPUT_MARGIN * float(st.v_min)),
                                  np.full(self.K, -self.a_max)])
        self.hi = np.concatenate([[self.d_max], np.full(self.K, INPUT_MARGIN * float(st.v_max)),
                                  np.full(self.K, self.a_max)])
        # the road's heading and curvature on a grid (the rear axle's s stays within it)
        s_all = np.asarray(cr.frame.to_road(start.states[:, :2]), dtype=float)[:, 0]
        self.grid = np.arange(s_all.min() - 60.0, s_all.max() + 60.0, 0.25)
        self.kap = np.asarray(cr.frame.curvature(self.grid), dtype=float)
        self.head = np.asarray(cr.frame.heading(self.grid), dtype=float)
        init = cr.planning_problem.initial_state
        psi0 = float(init.orientation)
        rear0 = np.asarray(init.position, dtype=float) - self.b * np.array([math.cos(psi0), math.sin(psi0)])
        s0, d0 = np.asarray(cr.frame.to_road(rear0[None, :]), dtype=float)[0]
        self.x0 = (float(s0), float(d0), _wrap(psi0 - float(np.interp(s0, self.grid, self.head))),
                   float(init.velocity))
        self.z0 = np.concatenate([[start.states[0, 2]], start.inputs[:, 0], start.inputs[:, 1]])
        self.z0 = np.clip(self.z0, self.lo, self.hi)
        # the vehicles near the starting solution at each step
        boxes = self.checks.step_boxes(cr, self.K)  # (4, K+1, m)
        c0 = np.asarray(cr.frame.to_road(start.centre), dtype=float)
        near = np.abs(0.5 * (boxes[0] + boxes[1]) - c0[:, 0:1]) < NEAR_S_M
        near[0] = False
        kk, ii = np.nonzero(near & np.isfinite(boxes[0]))
        self.pairs_k = kk
        self.pair_box = boxes[:, kk, ii]  # (4, P)
        self.holes = [(float(ob.s_lo.min()), float(ob.s_hi.max()), float(ob.d_lo.min()), float(ob.d_hi.max()))
                      for ob in cr.road_edges if ob.hole]
        self.road: tuple[FloatArray, FloatArray, FloatArray] | None = None
        if cr.corridor is not None:
            g, lo_, hi_ = cr.corridor
            ok = np.isfinite(lo_) & np.isfinite(hi_)
            self.road = (g[ok], lo_[ok], hi_[ok])
        e = cr.goal.elements[cand.element]
        self.goal = e
        self.piece = e.pieces[cand.piece] if e.pieces else None

    def simulate(self, Z: FloatArray) -> FloatArray:
        """States ``(n, K+1, 5)`` = ``(s, d, φ, v, δ)`` of the rear axle for each row of ``Z``."""
        n, K, dt, l_wb = Z.shape[0], self.K, self.dt, self.l
        X = np.empty((n, K + 1, 5))
        X[:, 0, :4] = self.x0
        X[:, 0, 4] = Z[:, 0]
        U1, A = Z[:, 1:K + 1], Z[:, K + 1:]

        def f(x: FloatArray, u: FloatArray, a: FloatArray) -> FloatArray:
            s, d, ph, v, de = x[:, 0], x[:, 1], x[:, 2], x[:, 3], x[:, 4]
            k = np.interp(s, self.grid, self.kap)
            sdot = v * np.cos(ph) / (1.0 - k * d)
            return np.stack([sdot, v * np.sin(ph), v * np.tan(de) / l_wb - k * sdot, a, u], axis=1)

        for j in range(K):
            x, u, a = X[:, j], U1[:, j], A[:, j]
            k1 = f(x, u, a)
            k2 = f(x + 0.5 * dt * k1, u, a)
            k3 = f(x + 0.5 * dt * k2, u, a)
            k4 = f(x + dt * k3, u, a)
            X[:, j + 1] = x + dt / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
        return X

    def residuals(self, Z: FloatArray) -> FloatArray:
        """The residual vectors ``(n, R)`` of the rows of ``Z`` (module docstring)."""
        body_overlap = self.checks.body_overlap
        X = self.simulate(Z)
        cr, K = self.cr, self.K
        s, d, ph, v, de = (X[..., i] for i in range(5))
        k = np.interp(s, self.grid, self.kap)
        sc = s + self.b * np.cos(ph) / (1.0 - k * d)
        dc = d + self.b * np.sin(ph)
        L2, W2 = cr.ego_length / 2, cr.ego_width / 2
        out = []
        # the vehicles
        kk = self.pairs_k
        bx = self.pair_box
        ov = body_overlap(sc[:, kk], dc[:, kk], ph[:, kk], bx[0], bx[1], bx[2], bx[3], L2, W2, VEHICLE_BUFFER_M)
        out.append(W_HARD * np.maximum(ov, 0.0))
        # the road: the body's corners within the corridor, out of its holes
        c, sn = np.cos(ph[:, 1:]), np.sin(ph[:, 1:])
        for ox, oy in ((L2, W2), (L2, -W2), (-L2, W2), (-L2, -W2)):
            cs = sc[:, 1:] + ox * c - oy * sn
            cd = dc[:, 1:] + ox * sn + oy * c
            if self.road is not None:
                g, lo_, hi_ = self.road
                out.append(W_HARD * np.maximum(cd - (np.interp(cs, g, hi_) - ROAD_BUFFER_M), 0.0))
                out.append(W_HARD * np.maximum((np.interp(cs, g, lo_) + ROAD_BUFFER_M) - cd, 0.0))
            else:
                y_lo, y_hi = cr.road_y
                out.append(W_HARD * np.maximum(cd - (y_hi - ROAD_BUFFER_M), 0.0))
                out.append(W_HARD * np.maximum((y_lo + ROAD_BUFFER_M) - cd, 0.0))
        for h in self.holes:
            one = np.ones_like(sc[:, 1:])
            hv = body_overlap(sc[:, 1:], dc[:, 1:], ph[:, 1:], h[0] * one, h[1] * one, h[2] * one, h[3] * one,
                              L2, W2, ROAD_BUFFER_M)
            out.append(W_HARD * np.maximum(hv, 0.0))
        # the goal at the final step
        g_out = []
        if self.piece is not None:
            A, bb = np.asarray(self.piece.A, dtype=float), np.asarray(self.piece.b, dtype=float)
            norm = np.linalg.norm(A, axis=1)
            P = np.stack([sc[:, K], dc[:, K]], axis=1)
            g_out.append(np.maximum(P @ A.T - (bb - GOAL_POSITION_M * norm), 0.0))
        if self.goal.speed is not None:
            lo_v, hi_v = self.goal.speed
            g_out.append(np.maximum(v[:, K:K + 1] - (hi_v - GOAL_SPEED_MPS), 0.0))
            g_out.append(np.maximum((lo_v + GOAL_SPEED_MPS) - v[:, K:K + 1], 0.0))
        if self.goal.orientation is not None:
            o_lo, o_hi = self.goal.orientation
            mid, half = 0.5 * (o_lo + o_hi), 0.5 * (o_hi - o_lo) - GOAL_HEADING_RAD
            psi = ph[:, K] + np.interp(s[:, K], self.grid, self.head)
            off = np.abs((psi - mid + math.pi) % (2 * math.pi) - math.pi)
            g_out.append(np.maximum(off - half, 0.0)[:, None])
        if g_out:
            out.append(W_HARD * np.concatenate(g_out, axis=1))
        # the model's limits at each step's start (as the checker tests them)
        Aacc = Z[:, K + 1:]
        vs, ds = v[:, :K], de[:, :K]
        out.append(W_HARD * np.maximum(np.abs(de[:, 1:]) - self.d_max, 0.0))
        engine = self.a_max * self.v_switch / np.maximum(vs, self.v_switch)
        out.append(W_HARD * np.maximum(Aacc - engine, 0.0))
        lat = vs * vs * np.tan(ds) / self.l
        out.append(W_HARD * np.maximum(np.sqrt(Aacc**2 + lat**2 + 1e-12) - self.a_max, 0.0))
        out.append(W_HARD * np.maximum(0.05 - v[:, 1:], 0.0))
        out.append(W_PULL * math.sqrt(self.dt) * (Z - self.z0[None, :]))
        return np.concatenate(out, axis=1)


def _wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def retimed(start: KSTrajectory, steps: int) -> KSTrajectory:
    """``start`` cut to ``steps`` steps, or continued to them with zero inputs (its last state
    held: only the inputs, the initial steering angle and the centres' rough whereabouts are used
    by :func:`refine`)."""
    K = len(start.inputs)
    if steps <= K:
        return KSTrajectory(start.states[:steps + 1], start.inputs[:steps], start.centre[:steps + 1],
                            start.deviation_m, start.vehicle_type)
    extra = steps - K
    return KSTrajectory(np.vstack([start.states, np.repeat(start.states[-1:], extra, 0)]),
                        np.vstack([start.inputs, np.zeros((extra, 2))]),
                        np.vstack([start.centre, np.repeat(start.centre[-1:], extra, 0)]),
                        start.deviation_m, start.vehicle_type)


def refine(cr: CommonRoadProblem, start: KSTrajectory, cand: Candidate, checks: Checks,
           max_evaluations: int = MAX_EVALUATIONS) -> tuple[KSTrajectory | None, int]:
    """The ``KS`` solution of the module docstring, optimised from ``start`` (a tracked solution
    over ``cand.steps`` steps ending in ``cand``'s goal state), or None when the optimum is not
    accepted (a vehicle, the road or the goal not met by the checker's own simulation).

    Parameters
    ----------
    cr : CommonRoadProblem
    start : KSTrajectory
        The starting solution (:func:`iamp.commonroad.ks.track` of a plan).
    cand : Candidate
        The final state whose goal element and piece the solution must reach at its last step.
    checks : Checks
        iamp's tests of a steered solution (:func:`iamp.commonroad.planning.refine_checks`).
    max_evaluations : int
        Evaluations of the residuals (with their Jacobian) at most.

    Returns
    -------
    (KSTrajectory or None, int)
        The solution and the evaluations spent.
    """
    from scipy.optimize import least_squares

    if cand.steps < 2 or cand.element >= len(cr.goal.elements) or max_evaluations < 1:
        return None, 0
    p = _params(start.vehicle_type)
    m = _Model(cr, cand, p, start, checks)
    n = m.z0.size

    def fun(z: FloatArray) -> FloatArray:
        return np.asarray(m.residuals(z[None, :])[0], dtype=float)

    def jac(z: FloatArray) -> FloatArray:
        h = FD_STEP * np.where(z + FD_STEP <= m.hi, 1.0, -1.0)
        Z = np.repeat(z[None, :], n + 1, axis=0)
        Z[1 + np.arange(n), np.arange(n)] += h
        R = m.residuals(Z)
        return np.asarray(((R[1:] - R[0][None, :]) / h[:, None]).T, dtype=float)

    # lsmr: matrix-vector products only (a dense SVD per iteration spins every BLAS thread)
    sol = least_squares(fun, m.z0, jac=jac, bounds=(m.lo, m.hi), method="trf", tr_solver="lsmr",
                        max_nfev=max_evaluations)
    return _accept(cr, cand, m, np.clip(sol.x, m.lo, m.hi), start), int(sol.nfev)


def _accept(cr: CommonRoadProblem, cand: Candidate, m: _Model, z: FloatArray,
            start: KSTrajectory) -> KSTrajectory | None:
    """The checker's simulation of the inputs ``z``, if it clears the vehicles, stays on the road
    and reaches the goal (module docstring)."""
    from commonroad.common.solution import VehicleType
    from commonroad_dc.feasibility.vehicle_dynamics import VehicleDynamics

    K = m.K
    dyn = VehicleDynamics.KS(VehicleType(start.vehicle_type))
    init = cr.planning_problem.initial_state
    psi0 = float(init.orientation)
    c0 = np.asarray(init.position, dtype=float)
    x = np.array([c0[0] - m.b * math.cos(psi0), c0[1] - m.b * math.sin(psi0), float(z[0]), float(init.velocity),
                  psi0])
    states = [x.copy()]
    U = np.column_stack([z[1:K + 1], z[K + 1:]])
    for k in range(K):
        nxt = dyn.forward_simulation(x, U[k], cr.dt, throw=False)
        if nxt is None:
            return None
        x = np.asarray(nxt, dtype=float)
        states.append(x.copy())
    S = np.array(states)
    centre = S[:, :2] + m.b * np.column_stack([np.cos(S[:, 4]), np.sin(S[:, 4])])
    # the checker's limits at each step's start (the optimiser's hinges may leave a residue)
    lat = S[:K, 3] ** 2 * np.tan(S[:K, 2]) / m.l
    engine = m.a_max * m.v_switch / np.maximum(S[:K, 3], m.v_switch) / INPUT_MARGIN
    if (np.any(np.hypot(U[:, 1], lat) > m.a_max / INPUT_MARGIN) or np.any(U[:, 1] > engine)
            or np.any(np.abs(S[:, 2]) > m.d_max / INPUT_MARGIN) or np.any(S[:, 3] < 0.0)):
        return None
    ks = KSTrajectory(states=S, inputs=U, centre=centre,
                      deviation_m=float(np.max(np.linalg.norm(centre - start.centre, axis=1))),
                      vehicle_type=start.vehicle_type)
    if not m.checks.clear(cr, centre, S[:, 4]):
        return None
    if m.checks.off_road(cr, centre, S[:, 4])[1:].any():
        return None
    if not m.checks.reaches_goal(cr, ks):
        return None
    return ks
