r"""The fixed-contact-time problem: its linear jump system, its solution and its closed-form
value function :math:`J(t)` (SPEC §2).

With :math:`H = \tfrac12(u_x^2+u_y^2) + p_1 v_x + p_2 u_x + p_3 v_y + p_4 u_y` the co-states
obey :math:`\dot p_1 = 0,\ \dot p_2 = -p_1` (and likewise ``p3``, ``p4``),
:math:`\partial H/\partial u = 0` gives :math:`u_x = -p_2,\ u_y = -p_4`, and at each contact
time :math:`p_{1,3}^-(t_i) = p_{1,3}^+(t_i) + \Phi_{i,x|y}` with :math:`p_{2,4}` continuous.
Per axis, therefore,

.. math::  u(t) = a + b\,t - \sum_i \Phi_i (t-t_i)_+ ,\qquad
           s(t) = s_0 + v_0 t + \tfrac{a}{2}t^2 + \tfrac{b}{6}t^3 - \sum_i \tfrac{\Phi_i}{6}(t-t_i)_+^3 ,

and the corner conditions :math:`s(t_i) = \text{corner}_i(t_i)` with the final position and
speed are ``m + 2`` linear equations in ``(a, b, Φ_1..Φ_m)`` (:func:`jump_system`), solved in
the scaled units of :mod:`iamp.planners.pmp.scale`.  Conditioning the unconstrained optimum
(the Hermite cubic :math:`\bar s`) on the interior points gives the value function

.. math::  J(t) = \bar J + \tfrac12 \sum_{\text{axis}} e^\top K(t)^{-1} e,\quad
           e_i = \text{corner}_i(t_i) - \bar s(t_i),\quad \Phi = -K^{-1}e,

with :math:`K(s,t) = s^2 (t_f-t)^2 (3 t_f t - t_f s - 2 s t) / (6 t_f^3)` for :math:`s\le t`.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from iamp.core.errors import SolverError
from iamp.core.free import min_energy_cubic
from iamp.core.problem import Problem

from . import search_kernels as sk
from .jumps import jump_system as jump_system
from .scale import Scaled, scale_problem
from .solution import PMPSolution
from .stationary import stationary_sigmas

FloatArray = npt.NDArray[np.float64]
ArrayLike = Any


def hermite_cubic(s0: float, v0: float, sf: float, vf: float, tf: float) -> FloatArray:
    """Ascending coefficients of the unconstrained minimum-energy path ``s̄(t)``
    (:func:`iamp.core.free.min_energy_cubic`)."""
    return np.array(min_energy_cubic(s0, v0, sf, vf, tf))


def bridge_kernel(s: ArrayLike, t: ArrayLike, tf: float) -> FloatArray:
    """Covariance kernel ``K(s, t)`` of the interior positions given both end states."""
    s = np.asarray(s, dtype=float)
    t = np.asarray(t, dtype=float)
    lo = np.minimum(s, t)
    hi = np.maximum(s, t)
    out: FloatArray = lo**2 * (tf - hi) ** 2 * (3 * tf * hi - tf * lo - 2 * lo * hi) / (6 * tf**3)
    return out


def bridge_kernel_ds(s: ArrayLike, t: ArrayLike, tf: float) -> FloatArray:
    """``∂K(s, t)/∂s`` for ``s ≠ t`` (first argument)."""
    s = np.asarray(s, dtype=float)
    t = np.asarray(t, dtype=float)
    below = (tf - t) ** 2 * s * (2 * tf * t - tf * s - 2 * s * t) / (2 * tf**3)
    above = t**2 * (tf - s) * (tf**2 - 3 * tf * s + 2 * t * s) / (2 * tf**3)
    out: FloatArray = np.where(s <= t, below, above)
    return out


def bridge_variance_dt(t: ArrayLike, tf: float) -> FloatArray:
    """``d K(t, t)/dt = t²(t_f − t)²(t_f − 2t)/t_f³``."""
    t = np.asarray(t, dtype=float)
    out: FloatArray = t**2 * (tf - t) ** 2 * (tf - 2 * t) / tf**3
    return out


def horner_rows(C: FloatArray, t: FloatArray) -> FloatArray:
    """Row ``i`` of ``C`` (ascending coefficients) evaluated at ``t[..., i]``."""
    y = np.broadcast_to(C[:, -1], t.shape).copy()
    for k in range(C.shape[1] - 2, -1, -1):
        y = y * t + C[:, k]
    return y


def _deriv_rows(C: FloatArray) -> FloatArray:
    """Ascending coefficients of each row's derivative, padded to the same width."""
    out = np.zeros(C.shape)
    out[:, :-1] = C[:, 1:] * np.arange(1, C.shape[1])
    return out


class ValueFunction:
    r"""The fixed-contact-time optimal cost :math:`J(t)` of a problem, in closed form.

    ``J(t) = J̄ + ½ Σ_axis eᵀ K(t)⁻¹ e`` (module docstring), evaluated in scaled units
    (``σ = t/t_f``, lengths over ``L``) and returned in physical units.  Vectorised over the
    leading dimensions of ``t`` (shape ``(..., m)``).
    """

    def __init__(self, problem: Problem, scaled: Scaled | None = None):
        self.problem = problem
        self.scaled = S = scale_problem(problem) if scaled is None else scaled
        self.tf = float(problem.tf)
        self.units = S.units
        self.j_bar = S.jbar * S.units.cost
        d = max(S.EX.shape[1], S.EY.shape[1])
        m = S.EX.shape[0]
        self._EX = np.zeros((m, d))
        self._EX[:, :S.EX.shape[1]] = S.EX
        self._EY = np.zeros((m, d))
        self._EY[:, :S.EY.shape[1]] = S.EY
        self._DEX = _deriv_rows(self._EX)
        self._DEY = _deriv_rows(self._EY)

    # --- scaled core ----------------------------------------------------------------------
    def errors_sigma(self, sig: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Scaled ``(ẽ_x, ẽ_y)`` at ``σ`` (shape ``(..., m)``)."""
        return horner_rows(self._EX, sig), horner_rows(self._EY, sig)

    def quad_sigma(self, sig: FloatArray) -> FloatArray:
        """``q(σ) = Σ_axis ẽᵀ K̃⁻¹ ẽ`` with the unit-horizon kernel; ``inf`` if degenerate
        (:func:`iamp.planners.pmp.search_kernels.quad`)."""
        sig = np.asarray(sig, dtype=float)
        m = sig.shape[-1]
        flat = np.ascontiguousarray(sig.reshape(-1, m))
        with np.errstate(all="ignore"):
            q: FloatArray = sk.kernel("quad")(self._EX, self._EY, flat)
        return q.reshape(sig.shape[:-1])

    def gradient_sigma(self, sig: FloatArray) -> FloatArray:
        r"""Scaled :math:`\nabla_\sigma \tilde J`: with ``μ = K̃⁻¹ẽ`` per axis,
        ``∂J̃/∂σ_i = Σ_axis μ_i ẽ_i' − μ_i Σ_{j≠i} ∂₁K̃(σ_i,σ_j) μ_j − ½ μ_i² dK̃_ii/dσ``
        (:func:`iamp.planners.pmp.search_kernels.gradient`; NaN where ``K̃`` is singular)."""
        sig = np.asarray(sig, dtype=float)
        m = sig.shape[-1]
        flat = np.ascontiguousarray(sig.reshape(-1, m))
        with np.errstate(all="ignore"):
            g: FloatArray = sk.kernel("gradient")(self._EX, self._EY, self._DEX, self._DEY, flat)
        return g.reshape(sig.shape)

    # --- physical interface ------------------------------------------------------------------
    def errors(self, t: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """``(e_x, e_y)`` in metres with the shape of ``t`` (``(..., m)``)."""
        ex, ey = self.errors_sigma(np.asarray(t, dtype=float) / self.tf)
        return ex * self.units.L, ey * self.units.L

    def __call__(self, t: ArrayLike) -> FloatArray:
        """``J(t)`` for ``t`` of shape ``(..., m)``; ``inf`` where the times are degenerate."""
        q = self.quad_sigma(np.asarray(t, dtype=float) / self.tf)
        out: FloatArray = (self.scaled.jbar + 0.5 * q) * self.units.cost
        return out

    def gradient(self, t: ArrayLike) -> FloatArray:
        """``∇J(t)`` (= the Hamiltonian-jump residuals ``r``, SPEC §2 identity 1)."""
        g = self.gradient_sigma(np.asarray(t, dtype=float) / self.tf)
        out: FloatArray = g * (self.units.cost / self.tf)
        return out

    def stationary_points_1d(self) -> FloatArray:
        """All zeros of the Hamiltonian-jump residual in ``(0, t_f)`` for one vehicle."""
        return np.array(stationary_sigmas(self._EX[0], self._EY[0])) * self.tf


def _horner(c: list[float], s: float) -> float:
    """Ascending coefficients ``c`` at ``s`` (the order of :func:`horner_rows`)."""
    y = c[-1]
    for k in range(len(c) - 2, -1, -1):
        y = y * s + c[k]
    return y


def cubes(xs: list[float]) -> list[float]:
    """``x**3`` for every ``x`` as numpy computes it on arrays (``np.power``; squares are
    ``x*x`` both in numpy and here)."""
    out: list[float] = np.power(np.array(xs, dtype=float), 3).tolist()
    return out


def jump_rows(S: Scaled, sig: list[float]) -> tuple[list[list[float]], list[list[float]]]:
    """:func:`jump_system_sigma` as nested lists (scalar code, the same numbers)."""
    m = len(sig)
    x0, vx0, xf, vxf, y0, vy0, yf, vyf = S.ego.tolist()
    # cubes through numpy's power (its results differ from libm's pow in the last bit)
    cub = cubes([*sig, *[max(s - r, 0.0) for s in sig for r in sig], *[1.0 - s for s in sig]])
    M = [[s * s / 2, cub[i] / 6, *[-cub[m + m * i + j] / 6 for j in range(m)]] for i, s in enumerate(sig)]
    M.append([0.5, 1.0 / 6.0, *[-cub[m + m * m + i] / 6 for i in range(m)]])
    M.append([1.0, 0.5, *[-((1.0 - s) * (1.0 - s)) / 2 for s in sig]])
    CY = S.CY.tolist()
    rhs = [[_horner(c, s) - x0 - vx0 * s, CY[i] - y0 - vy0 * s] for i, (c, s) in enumerate(zip(S.CX.tolist(), sig))]
    rhs.append([xf - x0 - vx0, yf - y0 - vy0])
    rhs.append([vxf - vx0, vyf - vy0])
    assert len(rhs) == m + 2
    return M, rhs


def system_and_cost(problem: Problem, S: Scaled, t: FloatArray) -> tuple[FloatArray, FloatArray, float]:
    """``(M, rhs, J)``: the scaled jump system (:func:`jump_system_sigma` at ``σ = t/T``) and the
    closed-form cost ``J(t)`` (:class:`ValueFunction`, physical units), in one call (what the
    self-check of :mod:`~iamp.planners.pmp.verify` reads of the fixed-time problem)."""
    M, rhs = jump_system_sigma(S, t / S.units.T)
    J = float(ValueFunction(problem, S)(t[None, :])[0])
    return M, rhs, J


def jump_system_sigma(S: Scaled, sig: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Scaled jump system ``M̃ z̃ = r̃`` at ``σ`` (see :func:`jump_system`); built by
    :func:`jump_rows`."""
    M, rhs = jump_rows(S, np.asarray(sig, dtype=float).tolist())
    return np.array(M), np.array(rhs)


def check_times(problem: Problem, contact_times: ArrayLike) -> FloatArray:
    """``contact_times`` as a float vector of length ``m`` inside ``(0, t_f)`` (else ValueError)."""
    t = np.asarray(contact_times, dtype=float).reshape(-1)
    if t.shape != (problem.m,):
        raise ValueError(f"need {problem.m} contact times, got {t.shape[0]}")
    if not np.all((t > 0) & (t < problem.tf)):
        raise ValueError(f"contact times must lie in (0, {problem.tf}); got {t}")
    return t


def solve_sigma(S: Scaled, sig: FloatArray) -> FloatArray:
    """Scaled ``z̃ = (ã, b̃, Φ̃)`` (rows) per axis (columns); SolverError if singular."""
    M, rhs = jump_system_sigma(S, sig)
    try:
        with np.errstate(all="raise"):
            z = np.linalg.solve(M, rhs)
    except (np.linalg.LinAlgError, FloatingPointError):
        raise SolverError(f"contact times {sig * S.units.T} make the jump conditions singular",
                          "numerical_error") from None
    if not np.all(np.isfinite(z)):
        raise SolverError(f"contact times {sig * S.units.T} make the jump conditions singular", "numerical_error")
    out: FloatArray = np.asarray(z, dtype=np.float64)
    return out


def solution_from_sigma(problem: Problem, S: Scaled, sig: FloatArray, z: FloatArray) -> PMPSolution:
    """The physical :class:`PMPSolution` of a scaled solve."""
    u = S.units
    return PMPSolution(problem, sig * u.T, z[0] * u.acc, z[1] * u.jerk, z[2:] * u.jerk, scaled=S, z_scaled=z)


def solve_fixed_times(problem: Problem, contact_times: ArrayLike, scaled: Scaled | None = None) -> PMPSolution:
    """Solve the necessary and co-state jump conditions for given contact times (in scaled
    units).  Raises :class:`SolverError` if the system is singular (coincident times)."""
    t = check_times(problem, contact_times)
    S = scale_problem(problem) if scaled is None else scaled
    sig = t / S.units.T
    return solution_from_sigma(problem, S, sig, solve_sigma(S, sig))


def one_vehicle_z(S: Scaled, s1: float) -> FloatArray:
    r"""Scaled ``z̃`` for one vehicle by eliminating ``Φ`` first (scalar code): per axis
    ``Φ̃ = −ẽ/K̃`` with ``K̃ = σ³(1−σ)³/3``, then ``(ã, b̃)`` from the two final conditions
    ``ã/2 + b̃/6 = E + Φ̃(1−σ)³/6`` and ``ã + b̃/2 = G + Φ̃(1−σ)²/2``."""
    K = s1**3 * (1 - s1) ** 3 / 3
    z = np.empty((3, 2))
    ex = float(horner_rows(S.EX, np.array([s1]))[0])
    ey = float(horner_rows(S.EY, np.array([s1]))[0])
    for k, e in ((0, ex), (1, ey)):
        s0, v0, sf, vf = S.ego[4 * k: 4 * k + 4]
        E = sf - s0 - v0
        G = vf - v0
        phi = -e / K
        r1 = E + phi * (1 - s1) ** 3 / 6
        r2 = G + phi * (1 - s1) ** 2 / 2
        b = 6 * r2 - 12 * r1
        z[0, k] = r2 - b / 2
        z[1, k] = b
        z[2, k] = phi
    return z


def solve_one_vehicle(problem: Problem, contact_time: float, scaled: Scaled | None = None) -> PMPSolution:
    """:func:`solve_fixed_times` for one vehicle by the Schur complement (same solution)."""
    t1 = float(check_times(problem, [contact_time])[0])
    S = scale_problem(problem) if scaled is None else scaled
    sig = np.array([t1 / S.units.T])
    return solution_from_sigma(problem, S, sig, one_vehicle_z(S, float(sig[0])))


def hamiltonian_jump_residuals(problem: Problem, contact_times: ArrayLike) -> FloatArray:
    """``r(t)`` — the Hamiltonian-jump residual of the fixed-time solution (= ``∇J(t)``)."""
    return solve_fixed_times(problem, contact_times).hamiltonian_jump_residual()
