r"""The paper's indirect planner: Pontryagin's minimum principle with interior-point
equality constraints at free contact times (SPEC §2).

Necessary conditions
--------------------
With :math:`H = \tfrac12(u_x^2+u_y^2) + p_1 v_x + p_2 u_x + p_3 v_y + p_4 u_y`,
the co-states obey :math:`\dot p_1 = 0,\ \dot p_2 = -p_1,\ \dot p_3 = 0,\ \dot p_4 = -p_3`
and :math:`\partial H/\partial u = 0` gives :math:`u_x = -p_2,\ u_y = -p_4`.  At each contact
time :math:`t_i` the co-states jump,

.. math::  p_{1,3}^-(t_i) = p_{1,3}^+(t_i) + \Phi_{i,x|y}, \qquad p_{2,4}\ \text{continuous},

so between contact times the input is linear and, per axis,

.. math::

    u(t) = a + b\,t - \sum_i \Phi_i (t-t_i)_+ ,\qquad
    s(t) = s_0 + v_0 t + \tfrac{a}{2}t^2 + \tfrac{b}{6}t^3 - \sum_i \tfrac{\Phi_i}{6}(t-t_i)_+^3 ,

with :math:`a = -p_2(0)` and :math:`b = p_1(0)`.  For fixed contact times the interior
constraints :math:`s(t_i) = \text{corner}_i(t_i)` and the final conditions
:math:`s(t_f), v(t_f)` are ``m + 2`` linear equations in ``(a, b, Φ_1..Φ_m)`` per axis; both
axes share the matrix (:func:`solve_fixed_times`).

Contact times
-------------
The free-time condition is the Hamiltonian jump :math:`H^-(t_i) = H^+(t_i) + \dot x_{s,i}(t_i)
\Phi_{i,x}`.  Its residual

.. math::  r_i = H^-(t_i) - H^+(t_i) - \dot x_{s,i}(t_i)\Phi_{i,x}
              = \Phi_{i,x}\,(v_x(t_i) - \dot x_{s,i}(t_i)) + \Phi_{i,y}\,v_y(t_i)

equals :math:`\partial J/\partial t_i` of the value function :math:`J(t)` of the fixed-time
problem.  That value function has a closed form: conditioning the unconstrained optimum
(the Hermite cubic :math:`\bar s`) on the interior points,

.. math::  J(t) = \bar J + \tfrac12 \sum_{\text{axis}} e^\top K(t)^{-1} e,\qquad
           e_i = \text{corner}_i(t_i) - \bar s(t_i),

with the integrated-Brownian-bridge kernel
:math:`K(s,t) = s^2 (t_f-t)^2 (3 t_f t - t_f s - 2 s t) / (6 t_f^3)` for :math:`s \le t`
(and :math:`\Phi = -K^{-1} e`).  For one vehicle :math:`K = t^3(t_f-t)^3/(3t_f^3)` and the
zeros of :math:`r` in :math:`(0, t_f)` are exactly the real roots of the polynomial
:math:`N'(t)\,t(t_f-t) - 3N(t)(t_f-2t)`, :math:`N = e_x^2 + e_y^2`: all stationary points
are found, and the global minimiser is picked among them (exact and global).  For two
vehicles, ``J`` is evaluated on a dense grid of ``(0,t_f)^2``, and every grid basin is
refined by Newton's method on ``r(t) = 0``; for more vehicles a quasi-random multistart
replaces the grid (global only with high probability — see :class:`PMPPlanner`).
"""

from __future__ import annotations

import time as _time
from dataclasses import dataclass

import numpy as np
from numpy.polynomial import polynomial as P

from iamp.core.errors import SolverError
from iamp.core.problem import Problem
from iamp.core.plan import STATUS_OPTIMAL, Plan

# --------------------------------------------------------------------------------------
# Closed-form pieces
# --------------------------------------------------------------------------------------


def hermite_cubic(s0: float, v0: float, sf: float, vf: float, tf: float) -> np.ndarray:
    """Ascending coefficients of the unconstrained minimum-energy path ``s̄(t)``."""
    e = sf - s0 - v0 * tf
    g = vf - v0
    return np.array([s0, v0, (3 * e - g * tf) / tf**2, (-2 * e + g * tf) / tf**3])


def transfer_cost(s0, v0, sf, vf, T):
    r"""Minimum of :math:`\tfrac12\int_0^T u^2` taking ``(s0, v0)`` to ``(sf, vf)`` in ``T``:
    :math:`6e^2/T^3 - 6eg/T^2 + 2g^2/T` with :math:`e = s_f - s_0 - v_0T`, :math:`g = v_f - v_0`."""
    e = sf - s0 - v0 * T
    g = vf - v0
    return 6 * e**2 / T**3 - 6 * e * g / T**2 + 2 * g**2 / T


def bridge_kernel(s, t, tf):
    """Covariance kernel ``K(s, t)`` of the interior positions given both end states."""
    s = np.asarray(s, dtype=float)
    t = np.asarray(t, dtype=float)
    lo = np.minimum(s, t)
    hi = np.maximum(s, t)
    return lo**2 * (tf - hi) ** 2 * (3 * tf * hi - tf * lo - 2 * lo * hi) / (6 * tf**3)


def bridge_kernel_ds(s, t, tf):
    """``∂K(s, t)/∂s`` for ``s ≠ t`` (first argument)."""
    s = np.asarray(s, dtype=float)
    t = np.asarray(t, dtype=float)
    below = (tf - t) ** 2 * s * (2 * tf * t - tf * s - 2 * s * t) / (2 * tf**3)
    above = t**2 * (tf - s) * (tf**2 - 3 * tf * s + 2 * t * s) / (2 * tf**3)
    return np.where(s <= t, below, above)


def bridge_variance_dt(t, tf):
    """``d K(t, t)/dt = t²(t_f − t)²(t_f − 2t)/t_f³``."""
    return t**2 * (tf - t) ** 2 * (tf - 2 * t) / tf**3


def _horner_rows(C: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Row ``i`` of ``C`` (ascending coefficients) evaluated at ``t[..., i]``."""
    y = np.broadcast_to(C[:, -1], t.shape).copy()
    for k in range(C.shape[1] - 2, -1, -1):
        y = y * t + C[:, k]
    return y


class ValueFunction:
    r"""The fixed-contact-time optimal cost :math:`J(t)` of a problem, in closed form.

    ``J(t) = J̄ + ½ Σ_axis eᵀ K(t)⁻¹ e`` (see the module docstring).  Vectorised over
    leading dimensions of ``t``; used to screen candidate contact times.
    """

    def __init__(self, problem: Problem):
        self.problem = problem
        ego = problem.ego
        self.tf = tf = ego.tf
        self.sx_bar = hermite_cubic(ego.x0, ego.vx0, ego.xf, ego.vxf, tf)
        self.sy_bar = hermite_cubic(ego.y0, ego.vy0, ego.yf, ego.vyf, tf)
        self.j_bar = float(transfer_cost(ego.x0, ego.vx0, ego.xf, ego.vxf, tf)
                           + transfer_cost(ego.y0, ego.vy0, ego.yf, ego.vyf, tf))
        # e_x,i(t) and e_y,i(t) as ascending polynomials
        self.ex = [P.polysub(np.r_[v.x_poly[0] + v.offset_x, v.x_poly[1:]], self.sx_bar) for v in problem.vehicles]
        self.ey = [P.polysub([v.corner_y], self.sy_bar) for v in problem.vehicles]
        # padded coefficient matrices (m, d) so all vehicles evaluate in one operation
        d = max(len(c) for c in self.ex + self.ey)
        pad = lambda cs: np.array([np.pad(c, (0, d - len(c))) for c in cs])  # noqa: E731
        self._EX, self._EY = pad(self.ex), pad(self.ey)
        k = np.arange(d)
        self._DEX = np.pad(self._EX[:, 1:] * k[1:], ((0, 0), (0, 1)))
        self._DEY = np.pad(self._EY[:, 1:] * k[1:], ((0, 0), (0, 1)))

    def errors(self, t):
        """``(e_x, e_y)`` with shape of ``t`` (``(..., m)``)."""
        t = np.asarray(t, dtype=float)
        return _horner_rows(self._EX, t), _horner_rows(self._EY, t)

    def __call__(self, t) -> np.ndarray:
        """``J(t)`` for ``t`` of shape ``(..., m)``; ``inf`` where the times are degenerate."""
        t = np.asarray(t, dtype=float)
        tf = self.tf
        ex, ey = self.errors(t)
        m = t.shape[-1]
        with np.errstate(divide="ignore", invalid="ignore"):
            if m == 1:
                k = bridge_kernel(t[..., 0], t[..., 0], tf)
                q = (ex[..., 0] ** 2 + ey[..., 0] ** 2) / k
            elif m == 2:
                k11 = bridge_kernel(t[..., 0], t[..., 0], tf)
                k22 = bridge_kernel(t[..., 1], t[..., 1], tf)
                k12 = bridge_kernel(t[..., 0], t[..., 1], tf)
                det = k11 * k22 - k12**2
                q = sum((k22 * e[..., 0] ** 2 - 2 * k12 * e[..., 0] * e[..., 1] + k11 * e[..., 1] ** 2)
                        for e in (ex, ey)) / det
            else:
                K = bridge_kernel(t[..., :, None], t[..., None, :], tf)
                E = np.stack([ex, ey], axis=-1)
                try:
                    sol = np.linalg.solve(K, E)
                    q = np.sum(E * sol, axis=(-1, -2))
                except np.linalg.LinAlgError:
                    q = np.full(t.shape[:-1], np.inf)
                    flat_K = K.reshape(-1, m, m)
                    flat_E = E.reshape(-1, m, 2)
                    qf = q.reshape(-1)
                    for n in range(flat_K.shape[0]):
                        try:
                            qf[n] = np.sum(flat_E[n] * np.linalg.solve(flat_K[n], flat_E[n]))
                        except np.linalg.LinAlgError:
                            qf[n] = np.inf
            J = self.j_bar + 0.5 * q
        return np.where(np.isfinite(J) & (J >= self.j_bar - 1e-9 * max(1.0, abs(self.j_bar))), J, np.inf)

    def gradient(self, t) -> np.ndarray:
        r"""``∇J(t)`` in closed form (= the Hamiltonian-jump residuals ``r``, identity 1):
        with ``μ = K⁻¹e`` per axis, ``∂J/∂t_i = Σ_axis μ_i ė_i − ½ μᵀ(∂K/∂t_i)μ``."""
        t = np.asarray(t, dtype=float)
        tf, m = self.tf, t.shape[-1]
        K = bridge_kernel(t[..., :, None], t[..., None, :], tf)
        dK = bridge_kernel_ds(t[..., :, None], t[..., None, :], tf)  # ∂K_ij/∂t_i (i ≠ j)
        diag = bridge_variance_dt(t, tf)
        ex, ey = _horner_rows(self._EX, t), _horner_rows(self._EY, t)
        dex, dey = _horner_rows(self._DEX, t), _horner_rows(self._DEY, t)
        g = np.zeros(t.shape)
        eye = np.eye(m, dtype=bool)
        for e, de in ((ex, dex), (ey, dey)):
            mu = np.linalg.solve(K, e[..., None])[..., 0]
            off = np.where(eye, 0.0, dK)
            g += mu * de - mu * np.einsum("...ij,...j->...i", off, mu) - 0.5 * mu**2 * diag
        return g

    def stationary_points_1d(self) -> np.ndarray:
        """All zeros of the Hamiltonian-jump residual in ``(0, t_f)`` for one vehicle.

        With ``t = t_f σ`` and ``N(σ) = e_x² + e_y²``, ``dJ/dt = 0`` ⇔
        ``N'(σ) σ(1-σ) − 3 N(σ)(1 − 2σ) = 0``: a polynomial whose real roots in ``(0, 1)``
        are all the stationary points.  Each root is polished by Newton's method.
        """
        return _stationary_times_one_vehicle(self.ex[0], self.ey[0], self.tf)


def _one_vehicle_root_polys(ex: np.ndarray, ey: np.ndarray, tf):
    """Coefficient rows (ascending, in ``σ = t/t_f``) of ``N`` and of the stationarity
    polynomial ``P = N'σ(1−σ) − 3N(1−2σ)`` for a batch: ``ex``, ``ey`` have shape
    ``(K, d+1)`` in powers of ``t``; ``tf`` is a scalar or one horizon per row."""
    d = max(ex.shape[1], ey.shape[1])
    scale = np.asarray(tf, dtype=float).reshape(-1, 1) ** np.arange(d)
    ex = np.pad(ex, ((0, 0), (0, d - ex.shape[1]))) * scale
    ey = np.pad(ey, ((0, 0), (0, d - ey.shape[1]))) * scale
    # N = ex² + ey² (row-wise convolution)
    N = np.zeros((ex.shape[0], 2 * d - 1))
    for i in range(d):
        N[:, i:i + d] += ex[:, i:i + 1] * ex + ey[:, i:i + 1] * ey
    k = np.arange(1, N.shape[1])
    dN = N[:, 1:] * k  # N' coefficients, degree 2d-3
    Pc = np.zeros((N.shape[0], N.shape[1] + 1))
    Pc[:, 1:dN.shape[1] + 1] += dN  # N'·σ
    Pc[:, 2:dN.shape[1] + 2] -= dN  # −N'·σ²
    Pc[:, :N.shape[1]] -= 3 * N  # −3N
    Pc[:, 1:N.shape[1] + 1] += 6 * N  # +6Nσ
    return N, Pc


def _real_roots_in_unit_interval(Pc: np.ndarray):
    """Real roots in (0, 1) of each row polynomial (batched companion eigenvalues), polished
    by two Newton steps.  Returns a ``(K, deg)`` array with NaN where there is no root."""
    Pc = Pc / np.max(np.abs(Pc), axis=1, keepdims=True)
    deg = Pc.shape[1] - 1
    lead = Pc[:, -1]
    # trailing zero leading coefficients (lower degree): perturb-free handling by row
    if np.any(np.abs(lead) < 1e-14):
        out = np.full((Pc.shape[0], deg), np.nan)
        for r in range(Pc.shape[0]):
            c = np.trim_zeros(Pc[r], "b")
            if len(c) > 1:
                rr = np.roots(c[::-1])
                out[r, : len(rr)] = np.where(np.abs(rr.imag) <= 1e-7 * np.maximum(1, np.abs(rr.real)), rr.real, np.nan)
        roots = out
    else:
        C = np.zeros((Pc.shape[0], deg, deg))
        C[:, 1:, :-1] = np.eye(deg - 1)
        C[:, :, -1] = -Pc[:, :-1] / lead[:, None]
        ev = np.linalg.eigvals(C)
        roots = np.where(np.abs(ev.imag) <= 1e-7 * np.maximum(1, np.abs(ev.real)), ev.real, np.nan)
    roots = np.where((roots > 0) & (roots < 1), roots, np.nan)
    dP = Pc[:, 1:] * np.arange(1, deg + 1)
    for _ in range(2):
        pv = np.zeros_like(roots)
        dv = np.zeros_like(roots)
        for j in range(deg, -1, -1):
            pv = pv * roots + Pc[:, j:j + 1]
        for j in range(deg - 1, -1, -1):
            dv = dv * roots + dP[:, j:j + 1]
        step = np.where(dv != 0, pv / np.where(dv != 0, dv, 1), 0.0)
        roots = np.clip(roots - step, 1e-15, 1 - 1e-15)
    return roots


def _stationary_times_one_vehicle(ex, ey, tf: float) -> np.ndarray:
    """All zeros of ``dJ/dt`` in ``(0, t_f)`` for one vehicle (see
    :meth:`ValueFunction.stationary_points_1d`); ``ex``, ``ey`` ascending in ``t``.

    Scalar code on purpose (a handful of coefficients): only the companion-matrix
    eigenvalues go through numpy.
    """
    d = max(len(ex), len(ey))
    ex = [float(c) * tf**k for k, c in enumerate(ex)] + [0.0] * (d - len(ex))
    ey = [float(c) * tf**k for k, c in enumerate(ey)] + [0.0] * (d - len(ey))
    N = [0.0] * (2 * d - 1)
    for i in range(d):
        for j in range(d):
            N[i + j] += ex[i] * ex[j] + ey[i] * ey[j]
    # P(σ) = N'(σ)·σ(1−σ) − 3N(σ)(1−2σ), ascending
    Pc = [0.0] * (len(N) + 1)
    for k in range(1, len(N)):
        dk = k * N[k]  # coefficient of σ^(k−1) in N'
        Pc[k] += dk
        Pc[k + 1] -= dk
    for k, n in enumerate(N):
        Pc[k] -= 3 * n
        Pc[k + 1] += 6 * n
    while len(Pc) > 1 and Pc[-1] == 0.0:
        Pc.pop()
    deg = len(Pc) - 1
    if deg < 1:
        return np.array([])
    lead = Pc[-1]
    if deg == 1:
        ev = np.array([-Pc[0] / lead])
    else:
        C = np.zeros((deg, deg))
        C[1:, :-1] = np.eye(deg - 1)
        C[:, -1] = [-c / lead for c in Pc[:-1]]
        ev = np.linalg.eigvals(C)
    out = []
    for r in ev.tolist() if ev.dtype.kind == "c" else ev.astype(complex).tolist():
        x = r.real
        if abs(r.imag) > 1e-7 * max(1.0, abs(x)) or not 0.0 < x < 1.0:
            continue
        for _ in range(2):  # Newton polish (the eigenvalues are already accurate to ~1e-12)
            p = dp = 0.0
            for c in reversed(Pc):
                dp = dp * x + p
                p = p * x + c
            if dp != 0.0:
                x = min(max(x - p / dp, 1e-15), 1 - 1e-15)
        out.append(x * tf)
    return np.sort(np.array(out))


def _horner(desc, x):
    """Polynomial (descending coefficients) at ``x``."""
    y = np.zeros_like(x)
    for c in desc:
        y = y * x + c
    return y


def one_vehicle_contact_time(problem: Problem) -> float:
    r"""The exact global contact time for one vehicle, in scalar code.

    Every stationary point of ``J`` (every zero of the Hamiltonian-jump residual) is a real
    root in ``(0, t_f)`` of ``N'(t) t(t_f−t) − 3N(t)(t_f−2t)`` with ``N = e_x² + e_y²``; the
    global minimiser is the root with the least ``J = J̄ + ½N/K``.
    """
    ego, T = problem.ego, problem.tf
    veh = problem.vehicles[0]
    hx = hermite_cubic(ego.x0, ego.vx0, ego.xf, ego.vxf, T)
    hy = hermite_cubic(ego.y0, ego.vy0, ego.yf, ego.vyf, T)
    xp = np.asarray(veh.x_poly, float)
    ex = np.zeros(max(4, len(xp)))
    ex[: len(xp)] = xp
    ex[0] += veh.offset_x
    ex[:4] -= hx
    ey = -hy
    ey[0] += veh.corner_y
    roots = _stationary_times_one_vehicle(ex, ey, T)
    if roots.size == 0:
        raise SolverError("J(t) has no stationary point in (0, tf): no interior contact time",
                          "no_interior_optimum")
    N = _horner(ex[::-1], roots) ** 2 + _horner(ey[::-1], roots) ** 2
    K = roots**3 * (T - roots) ** 3
    return float(roots[int(np.argmin(N / K))])


# --------------------------------------------------------------------------------------
# The fixed-time solution of the necessary and jump conditions
# --------------------------------------------------------------------------------------


@dataclass
class PMPSolution:
    """Solution of the necessary + co-state jump conditions for fixed contact times.

    Per axis (column 0 = x, 1 = y): ``u(t) = a + b t − Σ Φ_i (t − t_i)_+``;
    co-states ``p1 = b − Σ Φ_x,i H(t−t_i)``, ``p2 = −u_x``, ``p3``, ``p4`` likewise.
    """

    problem: Problem
    contact_times: np.ndarray  # (m,)
    a: np.ndarray  # (2,)  = (-p2(0), -p4(0))
    b: np.ndarray  # (2,)  = (p1(0), p3(0))
    jumps: np.ndarray  # (m, 2)  Φ_i = (Φ_i,x, Φ_i,y)

    # --- trajectory -------------------------------------------------------------------
    def _ramps(self, t, power, side="right"):
        t = np.atleast_1d(np.asarray(t, dtype=float))
        d = t[:, None] - self.contact_times[None, :]
        if power == 0:
            return (d > 0).astype(float) if side == "left" else (d >= 0).astype(float)
        return np.maximum(d, 0.0) ** power

    def inputs(self, t) -> np.ndarray:
        """``(u_x, u_y)`` at times ``t`` → shape ``(len(t), 2)``."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        return self.a[None, :] + self.b[None, :] * t[:, None] - self._ramps(t, 1) @ self.jumps

    def states(self, t) -> np.ndarray:
        """``(s_x, v_x, s_y, v_y)`` at times ``t`` → shape ``(len(t), 4)``."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        ego = self.problem.ego
        s0 = np.array([ego.x0, ego.y0])
        v0 = np.array([ego.vx0, ego.vy0])
        tt = t[:, None]
        v = v0 + self.a * tt + self.b * tt**2 / 2 - self._ramps(t, 2) @ self.jumps / 2
        s = s0 + v0 * tt + self.a * tt**2 / 2 + self.b * tt**3 / 6 - self._ramps(t, 3) @ self.jumps / 6
        return np.stack([s[:, 0], v[:, 0], s[:, 1], v[:, 1]], axis=1)

    def costates(self, t, side: str = "right") -> np.ndarray:
        """``(p1, p2, p3, p4)`` at ``t``; ``side`` picks the one-sided limit at a contact time."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        step = self._ramps(t, 0, side)
        p13 = self.b[None, :] - step @ self.jumps
        p24 = -self.inputs(t)
        return np.stack([p13[:, 0], p24[:, 0], p13[:, 1], p24[:, 1]], axis=1)

    def hamiltonian(self, t, side: str = "right") -> np.ndarray:
        """``H = ½|u|² + p1 v_x + p2 u_x + p3 v_y + p4 u_y`` (one-sided at contact times)."""
        X = self.states(t)
        U = self.inputs(t)
        p = self.costates(t, side)
        return (0.5 * np.sum(U**2, axis=1) + p[:, 0] * X[:, 1] + p[:, 1] * U[:, 0]
                + p[:, 2] * X[:, 3] + p[:, 3] * U[:, 1])

    # --- the conditions -----------------------------------------------------------------
    def system_residual(self) -> float:
        """max |M z − rhs| of the jump system (:func:`jump_system`) at this solution."""
        M, rhs = jump_system(self.problem, self.contact_times)
        z = np.vstack([self.a, self.b, self.jumps])
        return float(np.max(np.abs(M @ z - rhs)))

    def cost(self) -> float:
        """Exact ``J = ½∫|u|²``: ``u`` is linear between breakpoints, so each piece
        contributes ``h/3·(u_0² + u_0u_1 + u_1²)``."""
        bp = np.sort(np.r_[0.0, self.contact_times, self.problem.tf])
        U = self.inputs(bp)
        h = np.diff(bp)[:, None]
        return float(0.5 * np.sum(h / 3 * (U[:-1] ** 2 + U[:-1] * U[1:] + U[1:] ** 2)))

    def hamiltonian_jump_residual(self) -> np.ndarray:
        """``r_i = H⁻(t_i) − H⁺(t_i) − ẋ_s,i(t_i)·Φ_i,x`` (= ``∂J/∂t_i``)."""
        t = self.contact_times
        Hm = self.hamiltonian(t, "left")
        Hp = self.hamiltonian(t, "right")
        xdot = np.array([v.speed(ti) for v, ti in zip(self.problem.vehicles, t)])
        return Hm - Hp - xdot * self.jumps[:, 0]

    def residuals(self) -> dict:
        """Max-abs residual of every condition solved."""
        prob = self.problem
        t = self.contact_times
        ends = self.states(np.array([0.0, prob.tf]))
        boundary = max(np.max(np.abs(ends[0] - prob.ego.initial)), np.max(np.abs(ends[1] - prob.ego.final)))
        X = self.states(t)
        interior = np.max(np.abs(X[:, [0, 2]] - prob.corners(t)))
        ts = np.linspace(0.0, prob.tf, 201)
        U, p = self.inputs(ts), self.costates(ts)
        h_min = np.max(np.abs(U + p[:, [1, 3]]))  # ∂H/∂u = u + p2, u + p4
        pl, pr = self.costates(t, "left"), self.costates(t, "right")
        jump = max(np.max(np.abs(pl[:, [0, 2]] - pr[:, [0, 2]] - self.jumps)),
                   np.max(np.abs(pl[:, [1, 3]] - pr[:, [1, 3]])))
        return {
            "linear_system": self.system_residual(),
            "boundary": float(boundary),
            "interior_constraint": float(interior),
            "h_minimisation": float(h_min),
            "costate_jump": float(jump),
            "hamiltonian_jump": float(np.max(np.abs(self.hamiltonian_jump_residual()))),
        }


def jump_system(problem: Problem, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The linear system ``M z = rhs`` of the necessary and co-state jump conditions.

    Unknowns per axis (columns of ``z``): ``(a, b, Φ_1..Φ_m)``; rows: the ``m``
    interior-point constraints ``s(t_j) = corner_j``, then the final position and speed.
    Both axes share ``M`` (``(m+2)×(m+2)``); ``rhs`` has one column per axis.
    """
    m, ego, T = problem.m, problem.ego, problem.tf
    M = np.empty((m + 2, m + 2))
    M[:m, 0] = t**2 / 2
    M[:m, 1] = t**3 / 6
    M[:m, 2:] = -np.maximum(t[:, None] - t[None, :], 0.0) ** 3 / 6
    M[m] = np.r_[T**2 / 2, T**3 / 6, -((T - t) ** 3) / 6]
    M[m + 1] = np.r_[T, T**2 / 2, -((T - t) ** 2) / 2]
    C = problem.corners(t)
    rhs = np.empty((m + 2, 2))
    rhs[:m, 0] = C[:, 0] - ego.x0 - ego.vx0 * t
    rhs[:m, 1] = C[:, 1] - ego.y0 - ego.vy0 * t
    rhs[m] = [ego.xf - ego.x0 - ego.vx0 * T, ego.yf - ego.y0 - ego.vy0 * T]
    rhs[m + 1] = [ego.vxf - ego.vx0, ego.vyf - ego.vy0]
    return M, rhs


def _check_times(problem: Problem, contact_times) -> np.ndarray:
    t = np.asarray(contact_times, dtype=float).reshape(-1)
    if t.shape != (problem.m,):
        raise ValueError(f"need {problem.m} contact times, got {t.shape[0]}")
    if np.any(t <= 0) or np.any(t >= problem.tf):
        raise ValueError(f"contact times must lie in (0, {problem.tf}); got {t}")
    return t


def solve_fixed_times(problem: Problem, contact_times) -> PMPSolution:
    """Solve the necessary and co-state jump conditions (:func:`jump_system`) for given
    contact times.  Raises :class:`SolverError` if the system is singular (two contact
    times coincide)."""
    t = _check_times(problem, contact_times)
    M, rhs = jump_system(problem, t)
    try:
        z = np.linalg.solve(M, rhs)
    except np.linalg.LinAlgError:
        raise SolverError(f"contact times {t} make the jump conditions singular", "singular") from None
    res = float(np.max(np.abs(M @ z - rhs)))
    scale = max(1.0, float(np.max(np.abs(rhs))), float(np.max(np.abs(M) @ np.abs(z))))
    if not np.all(np.isfinite(z)) or res > 1e-8 * scale:
        raise SolverError(f"contact times {t} make the jump conditions singular", "singular")
    return PMPSolution(problem, t, z[0], z[1], z[2:])


def solve_one_vehicle(problem: Problem, contact_time: float) -> PMPSolution:
    r""":func:`solve_fixed_times` for one vehicle, by eliminating ``Φ`` first (scalar code).

    Per axis, ``Φ = −e/K`` with ``e = corner − s̄(t_1)`` and ``K = t_1^3 (t_f−t_1)^3/(3t_f^3)``
    (the Schur complement of the jump system), then ``(a, b)`` from the two final
    conditions.  Same solution as the dense solve (the residuals report checks
    ``M z = rhs``); about three times faster, for the contact-time search and the batch.
    """
    t1 = float(_check_times(problem, [contact_time])[0])
    ego, T = problem.ego, problem.tf
    veh = problem.vehicles[0]
    K = t1**3 * (T - t1) ** 3 / (3 * T**3)
    a, b, phi = [0.0, 0.0], [0.0, 0.0], [0.0, 0.0]
    axes = ((ego.x0, ego.vx0, ego.xf, ego.vxf, float(veh.corner_x(t1))),
            (ego.y0, ego.vy0, ego.yf, ego.vyf, veh.corner_y))
    for k, (s0, v0, sf, vf, c) in enumerate(axes):
        es = sf - s0 - v0 * T
        g = vf - v0
        c2 = (3 * es - g * T) / T**2
        c3 = (-2 * es + g * T) / T**3
        e = c - (s0 + v0 * t1 + c2 * t1**2 + c3 * t1**3)
        phi[k] = -e / K
        # a T²/2 + b T³/6 = es + Φ (T−t1)³/6 ;  a T + b T²/2 = g + Φ (T−t1)²/2
        r1 = es + phi[k] * (T - t1) ** 3 / 6
        r2 = g + phi[k] * (T - t1) ** 2 / 2
        b[k] = (12 * r1 - 6 * r2 * T) / -T**3
        a[k] = (r2 - b[k] * T**2 / 2) / T
    return PMPSolution(problem, np.array([t1]), np.array(a), np.array(b), np.array([phi]))


def hamiltonian_jump_residuals(problem: Problem, contact_times) -> np.ndarray:
    """``r(t)`` — the Hamiltonian-jump residual of the fixed-time solution (= ``∇J(t)``)."""
    return solve_fixed_times(problem, contact_times).hamiltonian_jump_residual()


# --------------------------------------------------------------------------------------
# The global contact-time search
# --------------------------------------------------------------------------------------


def _newton_on_jump_conditions(problem, J, t0, tol=1e-11, max_iter=50):
    """Solve ``r(t) = 0`` from ``t0`` by damped Newton, with backtracking on ``J`` so that it
    converges to a minimum inside ``(0, t_f)``.  ``r`` is the closed-form gradient (identity
    1: it equals the Hamiltonian-jump residual of the fixed-time solution, which the caller
    re-checks at the answer); its Jacobian comes from central differences, in one batch."""
    tf = problem.tf
    lo, hi = 1e-9 * tf, tf * (1 - 1e-9)
    t = np.array(t0, dtype=float)
    Jt = float(J(t[None, :])[0])
    m = t.size
    eps = 1e-6 * tf
    stencil = np.concatenate([np.eye(m), -np.eye(m)]) * eps
    for _ in range(max_iter):
        pts = np.clip(np.vstack([t[None, :], t[None, :] + stencil]), lo, hi)
        with np.errstate(all="ignore"):
            G = J.gradient(pts)
        r = G[0]
        if not np.all(np.isfinite(r)) or np.max(np.abs(r)) <= tol * max(1.0, Jt):
            break
        Hs = ((G[1:m + 1] - G[m + 1:]) / (2 * eps)).T
        Hs = 0.5 * (Hs + Hs.T)
        step = None
        if np.all(np.isfinite(Hs)):
            w = np.linalg.eigvalsh(Hs)
            if w[0] > 0:
                step = -np.linalg.solve(Hs, r)
        if step is None:  # not convex here: gradient step scaled to the horizon
            step = -r / max(np.max(np.abs(r)), 1e-300) * 0.05 * tf
        alpha = 1.0
        while alpha > 1e-8:
            tn = np.clip(t + alpha * step, lo, hi)
            Jn = float(J(tn[None, :])[0])
            if Jn <= Jt + 1e-14 * max(1.0, abs(Jt)):
                break
            alpha *= 0.5
        else:
            break
        if np.max(np.abs(tn - t)) < 1e-15 * tf:
            t, Jt = tn, Jn
            break
        t, Jt = tn, Jn
    return t, Jt


def _grid_local_minima(Z):
    """Indices of grid points not larger than any of their (up to 3^m − 1) neighbours."""
    m = Z.ndim
    pad = np.pad(Z, 1, constant_values=np.inf)
    is_min = np.isfinite(Z)
    core = tuple(slice(1, -1) for _ in range(m))
    for offset in np.ndindex(*([3] * m)):
        if all(o == 1 for o in offset):
            continue
        sl = tuple(slice(o, o + Z.shape[k]) for k, o in enumerate(offset))
        is_min &= Z <= pad[sl]
    del core
    return np.argwhere(is_min)


@dataclass
class PMPPlanner:
    """The PMP planner with a global contact-time search.

    Parameters
    ----------
    grid_2d : int
        Grid points per axis of the ``(0, t_f)^2`` screen for two vehicles.
    max_basins : int
        How many grid basins (best first) are refined by Newton.
    multistart : int
        Starts per vehicle for ``m ≥ 3``.
    seed : int
        Seed of the quasi-random starts for ``m ≥ 3``.

    Notes
    -----
    ``m = 1``: exact — every root of the Hamiltonian-jump condition is found as a polynomial
    root.  ``m = 2``: the global basin is found on a ``grid_2d²`` grid and refined to
    ``|r| ≲ 1e-11``; a basin narrower than the grid spacing could be missed in principle.
    ``m ≥ 3``: multistart Newton; global with high probability, not guaranteed.
    """

    grid_2d: int = 48
    max_basins: int = 4
    multistart: int = 24
    seed: int = 0

    def contact_times(self, problem: Problem) -> np.ndarray:
        """The global minimiser ``t*`` of ``J`` over ``(0, t_f)^m``."""
        if problem.m == 1:
            return np.array([one_vehicle_contact_time(problem)])
        J = ValueFunction(problem)
        tf, m = problem.tf, problem.m
        if m == 2:
            g = tf * (np.arange(self.grid_2d) + 0.5) / self.grid_2d
            T1, T2 = np.meshgrid(g, g, indexing="ij")
            Z = J(np.stack([T1, T2], axis=-1))
            idx = _grid_local_minima(Z)
            order = np.argsort(Z[tuple(idx.T)])[: self.max_basins]
            starts = [np.array([g[i], g[j]]) for i, j in idx[order]]
        else:
            rng = np.random.default_rng(self.seed)
            starts = list(np.sort(rng.uniform(0.02, 0.98, size=(self.multistart * m, m)), axis=1) * tf)
            # vehicles may be met in any order: shuffle coordinates of half the starts
            for k in range(0, len(starts), 2):
                starts[k] = rng.permutation(starts[k])
            vals = J(np.array(starts))
            starts = [starts[k] for k in np.argsort(vals)[: max(self.max_basins, 2 * m)]]
        best_t, best_J = None, np.inf
        for s in starts:
            try:
                t, Jt = _newton_on_jump_conditions(problem, J, s)
            except SolverError:
                continue
            if Jt < best_J:
                best_t, best_J = t, Jt
        if best_t is None:
            raise SolverError("no contact-time candidate could be solved", "no_interior_optimum")
        return best_t

    def solve(self, problem: Problem, contact_times=None) -> PMPSolution:
        """Fixed-time solution at ``contact_times`` (default: the global ``t*``)."""
        t = self.contact_times(problem) if contact_times is None else contact_times
        if problem.m == 1:
            return solve_one_vehicle(problem, np.asarray(t, dtype=float).reshape(-1)[0])
        return solve_fixed_times(problem, t)

    def plan(self, problem: Problem, contact_times=None, diagnostics: bool = True) -> Plan:
        """Plan; returns a :class:`Plan` whose ``trajectory`` is the exact
        :class:`PMPSolution` (evaluable at any time, with co-states and jumps).

        ``solve_time_s`` covers the contact-time search, the jump-condition solve and the
        cost; ``diagnostics=False`` skips the residual report (computed after the clock
        stops either way).
        """
        start = _time.perf_counter()
        sol = self.solve(problem, contact_times)
        cost = sol.cost()
        elapsed = _time.perf_counter() - start
        res = Plan(problem=problem, planner="pmp", status=STATUS_OPTIMAL, cost=cost,
                         contact_times=sol.contact_times.copy(), jumps=sol.jumps.copy(), trajectory=sol,
                         solve_time_s=elapsed)
        if diagnostics:
            res.residuals = sol.residuals()
            res.info["hamiltonian_jump_residuals"] = sol.hamiltonian_jump_residual()
        return res


@dataclass
class BatchPlan:
    """Result of :func:`plan_batch`: arrays over ``K`` one-vehicle problems."""

    contact_time: np.ndarray  # (K,)
    cost: np.ndarray  # (K,)
    jumps: np.ndarray  # (K, 2)
    status: np.ndarray  # (K,) of str


def plan_batch(problems) -> BatchPlan:
    r"""Plan many one-vehicle problems at once (vectorised over problems).

    Same mathematics as :class:`PMPPlanner` for ``m = 1``: all stationary points from the
    batched roots of ``N'σ(1−σ) − 3N(1−2σ)``, the global one by the closed-form
    ``J = J̄ + ½ |e|²/K``, and ``Φ = −e/K`` with ``K = t³(t_f−t)³/(3t_f³)``.  Problems may
    differ in every parameter; vehicle polynomials are padded to a common degree.
    """
    problems = list(problems)
    if any(p.m != 1 for p in problems):
        raise ValueError("plan_batch plans one-vehicle problems; use PMPPlanner for more")
    K = len(problems)
    ego = np.array([[p.ego.tf, p.ego.x0, p.ego.vx0, p.ego.xf, p.ego.vxf, p.ego.y0, p.ego.vy0, p.ego.yf, p.ego.vyf]
                    for p in problems])
    tf, x0, vx0, xf, vxf, y0, vy0, yf, vyf = ego.T
    d = max(4, max(len(p.vehicles[0].x_poly) for p in problems))
    xs = np.zeros((K, d))
    for k, p in enumerate(problems):
        c = p.vehicles[0].x_poly
        xs[k, : len(c)] = c
    off_x = np.array([p.vehicles[0].offset_x for p in problems])
    cy = np.array([p.vehicles[0].corner_y for p in problems])

    def hermite(s0, v0, sf, vf):
        e = sf - s0 - v0 * tf
        g = vf - v0
        return np.stack([s0, v0, (3 * e - g * tf) / tf**2, (-2 * e + g * tf) / tf**3], axis=1)

    hx, hy = hermite(x0, vx0, xf, vxf), hermite(y0, vy0, yf, vyf)
    ex = xs.copy()
    ex[:, 0] += off_x
    ex[:, :4] -= hx
    ey = -hy
    ey[:, 0] += cy
    jbar = transfer_cost(x0, vx0, xf, vxf, tf) + transfer_cost(y0, vy0, yf, vyf, tf)
    _, Pc = _one_vehicle_root_polys(ex, ey, tf)
    roots = _real_roots_in_unit_interval(Pc) * tf[:, None]
    powers = roots[..., None] ** np.arange(d)
    exv = np.einsum("kd,krd->kr", ex, powers)
    eyv = np.einsum("kd,krd->kr", np.pad(ey, ((0, 0), (0, d - 4))), powers)
    kern = roots**3 * (tf[:, None] - roots) ** 3 / (3 * tf[:, None] ** 3)
    J = jbar[:, None] + 0.5 * (exv**2 + eyv**2) / kern
    J = np.where(np.isfinite(J), J, np.inf)
    best = np.argmin(J, axis=1)
    rows = np.arange(K)
    ok = np.isfinite(J[rows, best])
    t = roots[rows, best]
    phi = -np.stack([exv[rows, best], eyv[rows, best]], axis=1) / kern[rows, best][:, None]
    status = np.where(ok, STATUS_OPTIMAL, "no_interior_optimum")
    return BatchPlan(contact_time=np.where(ok, t, np.nan), cost=np.where(ok, J[rows, best], np.nan),
                     jumps=np.where(ok[:, None], phi, np.nan), status=status)
