r"""Many one-vehicle problems at once (vectorised over problems).

Same mathematics and the same scaled units as :class:`~iamp.planners.pmp.planner.PMPPlanner` for
``m = 1``: all stationary points as the roots in ``(0, 1)`` of
:math:`P = N'\sigma(1-\sigma) - 3N(1-2\sigma)` (batched Bernstein isolation + Newton,
:func:`~iamp.planners.pmp.roots.batch_unit_roots`), the global one by
:math:`\tilde J = \tilde J_0 + \tfrac12 N/\tilde K`, :math:`\tilde\Phi = -\tilde e/\tilde K`
with :math:`\tilde K = \sigma^3(1-\sigma)^3/3`, then ``(ã, b̃)`` from the final conditions.

Each plan is verified like a single plan (:mod:`iamp.planners.pmp.verify`), in vectorised
form: the scaled backward error of the jump system, the corner and final-state residuals,
the Hamiltonian-jump residual relative to its terms and the closed-form cost against the
integral of :math:`|u|^2`; a failing row gets ``inaccurate`` (or ``numerical_error``) and NaN.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from itertools import chain
from operator import attrgetter

import numpy as np
import numpy.typing as npt

from iamp.core.free import min_energy_cubic
from iamp.core.problem import Problem
from iamp.core.status import INACCURATE, INFEASIBLE, NUMERICAL_ERROR, OPTIMAL
from iamp.core.tolerances import TOLERANCES

from .roots import batch_unit_roots

FloatArray = npt.NDArray[np.float64]


@dataclass
class BatchPlan:
    """Result of :func:`plan_batch`: arrays over ``K`` one-vehicle problems (physical units)."""

    contact_time: FloatArray  # (K,)
    cost: FloatArray  # (K,)
    jumps: FloatArray  # (K, 2)
    status: npt.NDArray[np.str_]  # (K,)


def _hermite(s0: FloatArray, v0: FloatArray, sf: FloatArray, vf: FloatArray) -> FloatArray:
    """Rows of :func:`iamp.core.free.min_energy_cubic` in scaled time (``t_f = 1``)."""
    return np.stack(min_energy_cubic(s0, v0, sf, vf), axis=1)


def _horner(C: FloatArray, x: FloatArray) -> FloatArray:
    """Row polynomials ``C`` (``(K, d)``) at ``x`` (``(K,)`` or ``(K, R)``)."""
    xx = x if x.ndim == 2 else x[:, None]
    y = np.broadcast_to(C[:, -1:], xx.shape).copy()
    for k in range(C.shape[1] - 2, -1, -1):
        y = y * xx + C[:, k:k + 1]
    return y if x.ndim == 2 else y[:, 0]


_EGO_FIELDS = attrgetter("tf", "x0", "vx0", "xf", "vxf", "y0", "vy0", "yf", "vyf")
_VEHICLE_FIELDS = attrgetter("length", "safety_x", "y", "width", "safety_y")


def batch_data(problems: list[Problem]) -> tuple[FloatArray, ...]:
    """Scaled data ``(units (K,2) = (T, L), ego (K,8), EX, EY, CX, CY)`` as in
    :func:`iamp.planners.pmp.scale.scale_problem`, vectorised.

    The fields are read with :func:`operator.attrgetter` (one C call per object); the corner
    offset and lateral coordinate are :attr:`SurroundingVehicle.offset_x` and ``corner_y``
    with the same operations, ``sign_x·(length/2 + safety_x)`` and ``y + sign_y·(width/2 +
    safety_y)``, the signs read once per corner name from the vehicles themselves."""
    K = len(problems)
    vehicles = [p.vehicles[0] for p in problems]
    raw = np.fromiter(chain.from_iterable(map(_EGO_FIELDS, [p.ego for p in problems])), dtype=np.float64,
                      count=9 * K).reshape(K, 9)
    geo = np.fromiter(chain.from_iterable(map(_VEHICLE_FIELDS, vehicles)), dtype=np.float64,
                      count=5 * K).reshape(K, 5)
    signs: dict[str, tuple[float, float]] = {}
    for v in vehicles:
        if v.corner not in signs:
            signs[v.corner] = (v.sign_x, v.sign_y)
    sxy = np.array([signs[v.corner] for v in vehicles])
    off = sxy[:, 0] * (geo[:, 0] / 2 + geo[:, 1])
    cyr = geo[:, 2] + sxy[:, 1] * (geo[:, 3] / 2 + geo[:, 4])
    T = raw[:, 0]
    polys = [v.x_poly for v in vehicles]
    d = max(4, max(len(c) for c in polys))
    if all(len(c) == d for c in polys):
        C = np.array(polys)
    else:
        C = np.array([c + (0.0,) * (d - len(c)) for c in polys])
    with np.errstate(over="ignore"):
        Cs = C * np.cumprod(np.column_stack([np.ones(K)] + [T] * (d - 1)), axis=1)
    size = np.abs(Cs)
    big = np.max(size, axis=1, keepdims=True)
    negl = size <= TOLERANCES["pmp_poly_negligible_rel"] * big
    trailing = np.flip(np.cumprod(np.flip(negl, axis=1), axis=1), axis=1).astype(bool)
    trailing[:, 0] = False
    Cs = np.where(trailing, 0.0, Cs)
    pos = np.abs(raw[:, [1, 3, 5, 7]])
    spd = np.abs(raw[:, [2, 4, 6, 8]]) * T[:, None]
    L = np.max(np.column_stack([pos, spd, np.sum(np.abs(Cs), axis=1) + np.abs(off), np.abs(cyr)]), axis=1)
    L = np.where((L > 0) & np.isfinite(L), L, 1.0)
    ego = np.column_stack([raw[:, 1] / L, raw[:, 2] * T / L, raw[:, 3] / L, raw[:, 4] * T / L,
                           raw[:, 5] / L, raw[:, 6] * T / L, raw[:, 7] / L, raw[:, 8] * T / L])
    CX = Cs / L[:, None]
    CX[:, 0] += off / L
    EX = CX.copy()
    EX[:, :4] -= _hermite(*ego[:, :4].T)
    EY = -_hermite(*ego[:, 4:].T)
    CY = cyr / L
    EY[:, 0] += CY
    return np.column_stack([T, L]), ego, EX, EY, CX, CY


def _stationarity_rows(EX: FloatArray, EY: FloatArray) -> FloatArray:
    """Rows of ``P = N'σ(1−σ) − 3N(1−2σ)`` (same arithmetic order as the scalar code)."""
    d = max(EX.shape[1], EY.shape[1])
    ex = np.pad(EX, ((0, 0), (0, d - EX.shape[1])))
    ey = np.pad(EY, ((0, 0), (0, d - EY.shape[1])))
    N = np.zeros((ex.shape[0], 2 * d - 1))
    for i in range(d):
        for j in range(d):
            N[:, i + j] += ex[:, i] * ex[:, j] + ey[:, i] * ey[:, j]
    Pc = np.zeros((N.shape[0], N.shape[1] + 1))
    for k in range(1, N.shape[1]):
        dk = k * N[:, k]
        Pc[:, k] += dk
        Pc[:, k + 1] -= dk
    for k in range(N.shape[1]):
        Pc[:, k] -= 3 * N[:, k]
        Pc[:, k + 1] += 6 * N[:, k]
    return Pc


def plan_batch(problems: Iterable[Problem]) -> BatchPlan:
    """Plan many one-vehicle problems at once (module docstring); problems may differ in
    every parameter (polynomials are padded to a common degree)."""
    problems = list(problems)
    if any(len(p.vehicles) != 1 for p in problems):
        raise ValueError("plan_batch plans one-vehicle problems; use PMPPlanner for more")
    K = len(problems)
    if K == 0:
        e = np.zeros(0)
        return BatchPlan(e, e, np.zeros((0, 2)), np.array([], dtype=str))
    units, ego, EX, EY, CX, CY = batch_data(problems)
    T, L = units[:, 0], units[:, 1]
    with np.errstate(all="ignore"):
        roots = batch_unit_roots(_stationarity_rows(EX, EY))
        ex = _horner(EX, roots)
        ey = _horner(EY, roots)
        wr = 1.0 - roots
        q = (ex * ex + ey * ey) * 3.0 / (roots * roots * roots * wr * wr * wr)
        q = np.where(np.isfinite(q), q, np.inf)
        best = np.argmin(q, axis=1)
        rows = np.arange(K)
        found = np.isfinite(q[rows, best])
        s = roots[rows, best]
        qs = q[rows, best]
        w1 = 1.0 - s
        Kt = s * s * s * w1 * w1 * w1 / 3.0
        phi = -np.stack([ex[rows, best], ey[rows, best]], axis=1) / Kt[:, None]
        x0, vx0, xf, vxf, y0, vy0, yf, vyf = ego.T
        E = np.stack([xf - x0 - vx0, yf - y0 - vy0], axis=1)
        G = np.stack([vxf - vx0, vyf - vy0], axis=1)
        w = (1 - s)[:, None]
        r1 = E + phi * w * w * w / 6.0
        r2 = G + phi * w * w / 2.0
        b = 6 * r2 - 12 * r1
        a = r2 - b / 2
        jbar = 6 * E * E - 6 * E * G + 2 * G * G
        J_closed = np.sum(jbar, axis=1) + 0.5 * qs
        status, J_traj = _batch_checks(ego, CX, CY, EX, EY, s, a, b, phi, J_closed)
    status = np.where(found, status, INFEASIBLE)
    ok = status == OPTIMAL
    jerk = L / (T * T * T)
    return BatchPlan(contact_time=np.where(ok, s * T, np.nan), cost=np.where(ok, J_traj * L * L / (T * T * T), np.nan),
                     jumps=np.where(ok[:, None], phi * jerk[:, None], np.nan), status=status)


def _batch_checks(ego: FloatArray, CX: FloatArray, CY: FloatArray, EX: FloatArray, EY: FloatArray, s: FloatArray,
                  a: FloatArray, b: FloatArray, phi: FloatArray,
                  J_closed: FloatArray) -> tuple[npt.NDArray[np.str_], FloatArray]:
    """Vectorised :mod:`iamp.planners.pmp.verify` checks for one vehicle → ``(status, J_traj)``."""
    s0 = ego[:, [0, 4]]
    v0 = ego[:, [1, 5]]
    sf = ego[:, [2, 6]]
    vf = ego[:, [3, 7]]
    ss = s[:, None]
    w = 1 - ss
    pos_c = s0 + v0 * ss + a * ss**2 / 2 + b * ss**3 / 6
    vel_c = v0 + a * ss + b * ss**2 / 2
    corner = np.stack([_horner(CX, s), CY], axis=1)
    sF = s0 + v0 + a / 2 + b / 6 - phi * w**3 / 6
    vF = v0 + a + b / 2 - phi * w**2 / 2
    # backward error of the 3x3 system per axis (rows: corner, final position, final speed)
    res = np.stack([pos_c - s0 - v0 * ss - (corner - s0 - v0 * ss),
                    sF - sf, vF - vf], axis=1)
    Mrow = np.stack([ss**2 / 2 + ss**3 / 6, 0.5 + 1 / 6 + w**3 / 6, 1.5 + w**2 / 2], axis=1)[..., 0]
    zmax = np.max(np.abs(np.stack([a, b, phi], axis=1)), axis=(1, 2))
    rmax = np.max(np.abs(np.stack([corner - s0 - v0 * ss, sf - s0 - v0, vf - v0], axis=1)), axis=(1, 2))
    lin = np.max(np.abs(res), axis=(1, 2)) / np.maximum(np.max(Mrow, axis=1) * zmax + rmax, 1e-300)
    pos_err = np.max(np.abs(pos_c - corner), axis=1)
    end_err = np.maximum(np.max(np.abs(sF - sf), axis=1), np.max(np.abs(vF - vf), axis=1))
    xdot = _horner(np.pad(CX[:, 1:] * np.arange(1, CX.shape[1]), ((0, 0), (0, 1))), s)
    r = phi[:, 0] * (vel_c[:, 0] - xdot) + phi[:, 1] * vel_c[:, 1]
    size = np.abs(phi[:, 0]) * (np.abs(vel_c[:, 0]) + np.abs(xdot)) + np.abs(phi[:, 1]) * np.abs(vel_c[:, 1])
    hj = np.abs(r) / np.maximum(size, 1e-300)
    u0 = a
    u1 = a + b * ss
    u2 = a + b - phi * w
    J_traj = 0.5 * np.sum(ss / 3.0 * (u0 * u0 + u0 * u1 + u1 * u1) + w / 3.0 * (u1 * u1 + u1 * u2 + u2 * u2), axis=1)
    cons = np.abs(J_closed - J_traj) / np.maximum(np.abs(J_traj), 1e-300)
    vals = np.stack([lin, pos_err, end_err, hj, cons], axis=1)
    t = TOLERANCES
    lim = np.array([t["pmp_linear_system_rel"], t["pmp_scaled_residual"], t["pmp_scaled_residual"],
                    t["pmp_hjump_rel"], t["pmp_cost_consistency_rel"]])
    finite = np.all(np.isfinite(vals), axis=1)
    good = finite & np.all(vals <= lim, axis=1)
    status = np.where(good, OPTIMAL, np.where(finite, INACCURATE, NUMERICAL_ERROR))
    return status, J_traj
