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
* ``hamiltonian_jump`` — :math:`|H^- - H^+ - \dot x_s\Phi_x|` over the size of its terms
  (``pmp_hjump_rel``; free contact times only);
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

from .fixed import ValueFunction, jump_system_sigma, system_and_quad
from .scale import Scaled, scale_problem
from .solution import PMPSolution

FloatArray = npt.NDArray[np.float64]
Checks = dict[str, dict[str, float | bool]]
_INF = math.inf

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


def check_values(sol: PMPSolution, S: Scaled | None = None, stationary: bool = True) -> dict[str, float]:
    """The dimensionless value of every check (module docstring).  ``stationary=False``
    leaves out the Hamiltonian-jump condition (contact times given by the caller)."""
    prob = sol.problem
    S = S if S is not None else (sol.scaled if sol.scaled is not None else scale_problem(prob))
    u = S.units
    t = sol.contact_times
    sig = t / u.T
    out: dict[str, float] = {}
    with np.errstate(all="ignore"):
        M, rhs = jump_system_sigma(S, sig)
        if sol.z_scaled is not None:
            z = sol.z_scaled
        else:
            z = np.vstack([sol.a / u.acc, sol.b / u.jerk, sol.jumps / u.jerk])
        den = float(np.max(np.sum(np.abs(M), axis=1)) * np.max(np.abs(z)) + np.max(np.abs(rhs)))
        out["linear_system"] = float(np.max(np.abs(M @ z - rhs))) / max(den, 1e-300)
        vel_pos = np.array([u.L, u.vel, u.L, u.vel])
        ends = sol.states(np.array([0.0, u.T]))
        out["boundary"] = float(max(np.max(np.abs(ends[0] - prob.ego.initial) / vel_pos),
                                    np.max(np.abs(ends[1] - prob.ego.final) / vel_pos)))
        X = sol.states(t)
        out["corner"] = float(np.max(np.abs(X[:, [0, 2]] - prob.corners(t)))) / u.L
        bp = np.r_[0.0, t, u.T]
        p = sol.costates(bp)
        out["h_minimisation"] = float(np.max(np.abs(sol.inputs(bp) + p[:, [1, 3]]))) / u.acc
        pl, pr = sol.costates(t, "left"), sol.costates(t, "right")
        out["costate_jump"] = float(max(np.max(np.abs(pl[:, [0, 2]] - pr[:, [0, 2]] - sol.jumps)) / u.jerk,
                                        np.max(np.abs(pl[:, [1, 3]] - pr[:, [1, 3]])) / u.acc))
        if stationary:
            r, size = sol.hamiltonian_jump_terms()
            out["hamiltonian_jump"] = float(np.max(np.abs(r) / np.maximum(size, 1e-300 * u.ham)))
        J_closed = float(ValueFunction(prob, S)(t[None, :])[0])
        J_traj = sol.cost()
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
           lean: bool = False) -> tuple[Checks, str | None, str | None]:
    """:func:`judge` of :func:`check_values` (``lean``: of :func:`check_values_lean`, for a
    solution solved in the scaled units ``S``)."""
    if lean and S is not None and sol.z_scaled is not None:
        return judge(check_values_lean(sol, S, stationary))
    return judge(check_values(sol, S, stationary))


# --- the lean path: the same checks in scalar code ---------------------------------------------


def _amax(xs: Iterable[float]) -> float:
    """``np.max`` of a few floats (NaN if any is NaN, as numpy)."""
    best = -_INF
    for x in xs:
        if x > best:
            best = x
        elif x != x:
            return math.nan
    return best


def _sum(a: list[float]) -> float:
    """``np.sum`` of a short contiguous float64 vector, in numpy's order (pairwise
    summation: a plain loop below 8 terms, eight accumulators up to 128)."""
    n = len(a)
    if n < 8:
        res = -0.0
        for x in a:
            res += x
        return res
    if n > 128:
        return float(np.sum(np.array(a)))
    r = a[:8]
    i = 8
    while i < n - n % 8:
        for j in range(8):
            r[j] += a[i + j]
        i += 8
    res = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]))
    while i < n:
        res += a[i]
        i += 1
    return res


def _cubes(xs: list[float]) -> list[float]:
    """``x**3`` as numpy computes it on arrays (``np.power``; as :func:`.fixed.cubes`)."""
    out: list[float] = np.power(np.array(xs, dtype=float), 3).tolist()
    return out


def check_values_lean(sol: PMPSolution, S: Scaled, stationary: bool = True) -> dict[str, float]:
    """:func:`check_values` in scalar code for a solution solved in scaled units
    (``sol.z_scaled`` set): the same quantities with the same floating operations, evaluated
    only where the conditions live (``0``, the contact times, ``t_f``), no trajectory arrays.

    The matrix products stay numpy's (``M @ z``; every ``ramps @ jumps`` row in one
    product, whose rows do not depend on how many there are), cubes go through numpy's
    power and squares are products, as numpy computes them.  Any float exception
    (``OverflowError``, ``ZeroDivisionError``) falls back to :func:`check_values`.
    """
    return lean_checks_and_cost(sol, S, stationary)[0]


def lean_checks_and_cost(sol: PMPSolution, S: Scaled, stationary: bool = True) -> tuple[dict[str, float], float]:
    """:func:`check_values_lean` and the trajectory's cost ``½∫|u|²`` it computed on the way
    (the numbers of ``sol.cost()``, which the plan reports)."""
    try:
        return _lean(sol, S, stationary)
    except (OverflowError, ZeroDivisionError, ValueError):
        return check_values(sol, S, stationary), sol.cost()


def _lean(sol: PMPSolution, S: Scaled, stationary: bool) -> tuple[dict[str, float], float]:
    prob = sol.problem
    ego = prob.ego
    u = S.units
    T, L = u.T, u.L
    vel, acc, jerk = L / T, L / T**2, L / T**3
    t = sol.contact_times.tolist()
    m = len(t)
    ax, ay = sol.a.tolist()
    bx, by = sol.b.tolist()
    jumps = sol.jumps.tolist()
    z = sol.z_scaled
    assert z is not None
    out: dict[str, float] = {}
    sig = [ti / T for ti in t]

    # linear_system: the scaled jump system rebuilt from (S, σ), numpy's product; with it the
    # closed-form q(σ) of the cost check (one read of the fixed-time system)
    M, rhs, q_sig = system_and_quad(S, sig)
    Ma = np.array(M)
    ra = np.array(rhs)
    den = _amax(_sum([abs(x) for x in row]) for row in M) * float(np.max(np.abs(z))) + _amax(
        abs(x) for row in rhs for x in row)
    out["linear_system"] = float(np.max(np.abs(Ma @ z - ra))) / max(den, 1e-300)

    x0, vx0, y0, vy0 = float(ego.x0), float(ego.vx0), float(ego.y0), float(ego.vy0)

    # every ramp/step sum the checks need, ``W @ jumps`` in one product (numpy's, so the
    # numbers are the generic path's): rows (kind, point) for the points 0, t_f, t_1..t_m,
    # kinds (t−t_i)_+, (t−t_i)_+², (t−t_i)_+³, H(t−t_i) left and right limits
    pts = [0.0, T, *t]
    n_pts = len(pts)
    dpos = [[max(p - ti, 0.0) for ti in t] for p in pts]
    cub = _cubes([*pts, *[w for row in dpos for w in row]])
    W = [*dpos, *[[w * w for w in row] for row in dpos],
         *[cub[n_pts + n * m: n_pts + (n + 1) * m] for n in range(n_pts)],
         *[[1.0 if p - ti > 0 else 0.0 for ti in t] for p in pts],
         *[[1.0 if p - ti >= 0 else 0.0 for ti in t] for p in pts]]
    R = (np.array(W) @ sol.jumps).tolist()

    def state(n: int) -> tuple[float, float, float, float]:
        tt = pts[n]
        r2x, r2y = R[n_pts + n]
        r3x, r3y = R[2 * n_pts + n]
        t2, t3 = tt * tt, cub[n]
        return (x0 + vx0 * tt + ax * t2 / 2 + bx * t3 / 6 - r3x / 6, vx0 + ax * tt + bx * t2 / 2 - r2x / 2,
                y0 + vy0 * tt + ay * t2 / 2 + by * t3 / 6 - r3y / 6, vy0 + ay * tt + by * t2 / 2 - r2y / 2)

    def inputs(n: int) -> tuple[float, float]:
        tt = pts[n]
        r1x, r1y = R[n]
        return ax + bx * tt - r1x, ay + by * tt - r1y

    def costate(n: int, left: bool) -> tuple[float, float, float, float]:
        tt = pts[n]
        r0x, r0y = R[(3 if left else 4) * n_pts + n]
        r1x, r1y = R[n]
        return bx - r0x, -ax - bx * tt + r1x, by - r0y, -ay - by * tt + r1y

    # boundary
    vp = (L, vel, L, vel)
    e0 = state(0)
    e1 = state(1)
    ini = (x0, vx0, y0, vy0)
    fin = (float(ego.xf), float(ego.vxf), float(ego.yf), float(ego.vyf))
    out["boundary"] = max(_amax(abs(e0[k] - ini[k]) / vp[k] for k in range(4)),
                          _amax(abs(e1[k] - fin[k]) / vp[k] for k in range(4)))

    # corner (the vehicles' own polynomials, numpy's polyval order)
    X = [state(2 + i) for i in range(m)]
    dev: list[float] = []
    xdot: list[float] = []
    for v, ti, Xi in zip(prob.vehicles, t, X):
        c = [float(ck) for ck in v.x_poly]
        pos = c[-1] + ti * 0
        for k in range(2, len(c) + 1):
            pos = c[-k] + pos * ti
        dev.append(abs(Xi[0] - (pos + v.offset_x)))
        dev.append(abs(Xi[2] - v.corner_y))
        if len(c) > 1:
            dc = [j * c[j] for j in range(1, len(c))]
            sp = dc[-1] + ti * 0
            for k in range(2, len(dc) + 1):
                sp = dc[-k] + sp * ti
        else:
            sp = 0.0
        xdot.append(sp)
    out["corner"] = _amax(dev) / L

    # h_minimisation at 0, t_i, t_f
    hm: list[float] = []
    for n in [0, *range(2, n_pts), 1]:
        ux, uy = inputs(n)
        p = costate(n, False)
        hm.append(abs(ux + p[1]))
        hm.append(abs(uy + p[3]))
    out["h_minimisation"] = _amax(hm) / acc

    # costate_jump
    pl = [costate(2 + i, True) for i in range(m)]
    pr = [costate(2 + i, False) for i in range(m)]
    j13 = _amax(abs(a[k] - b[k] - jj[n]) for a, b, jj in zip(pl, pr, jumps) for n, k in ((0, 0), (1, 2)))
    j24 = _amax(abs(a[k] - b[k]) for a, b in zip(pl, pr) for k in (1, 3))
    out["costate_jump"] = max(j13 / jerk, j24 / acc)

    if stationary:
        ham = u.ham
        vals: list[float] = []
        for i, (Xi, (jx, jy), sp, plm, prp) in enumerate(zip(X, jumps, xdot, pl, pr)):
            ux, uy = inputs(2 + i)
            half = 0.5 * (ux * ux + uy * uy)
            Hm = half + plm[0] * Xi[1] + plm[1] * ux + plm[2] * Xi[3] + plm[3] * uy
            Hp = half + prp[0] * Xi[1] + prp[1] * ux + prp[2] * Xi[3] + prp[3] * uy
            size = abs(jx) * (abs(Xi[1]) + abs(sp)) + abs(jy) * abs(Xi[3])
            r = Hm - Hp - sp * jx
            vals.append(abs(r) / max(size, 1e-300 * ham))
        out["hamiltonian_jump"] = _amax(vals)

    # cost_consistency: closed form J(t) against ½∫|u|² of the trajectory
    J_closed = (S.jbar + 0.5 * q_sig) * (L**2 / T**3)
    order = sorted(range(n_pts), key=pts.__getitem__)  # = np.sort(np.r_[0, t, t_f])
    bp = [pts[n] for n in order]
    U = [inputs(n) for n in order]
    terms: list[float] = []
    for n in range(len(bp) - 1):
        h3 = (bp[n + 1] - bp[n]) / 3
        for k in (0, 1):
            u0, u1 = U[n][k], U[n + 1][k]
            terms.append(h3 * (u0 * u0 + u0 * u1 + u1 * u1))
    J_traj = 0.5 * _sum(terms)
    out["cost_consistency"] = abs(J_closed - J_traj) / max(abs(J_traj), 1e-300 * (L**2 / T**3))
    return out, J_traj
