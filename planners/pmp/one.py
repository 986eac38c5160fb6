r"""One vehicle, start to verified finish, in scalar code (the planner's fast path).

The same mathematics as the general path, specialised to ``m = 1`` in scaled units
(:mod:`iamp.planners.pmp.scale`): the global contact time is the root of
:math:`P = N'\sigma(1-\sigma) - 3N(1-2\sigma)` with the least :math:`N/\tilde K`
(:func:`iamp.planners.pmp.search.one_vehicle_sigma`), :math:`\tilde\Phi = -\tilde e/\tilde K`,
``(ã, b̃)`` from the two final conditions, and the checks of :mod:`iamp.planners.pmp.verify`
written out for the three-piece solution:

* ``linear_system`` — backward error of the 3×3 system per axis (rows: corner, final
  position, final speed);
* ``corner`` and ``boundary`` — the corner and the final state reached by the solution;
* ``hamiltonian_jump`` — :math:`r = \tilde\Phi_x(\tilde v_x - \dot{\tilde x}_s) + \tilde\Phi_y\tilde v_y`
  over :math:`|\tilde\Phi_x|(|\tilde v_x|+|\dot{\tilde x}_s|) + |\tilde\Phi_y||\tilde v_y|`, floored at
  :data:`~iamp.planners.pmp.verify.HJUMP_FLOOR` (the corner on the unconstrained path: jumps of
  rounding size);
* ``cost_consistency`` — :math:`\tilde J_0 + N/(2\tilde K)` against
  :math:`\tfrac12\int|\tilde u|^2` of the piecewise-linear input.

(``h_minimisation`` and ``costate_jump`` hold by construction of the scalar formulas and are
checked by the general path, :func:`iamp.planners.pmp.verify.check_values`, in the tests.)
The kernel takes and returns plain floats and lists, so numba compiles it unchanged
(:mod:`iamp.planners.pmp.jit`, :func:`iamp.planners.pmp.compiled.compiled_kernel`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from operator import attrgetter

from iamp.core.problem import Problem
from iamp.core.tolerances import TOLERANCES

from .jit import compilable
from .search import one_vehicle_sigma
from .verify import HJUMP_FLOOR, TOLERANCE_OF, Checks, judge_pairs

_EGO_FIELDS = attrgetter("tf", "x0", "vx0", "xf", "vxf", "y0", "vy0", "yf", "vyf")
_INF = math.inf

#: Names of the values returned by :func:`one_vehicle_kernel` after ``(σ, ã_x, ã_y, b̃_x,
#: b̃_y, Φ̃_x, Φ̃_y, J̃)``, in order.
CHECK_NAMES = ("linear_system", "corner", "boundary", "hamiltonian_jump", "cost_consistency")


@compilable
def one_vehicle_kernel(ego: Sequence[float], ex: Sequence[float], ey: Sequence[float],
                       cx: Sequence[float], cy: float) -> list[float]:
    r"""The one-vehicle PMP plan in scaled units: the global contact time, the solution and its checks.

    Time is scaled by :math:`t_f` (:math:`\sigma = t/t_f`) and lengths by the problem's size
    :math:`L` (:func:`one_vehicle_data` makes the arguments).  The contact time is the root of
    the stationarity polynomial with the least cost (:func:`~iamp.planners.pmp.search.one_vehicle_sigma`);
    then, per axis, the co-state jump :math:`\tilde\Phi = -\tilde e(\sigma)/\tilde K(\sigma)`,
    :math:`\tilde K = \sigma^3 (1-\sigma)^3 / 3`, the input :math:`\tilde u = \tilde a + \tilde b\tau`
    before the contact and :math:`\tilde u - \tilde\Phi(\tau - \sigma)` after it, and the five
    checks of :data:`CHECK_NAMES`.

    (The maxima are written as comparisons, ``if x > m: m = x``: the same values as
    ``max(m, x)``, NaN included, without a call.)

    Parameters
    ----------
    ego : sequence of float
        The scaled boundary states ``(x0, vx0, xf, vxf, y0, vy0, yf, vyf)``.
    ex, ey : sequence of float
        Ascending coefficients in :math:`\sigma` of :math:`\tilde e_x`, :math:`\tilde e_y`: the
        corner minus the unconstrained (Hermite) path, per axis.
    cx : sequence of float
        Ascending coefficients in :math:`\sigma` of the corner's scaled :math:`x`,
        :math:`(x_s(\sigma t_f) \pm (L_v/2 + S_x))/L`.
    cy : float
        The corner's scaled :math:`y`.

    Returns
    -------
    list of float
        13 values: ``[σ, ã_x, ã_y, b̃_x, b̃_y, Φ̃_x, Φ̃_y, J̃]`` and the five checks of
        :data:`CHECK_NAMES`; ``σ`` is NaN (and the rest 0) if :math:`J` has no interior
        stationary point.
    """
    s, q = one_vehicle_sigma(ex, ey)
    out = [s, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
    if not s == s:  # NaN: no stationary point
        return out
    w = 1.0 - s
    Kt = s * s * s * w * w * w / 3.0
    # e at σ and the corner x and its speed (Horner)
    exv = 0.0
    for c in ex[::-1]:
        exv = exv * s + c
    eyv = 0.0
    for c in ey[::-1]:
        eyv = eyv * s + c
    cxv = 0.0
    cxd = 0.0
    for c in cx[::-1]:
        cxd = cxd * s + cxv
        cxv = cxv * s + c
    # the largest row sum of the 3x3 matrix (rows: corner, final position, final speed)
    mrow = max(s * s / 2.0 + s * s * s / 6.0, 2.0 / 3.0 + w * w * w / 6.0, 1.5 + w * w / 2.0)
    lin = 0.0
    den = 0.0
    corner = 0.0
    bound = 0.0
    rj = 0.0
    size = 0.0
    jbar = 0.0
    uint = 0.0
    for axis in range(2):
        i = 4 * axis
        s0 = ego[i]
        v0 = ego[i + 1]
        sf = ego[i + 2]
        vf = ego[i + 3]
        if axis == 0:
            e = exv
            c = cxv
            xdot = cxd
        else:
            e = eyv
            c = cy
            xdot = 0.0
        E = sf - s0 - v0
        G = vf - v0
        phi = -e / Kt
        r1 = E + phi * w * w * w / 6.0
        r2 = G + phi * w * w / 2.0
        b = 6.0 * r2 - 12.0 * r1
        a = r2 - b / 2.0
        out[1 + axis] = a
        out[3 + axis] = b
        out[5 + axis] = phi
        jbar += 6.0 * E * E - 6.0 * E * G + 2.0 * G * G
        # the three rows of M z − rhs (corner, final position, final speed)
        pos = s0 + v0 * s + a * s * s / 2.0 + b * s * s * s / 6.0
        vel = v0 + a * s + b * s * s / 2.0
        d_pos = abs(pos - c)
        d_sf = abs(s0 + v0 + a / 2.0 + b / 6.0 - phi * w * w * w / 6.0 - sf)
        d_vf = abs(v0 + a + b / 2.0 - phi * w * w / 2.0 - vf)
        if d_pos > lin:
            lin = d_pos
        if d_sf > lin:
            lin = d_sf
        if d_vf > lin:
            lin = d_vf
        zmax = abs(a)
        if abs(b) > zmax:
            zmax = abs(b)
        if abs(phi) > zmax:
            zmax = abs(phi)
        rmax = abs(c - s0 - v0 * s)
        if abs(E) > rmax:
            rmax = abs(E)
        if abs(G) > rmax:
            rmax = abs(G)
        d_row = mrow * zmax + rmax
        if d_row > den:
            den = d_row
        if d_pos > corner:
            corner = d_pos
        if d_sf > bound:
            bound = d_sf
        if d_vf > bound:
            bound = d_vf
        rj += phi * (vel - xdot)
        size += abs(phi) * (abs(vel) + abs(xdot))
        u1 = a + b * s
        u2 = a + b - phi * w
        uint += s / 3.0 * (a * a + a * u1 + u1 * u1) + w / 3.0 * (u1 * u1 + u1 * u2 + u2 * u2)
    J_closed = jbar + 0.5 * q
    J_traj = 0.5 * uint
    out[7] = J_traj
    out[8] = lin / max(den, 1e-300)
    out[9] = corner
    out[10] = bound
    out[11] = abs(rj) / max(size, HJUMP_FLOOR)
    out[12] = abs(J_closed - J_traj) / max(abs(J_traj), 1e-300)
    return out


def one_vehicle_data(problem: Problem) -> tuple[float, float, list[float], list[float], list[float], list[float],
                                                float]:
    """``(T, L, ego, ex, ey, cx, cy)``: :func:`iamp.planners.pmp.scale.scale_problem` for one
    vehicle in plain floats (same operations, same numbers; the maxima and sums written as
    loops with the same order of operations)."""
    v = problem.vehicles[0]
    T, ex0, evx0, exf, evxf, ey0, evy0, eyf, evyf = _EGO_FIELDS(problem.ego)
    xp = v.x_poly
    r = xp[0] * 1.0
    raw = [r]
    big = abs(r)
    tk = 1.0
    for k in range(1, len(xp)):
        tk = tk * T
        r = xp[k] * tk
        raw.append(r)
        if abs(r) > big:
            big = abs(r)
    eps = TOLERANCES["pmp_poly_negligible_rel"]
    keep = len(raw)
    while keep > 1 and abs(raw[keep - 1]) <= eps * big:
        keep -= 1
    if keep < len(raw):
        del raw[keep:]
    off = v.offset_x
    cyr = v.corner_y
    size = 0.0
    for c in raw:
        size += abs(c)
    L = max(abs(ex0), abs(exf), abs(ey0), abs(eyf), abs(evx0) * T, abs(evxf) * T, abs(evy0) * T,
            abs(evyf) * T, size + abs(off), abs(cyr))
    if not (L > 0 and math.isfinite(L)):
        L = 1.0
    x0, vx0, xf, vxf = ex0 / L, evx0 * T / L, exf / L, evxf * T / L
    y0, vy0, yf, vyf = ey0 / L, evy0 * T / L, eyf / L, evyf * T / L
    ego = [x0, vx0, xf, vxf, y0, vy0, yf, vyf]
    cx = [c / L for c in raw]
    while len(cx) < 4:
        cx.append(0.0)
    cx[0] += off / L
    # e = corner − the unconstrained (Hermite) path, coefficients (s0, v0, 3E − G, −2E + G)
    E = xf - x0 - vx0
    G = vxf - vx0
    ex = list(cx)
    ex[0] -= x0
    ex[1] -= vx0
    ex[2] -= 3 * E - G
    ex[3] -= -2 * E + G
    E = yf - y0 - vy0
    G = vyf - vy0
    cy = cyr / L
    ey = [0.0 - y0 + cy, 0.0 - vy0, 0.0 - (3 * E - G), 0.0 - (-2 * E + G)]
    return T, L, ego, ex, ey, cx, cy


def solve_one(problem: Problem, kernel: Callable[..., list[float]]
              ) -> tuple[float, float, list[float], tuple[Checks, str | None, str | None] | None]:
    """``(T, L, k, judged)``: the problem's data (:func:`one_vehicle_data`), the ``kernel``'s
    output ``k`` (:func:`one_vehicle_kernel` or its compiled twin) and, when the kernel found a
    contact time, its five checks judged (:func:`judge_kernel`; ``None`` if ``σ`` is NaN).
    Raises what the arithmetic raises (``OverflowError``, ``ZeroDivisionError``, ``ValueError``)."""
    T, L, ego, ex, ey, cx, cy = one_vehicle_data(problem)
    k = kernel(ego, ex, ey, cx, cy)
    if not k[0] == k[0]:
        return T, L, k, None
    return T, L, k, judge_kernel(k)


def judge_kernel(k: Sequence[float]) -> tuple[Checks, str | None, str | None]:
    """:func:`iamp.planners.pmp.verify.judge_pairs` of the kernel's checks ``k[8:13]``
    (:data:`CHECK_NAMES`), the usual case — every check finite and inside its tolerance —
    built as one literal: the same table, the same verdict."""
    v0, v1, v2, v3, v4 = k[8:13]
    t = TOLERANCES
    l0 = t[TOLERANCE_OF["linear_system"]]
    l1 = t[TOLERANCE_OF["corner"]]
    l2 = t[TOLERANCE_OF["boundary"]]
    l3 = t[TOLERANCE_OF["hamiltonian_jump"]]
    l4 = t[TOLERANCE_OF["cost_consistency"]]
    if -_INF < v0 <= l0 and -_INF < v1 <= l1 and -_INF < v2 <= l2 and -_INF < v3 <= l3 and -_INF < v4 <= l4:
        return ({"linear_system": {"value": float(v0), "tol": l0, "ok": True},
                 "corner": {"value": float(v1), "tol": l1, "ok": True},
                 "boundary": {"value": float(v2), "tol": l2, "ok": True},
                 "hamiltonian_jump": {"value": float(v3), "tol": l3, "ok": True},
                 "cost_consistency": {"value": float(v4), "tol": l4, "ok": True}}, None, None)
    return judge_pairs(CHECK_NAMES, k[8:13])
