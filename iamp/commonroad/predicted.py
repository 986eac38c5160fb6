r"""The predicted mode of ``iamp commonroad plan|bench --predict``: the §7 predictor instead of
the recorded future.

The planner sees, for every recorded vehicle, only what was observable at ``t = 0``: its
state in the scenario file (position, heading, speed and the recorded NGSIM acceleration
:math:`a_0`).  The CommonRoad benchmark files hold no earlier past (every obstacle's record
starts at time step 0), so the §7 chain is started from the bin of :math:`a_0` in each of its
``n`` history states, :math:`\hat x_0 = e_{b(a_0)}`, and propagated,

.. math::  \hat x_k = \sum_{i=1}^{n} \lambda_i Q_i \hat x_{k-i}, \qquad
           \bar a_k = c^\top \hat x_k,

the expected acceleration integrated exactly (piecewise linear between the model's nodes,
speed clamped at 0) from the recorded :math:`(s_0, \dot s_0)` and fitted by a least-squares
cubic, as in the paper's pipeline.  Laterally a predicted vehicle keeps its lane: its box is
the recorded box at ``t = 0`` for the whole horizon (the chain predicts no lane change).  The
plan is then judged by CommonRoad's checker against the *recorded* future, so the difference
between ``--predict`` and the recorded mode is the cost of prediction error.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from iamp.commonroad.convert import CommonRoadProblem, Obstacle
from iamp.prediction.predictor import Predictor


def predict_obstacles(cr: CommonRoadProblem, predictor: Predictor | None = None) -> CommonRoadProblem:
    """``cr`` with every obstacle's future replaced by the §7 prediction (module docstring).

    Parameters
    ----------
    cr : CommonRoadProblem
        The problem read with its recorded obstacles (:func:`~iamp.commonroad.convert.load`).
    predictor : iamp.prediction.predictor.Predictor, optional
        The predictor (default: the shipped model).
    """
    from iamp.prediction.kinematics import integrate_nodes

    pred = predictor if predictor is not None else Predictor.default()
    model = pred.model
    accel0 = {int(o.obstacle_id): float(getattr(o.initial_state, "acceleration", 0.0) or 0.0)
              for o in cr.scenario.dynamic_obstacles}
    out: list[Obstacle] = []
    for ob in cr.obstacles:
        if ob.t[0] > 1e-9:  # appears later: nothing observed at t = 0, so nothing to predict from
            continue
        half0 = 0.5 * float(ob.s_hi[0] - ob.s_lo[0])
        s0 = 0.5 * float(ob.s_hi[0] + ob.s_lo[0])
        v0 = _road_speed(cr, ob.obstacle_id, s0, 0.5 * float(ob.d_lo[0] + ob.d_hi[0]))
        T = float(ob.t[-1]) if ob.t.size > 1 else pred.dt
        M = max(int(np.ceil(T / pred.dt - 1e-9)), 1)
        states = np.full(model.order, model.states(accel0.get(ob.obstacle_id, 0.0)), dtype=np.int64)
        _, abar = pred._node_accelerations(states, M)
        x, _v = integrate_nodes(s0, v0, abar, pred.dt, ob.t)
        centre = np.asarray(x[0], dtype=float)
        deg = int(min(3, ob.t.size - 1))
        coeffs = np.polynomial.polynomial.polyfit(ob.t, centre, deg) if deg > 0 else np.array([centre[0]])
        resid = float(np.max(np.abs(np.polynomial.polynomial.polyval(ob.t, coeffs) - centre)))
        n = ob.t.size
        out.append(dataclasses.replace(
            ob, s_lo=centre - half0, s_hi=centre + half0, d_lo=np.full(n, ob.d_lo[0]), d_hi=np.full(n, ob.d_hi[0]),
            cubic=tuple(float(c) for c in coeffs), half_length=half0 + resid, fit_residual_m=resid,
            lane_change=False))
    notes = [*cr.notes, f"--predict: {len(out)} vehicles predicted by the MTD chain ({pred.name}) from their state "
                        "at t = 0, lane kept; vehicles appearing later are not known to the planner"]
    return dataclasses.replace(cr, obstacles=out, notes=notes)


def _road_speed(cr: CommonRoadProblem, obstacle_id: int, s: float, d: float) -> float:
    """Speed along the road of obstacle ``obstacle_id`` at ``t = 0``."""
    import math

    o = cr.scenario.obstacle_by_id(obstacle_id)
    st = o.initial_state
    vel = np.array([[float(st.velocity) * math.cos(float(st.orientation)),
                     float(st.velocity) * math.sin(float(st.orientation))]])
    return max(0.0, float(cr.frame.velocity_to_road(s, d, vel)[0, 0]))
