r"""The PMP plan checks itself before it is called optimal (issue 9.1).

Every condition the planner solved is recomputed from the returned solution, made
dimensionless with the units of :mod:`iamp.planners.pmp.scale` (time ``T = t_f``, length
``L``), and compared with a named entry of :mod:`iamp.core.tolerances`:

* ``linear_system`` — backward error
  :math:`\|\tilde M\tilde z-\tilde r\|_\infty/(\|\tilde M\|_\infty\|\tilde z\|_\infty+\|\tilde r\|_\infty)`
  of the scaled jump system (``pmp_linear_system_rel``);
* ``boundary`` — :math:`|s(0)-s_0|/L`, :math:`|v(0)-v_0|T/L`, the same at :math:`t_f`
  (``pmp_scaled_residual``);
* ``corner`` — :math:`|s(t_i)-\text{corner}_i(t_i)|/L` (``pmp_scaled_residual``);
* ``h_minimisation`` — :math:`|u+p_{2,4}|\,T^2/L` at ``0, t_i, t_f`` (``pmp_scaled_residual``);
* ``costate_jump`` — :math:`|p^-_{1,3}-p^+_{1,3}-\Phi|\,T^3/L` and
  :math:`|p^-_{2,4}-p^+_{2,4}|\,T^2/L` (``pmp_scaled_residual``);
* ``hamiltonian_jump`` — :math:`|H^- - H^+ - \dot x_s\Phi_x|` over the size of its terms,
  :math:`|\Phi_x|(|v_x|+|\dot x_s|)+|\Phi_y||v_y|`, floored at :data:`HJUMP_FLOOR` units of
  :math:`H` (``pmp_hjump_rel``; free contact times only).  The floor matters when the corner
  lies on (or within rounding of) the unconstrained path: the jumps vanish, the condition
  reduces to the continuity of :math:`H`, and the residual is held to the absolute scaled
  ``pmp_scaled_residual`` like the other conditions instead of being divided by rounding noise;
* ``cost_consistency`` — :math:`|J(t) - \tfrac12\int|u|^2|/J`, closed form against the
  trajectory (``pmp_cost_consistency_rel``).

(:math:`p_{2,4}` are integrated from :math:`\dot p_2 = -p_1`, not read off ``u``.)  A
non-finite value fails as ``numerical_error``; any other failure as ``inaccurate``.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np
import numpy.typing as npt

from iamp.core.status import INACCURATE, NUMERICAL_ERROR
from iamp.core.tolerances import TOLERANCES

from .fixed import system_and_cost
from .scale import Scaled, scale_problem
from .solution import Evaluation, PMPSolution

FloatArray = npt.NDArray[np.float64]
Checks = dict[str, dict[str, float | bool]]
_INF = math.inf

#: The floor, in units of the Hamiltonian (:attr:`~iamp.planners.pmp.scale.Units.ham`), of the
#: size the Hamiltonian-jump residual is divided by: with jumps this small the check is
#: ``|r|/H_unit <= pmp_scaled_residual`` (the relative tolerance times this floor).
HJUMP_FLOOR = TOLERANCES["pmp_scaled_residual"] / TOLERANCES["pmp_hjump_rel"]

#: The entry of :data:`iamp.core.tolerances.TOLERANCES` each check is compared with.
TOLERANCE_OF = _TOLS = {
    "linear_system": "pmp_linear_system_rel",
    "boundary": "pmp_scaled_residual",
    "corner": "pmp_scaled_residual",
    "h_minimisation": "pmp_scaled_residual",
    "costate_jump": "pmp_scaled_residual",
    "hamiltonian_jump": "pmp_hjump_rel",
    "cost_consistency": "pmp_cost_consistency_rel",
}


def check_values(sol: PMPSolution, S: Scaled | None = None, stationary: bool = True,
                 ev: Evaluation | None = None) -> dict[str, float]:
    """The dimensionless value of every check (module docstring).  ``stationary=False``
    leaves out the Hamiltonian-jump condition (contact times given by the caller).

    The solution is read once, :meth:`~iamp.planners.pmp.solution.PMPSolution.evaluate` (or
    ``ev``, an evaluation the caller made): the corners and speeds at the contact times and the
    trajectory at ``0``, ``t_f``, the contact times and the sorted breakpoints; the fixed-time
    problem once, :func:`~iamp.planners.pmp.fixed.system_and_cost`."""
    prob = sol.problem
    S = S if S is not None else (sol.scaled if sol.scaled is not None else scale_problem(prob))
    u = S.units
    t = sol.contact_times
    m = t.shape[0]
    out: dict[str, float] = {}
    with np.errstate(all="ignore"):
        ev = sol.evaluate() if ev is None else ev
        corners, xdot, bp, at = ev.corners, ev.xdot, ev.breakpoints, ev.samples
        M, rhs, J_closed = system_and_cost(prob, S, t)
        if sol.z_scaled is not None:
            z = sol.z_scaled
        else:
            z = np.vstack([sol.a / u.acc, sol.b / u.jerk, sol.jumps / u.jerk])
        den = float(np.max(np.sum(np.abs(M), axis=1)) * np.max(np.abs(z)) + np.max(np.abs(rhs)))
        out["linear_system"] = float(np.max(np.abs(M @ z - rhs))) / max(den, 1e-300)
        vel_pos = np.array([u.L, u.vel, u.L, u.vel])
        ends = at.states[:2]
        out["boundary"] = float(max(np.max(np.abs(ends[0] - prob.ego.initial) / vel_pos),
                                    np.max(np.abs(ends[1] - prob.ego.final) / vel_pos)))
        X = at.states[2:2 + m]
        out["corner"] = float(np.max(np.abs(X[:, [0, 2]] - corners))) / u.L
        p = at.costates[:2 + m]  # at 0, t_f and the contact times (right limits)
        out["h_minimisation"] = float(np.max(np.abs(at.inputs[:2 + m] + p[:, [1, 3]]))) / u.acc
        pl, pr = at.costates_left, at.costates[2:2 + m]
        out["costate_jump"] = float(max(np.max(np.abs(pl[:, [0, 2]] - pr[:, [0, 2]] - sol.jumps)) / u.jerk,
                                        np.max(np.abs(pl[:, [1, 3]] - pr[:, [1, 3]])) / u.acc))
        if stationary:
            jumps = sol.jumps
            r = at.h_left - at.h_right - xdot * jumps[:, 0]
            size = np.abs(jumps[:, 0]) * (np.abs(X[:, 1]) + np.abs(xdot)) + np.abs(jumps[:, 1]) * np.abs(X[:, 3])
            out["hamiltonian_jump"] = float(np.max(np.abs(r) / np.maximum(size, HJUMP_FLOOR * u.ham)))
        U = at.inputs[2 + m:4 + 2 * m]
        h = np.diff(bp)[:, None]
        J_traj = float(0.5 * np.sum(h / 3 * (U[:-1] ** 2 + U[:-1] * U[1:] + U[1:] ** 2)))  # = sol.cost()
        out["cost_consistency"] = abs(J_closed - J_traj) / max(abs(J_traj), 1e-300 * u.cost)
    return out


def judge(values: dict[str, float]) -> tuple[Checks, str | None, str | None]:
    """``(checks, failed_check, status)``: the table of ``{value, tol, ok}``, the first
    failing check (or ``None``) and the failure status (``None`` if all pass)."""
    return judge_pairs(values.keys(), values.values())


def judge_pairs(names: Iterable[str], values: Iterable[float]) -> tuple[Checks, str | None, str | None]:
    """:func:`judge` of the checks ``names`` with the values ``values`` (in order), without
    building the ``{name: value}`` dictionary first (the one-vehicle fast path)."""
    checks: Checks = {}
    failed: str | None = None
    status: str | None = None
    for name, v in zip(names, values):
        limit = TOLERANCES[_TOLS[name]]  # = tol(...), without the call
        value = float(v)
        if -_INF < value <= limit:  # finite and inside (a NaN compares False)
            checks[name] = {"value": value, "tol": limit, "ok": True}
            continue
        finite = math.isfinite(value)
        checks[name] = {"value": value, "tol": limit, "ok": False}
        if failed is None:
            failed = name
            status = INACCURATE if finite else NUMERICAL_ERROR
        if not finite:
            status = NUMERICAL_ERROR
    return checks, failed, status


def verify(sol: PMPSolution, S: Scaled | None = None, stationary: bool = True,
           ev: Evaluation | None = None) -> tuple[Checks, str | None, str | None]:
    """:func:`judge` of :func:`check_values`."""
    return judge(check_values(sol, S, stationary, ev))
