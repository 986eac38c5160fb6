r"""The saturated co-state law for one axis at fixed contact times (SPEC §14, bounded PMP).

Problem (one axis, the x and y axes decouple for fixed contact times when only the input box
``ax``/``ay`` is imposed):

.. math::

    \min_u \tfrac12\int_0^{T} u^2\,dt \quad\text{s.t.}\quad \ddot s = u,\
    s(0)=s_0,\ \dot s(0)=v_0,\ s(T)=s_f,\ \dot s(T)=v_f,\
    s(t_i) = c_i\ (i=1..m),\ \ell \le u(t) \le h .

Every equality is a linear functional of ``u``: with :math:`s(t) = s_0 + v_0 t +
\int_0^t (t-\tau)u(\tau)\,d\tau`,

.. math::

    \int_0^T g_k(\tau)\,u(\tau)\,d\tau = d_k,\qquad
    g_i = (t_i-\tau)_+,\ g_{m+1} = T-\tau,\ g_{m+2} = 1,

    d_i = c_i - s_0 - v_0 t_i,\ d_{m+1} = s_f - s_0 - v_0 T,\ d_{m+2} = v_f - v_0 .

**Co-states and the saturated law.**  With the multipliers :math:`\lambda\in\mathbb R^{m+2}`
the pointwise minimisation of :math:`\tfrac12u^2 - w u`, :math:`w(\tau)=\lambda^\top g(\tau)`,
over the box gives

.. math::  u(\tau) = \operatorname{clip}(w(\tau), \ell, h) = \operatorname{clip}(-p_v(\tau), \ell, h),

since :math:`w = -p_v` (``p_v = p_2`` or ``p_4``) is the unbounded PMP's co-state form
:math:`w = a + bt - \sum_i\Phi_i (t-t_i)_+` with

.. math::  a = \textstyle\sum_i\lambda_i t_i + \lambda_{m+1}T + \lambda_{m+2},\quad
           b = -\sum_i\lambda_i - \lambda_{m+1},\quad \Phi_i = -\lambda_i .

So ``p_v`` is continuous and linear between contact times, ``p_s = \dot w`` (``p1`` or ``p3``)
jumps by :math:`p_s^- - p_s^+ = \Phi_i` at :math:`t_i`, and ``u`` is continuous and piecewise
linear with kinks at the contact times and at the **switching times** :math:`\theta`, the
roots of :math:`w(\theta) = \ell` or :math:`w(\theta) = h` (where ``−p_v`` crosses a bound).

**The dual and its Newton method.**  The dual function

.. math::  D(\lambda) = \lambda^\top d + \int_0^T \big(\tfrac12 u^2 - w u\big)\,d\tau,
           \quad u = \operatorname{clip}(w),

is concave and piecewise quadratic, with :math:`\nabla D = d - \int g\,u =: -F(\lambda)`
(minus the equality residuals) and generalised Hessian
:math:`-\int_{\ell<w<h} g g^\top d\tau`.  A semi-smooth Newton method with an Armijo line
search on ``D`` solves :math:`F(\lambda)=0`; on a piecewise-quadratic concave function it
stops after finitely many steps once the saturated set is right.  Every integral is exact:
between consecutive contact and switching times ``g``, ``w`` and ``u`` are linear, so
Simpson's rule on each piece is exact.  Started from the unbounded solution (the full Gram
system), the first iterate is the unbounded optimum, which is returned unchanged when it
respects the box.

**Infeasible box.**  If no input in the box meets the equalities, ``D`` is unbounded above
and the iterates run off along a Farkas direction :math:`\hat\lambda`:
:math:`\hat\lambda^\top d > \sigma(\hat\lambda) = \int_0^T \max(h\,w, \ell\,w)\,d\tau`
(``σ`` the support function of the reachable set).  That inequality is checked exactly and
returned as the certificate.

All the work is done in the axis' own units (time over ``T``, lengths over the largest
datum), so residuals are dimensionless.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from . import compiled as _compiled
from . import jit
from . import saturated_kernel as _kernel

#: Newton iterations before the dual is declared divergent (an infeasibility candidate).
MAX_NEWTON = 60


@dataclass
class AxisSolution:
    """The saturated optimum of one axis (physical units).

    Attributes
    ----------
    knots : list of float
        ``0 = τ_0 < … < τ_K = T``: contact times and switching times, where ``u`` may kink.
    u : list of float
        ``u(τ_k)`` (``u`` is continuous and linear between knots).
    a, b : float
        ``w(0)`` and ``ẇ(0)`` of ``w = −p_v`` (``p_v(0) = −a``, ``p_s(0) = b``).
    jumps : list of float
        ``Φ_i`` in the order of the contact times given.
    switching : list of tuple
        ``(θ, bound_value, "lower"|"upper", direction)``: ``w`` enters (``+1``) or leaves
        (``−1``) the saturated set at ``θ``.
    cost : float
        ``½∫u²`` (exact).
    dual : float
        ``D(λ)`` at the returned multipliers (equals ``cost`` at the optimum).
    iterations : int
        Newton steps taken.
    """

    knots: list[float]
    u: list[float]
    a: float
    b: float
    jumps: list[float]
    switching: list[tuple[float, float, str, int]]
    cost: float
    dual: float
    iterations: int
    newton_residual: float
    lam: list[float] = field(default_factory=list)
    #: ``v(t_i)`` at the contact times (order of the contact times given).
    contact_speeds: list[float] = field(default_factory=list)


class AxisInfeasible(Exception):
    """The box cannot meet the equalities; ``certificate`` is the Farkas direction and
    ``margin = λ̂ᵀd − σ(λ̂) > 0`` (scaled units); ``lam_phys`` and ``margin_phys`` the same in
    physical units (``λ`` of the ramps and of ``T − τ`` times ``ℓ/T³``, of ``1`` times
    ``ℓ/T²``; the margin times ``ℓ²/T³``)."""

    def __init__(self, message: str, certificate: list[float], margin: float,
                 lam_phys: list[float] | None = None, margin_phys: float | None = None):
        super().__init__(message)
        self.certificate = certificate
        self.margin = margin
        self.lam_phys = lam_phys
        self.margin_phys = margin_phys


class AxisNoConvergence(Exception):
    """The dual Newton method stopped without convergence and without a certificate."""


class _Axis:
    """The scaled data of one axis: ``σ_i = t_i/T``, ``d̃``, bounds ``ũ = uT²/ℓ``."""

    def __init__(self, times: list[float], T: float, s0: float, v0: float, sf: float, vf: float,
                 corners: list[float], lo: float, hi: float):
        self.T = T
        self.v0 = v0
        self.m = m = len(times)
        d = [c - s0 - v0 * t for c, t in zip(corners, times)] + [sf - s0 - v0 * T, (vf - v0) * T]
        scale = max([abs(x) for x in d] + [1e-300])
        for bnd in (lo, hi):
            if math.isfinite(bnd):
                scale = max(scale, abs(bnd) * T * T)
        self.ell = scale  # length unit
        self.d = [x / scale for x in d]
        self.lo = lo * T * T / scale
        self.hi = hi * T * T / scale
        self.sig = [t / T for t in times]
        self.base = sorted(set([0.0, 1.0] + [s for s in self.sig if 0.0 < s < 1.0]))
        self.n = m + 2

    def g(self, tau: float) -> list[float]:
        """``g̃(τ)``: ramps ``(σ_i − τ)_+``, then ``1 − τ`` and ``1``."""
        return [max(s - tau, 0.0) for s in self.sig] + [1.0 - tau, 1.0]

    def pieces(self, lam: list[float]) -> list[tuple[float, float, float, float, int]]:
        """Sub-pieces ``(τa, τb, wa, wb, kind)`` with kind 0 free, −1 lower, +1 upper."""
        return _tuples(_kernel.pieces(self.sig, self.base, lam, self.lo, self.hi))

    def clip(self, w: float) -> float:
        return self.lo if w < self.lo else (self.hi if w > self.hi else w)

    def support(self, lam: list[float]) -> float:
        """``σ(λ) = ∫ max(h̃ w, ℓ̃ w) dτ`` (exact; ``inf`` when an infinite bound meets a nonzero w;
        :func:`~iamp.planners.pmp.saturated_kernel.support`)."""
        return float(_kernel.support(self.sig, self.base, lam, self.lo, self.hi))


def solve_axis(times: list[float], T: float, s0: float, v0: float, sf: float, vf: float,
               corners: list[float], lo: float, hi: float, lam0: list[float] | None = None,
               tol_residual: float = 1e-12) -> AxisSolution:
    """The saturated optimum of one axis (module docstring).

    Parameters
    ----------
    times : list of float
        Contact times in ``(0, T)`` (any order; distinct).
    T, s0, v0, sf, vf : float
        Horizon and boundary conditions.
    corners : list of float
        The interior-point values :math:`c_i = s(t_i)`.
    lo, hi : float
        Input box (``±inf`` for an unbounded axis).
    lam0 : list of float, optional
        Scaled multipliers to start from (warm start); default: the unbounded optimum.
    tol_residual : float
        Newton stops when ``max|F| <= tol_residual`` (scaled units).

    Raises
    ------
    AxisInfeasible
        With an exactly checked Farkas certificate when the box cannot meet the equalities.
    AxisNoConvergence
        When Newton stalls without a certificate.
    """
    ax = _Axis(times, T, s0, v0, sf, vf, corners, lo, hi)
    code, it, res, D, _, lam, F, _, ps = _core(ax, lam0, tol_residual)
    if code == _kernel.SINGULAR_GRAM:
        raise AxisNoConvergence("the contact times make the jump conditions singular")
    if code != _kernel.CONVERGED:
        _raise_infeasible_or_stall(ax, lam, F, res)
    return _axis_solution(ax, lam, D, _tuples(ps), it, res)


def solve_axis_value(times: list[float], T: float, s0: float, v0: float, sf: float, vf: float,
                     corners: list[float], lo: float, hi: float, lam0: list[float] | None = None,
                     tol_residual: float = 1e-12
                     ) -> tuple[float, list[float], list[float], list[float]] | None:
    """What the contact-time search needs of :func:`solve_axis`, without building the
    :class:`AxisSolution`: ``(cost, jumps, contact_speeds, lam)`` (the same numbers, the same
    arithmetic), or ``None`` where :func:`solve_axis` raises (infeasible box or a stall)."""
    ax = _Axis(times, T, s0, v0, sf, vf, corners, lo, hi)
    code, _, _, _, cost, lam, _, vc, _ = _core(ax, lam0, tol_residual)
    if code != _kernel.CONVERGED:
        return None
    ell = ax.ell
    T3 = T**3
    jumps = [-(x * ell / T3) for x in lam[:ax.m]]
    speeds = [v0 + x * ell / T for x in vc]
    return cost * ell * ell / T3, jumps, speeds, list(lam)


def _core(ax: _Axis, lam0: list[float] | None, tol_residual: float
          ) -> tuple[int, int, float, float, float, list[float], list[float], list[float], list[float]]:
    """:func:`~iamp.planners.pmp.saturated_kernel.axis_core` on ``ax``: the compiled twin
    once :func:`~iamp.planners.pmp.compiled.load_axis` has run in the process, else the
    pure Python one (the same code, the same numbers)."""
    run = _compiled.axis_core()
    if run is None:
        return _kernel.axis_core(ax.sig, ax.base, ax.d, ax.lo, ax.hi, [] if lam0 is None else lam0,
                                 lam0 is not None, tol_residual, MAX_NEWTON)
    out: tuple[int, int, float, float, float, list[float], list[float], list[float], list[float]] = run(
        ax.sig, ax.base, ax.d, ax.lo, ax.hi, lam0, tol_residual, MAX_NEWTON)
    return out


def contact_points(ts: list[float], T: float, pos: list[float], off_x: float, off_y: float, data: list[float],
                   warm: list[float], has_warm: list[float], retry_cold: bool, tol_residual: float = 1e-12
                   ) -> list[float]:
    """:func:`~iamp.planners.pmp.saturated_kernel.contact_points` (both axes of one vehicle at
    many contact times in one call): the compiled twin once
    :func:`~iamp.planners.pmp.compiled.load_axis` has run in the process (compiled from the
    same source on its first call), else the Python function: the same numbers."""
    if _compiled.axis_core() is None:
        return _kernel.contact_points(ts, T, T**2, T**3, pos, off_x, off_y, data, warm, has_warm, retry_cold,
                                      tol_residual, MAX_NEWTON)
    import numpy as np

    run = jit.twin(_kernel.contact_points)
    arr = [np.asarray(x, dtype=float) for x in (ts, pos, data, warm, has_warm)]
    out: list[float] = run(arr[0], float(T), float(T**2), float(T**3), arr[1], float(off_x), float(off_y), arr[2],
                           arr[3], arr[4], bool(retry_cold), float(tol_residual), MAX_NEWTON)
    return out


def interval_terms(ab: list[float], T: float, pos: list[float], der: list[float], off_x: float, off_y: float,
                   data: list[float], warm: list[float], has_warm: list[float], cddot_x: float,
                   tol_residual: float = 1e-12) -> list[float]:
    """:func:`~iamp.planners.pmp.saturated_kernel.interval_terms` (the global certificate's
    bound terms on many intervals of one vehicle's contact time): the compiled twin once
    :func:`~iamp.planners.pmp.compiled.load_axis` has run in the process, else the Python
    function: the same numbers."""
    if _compiled.axis_core() is None:
        return _kernel.interval_terms(ab, T, T**2, T**3, pos, der, off_x, off_y, data, warm, has_warm, cddot_x,
                                      tol_residual, MAX_NEWTON)
    import numpy as np

    run = jit.twin(_kernel.interval_terms)
    arr = [np.asarray(x, dtype=float) for x in (ab, pos, der, data, warm, has_warm)]
    out: list[float] = run(arr[0], float(T), float(T**2), float(T**3), arr[1], arr[2], float(off_x), float(off_y),
                           arr[3], arr[4], arr[5], float(cddot_x), float(tol_residual), MAX_NEWTON)
    return out


def cover_points(times: list[float], corners: list[float], m: int, T: float, data: list[float],
                 tol_residual: float = 1e-12) -> list[float]:
    """:func:`~iamp.planners.pmp.saturated_kernel.cover_points` (both axes, cold, with the Farkas
    test, at many choices of ``m`` contact times): the compiled twin once
    :func:`~iamp.planners.pmp.compiled.load_axis` has run in the process, else the Python
    function: the same numbers."""
    if _compiled.axis_core() is None:
        return _kernel.cover_points(times, corners, m, T, T**2, T**3, data, tol_residual, MAX_NEWTON)
    import numpy as np

    run = jit.twin(_kernel.cover_points)
    out: list[float] = run(np.asarray(times, dtype=float), np.asarray(corners, dtype=float), int(m), float(T),
                           float(T**2), float(T**3), np.asarray(data, dtype=float), float(tol_residual), MAX_NEWTON)
    return out


def _farkas_margin(ax: _Axis, cand: list[float]) -> tuple[float, float]:
    """:func:`~iamp.planners.pmp.saturated_kernel.farkas_margin` on ``ax``: compiled once
    :func:`~iamp.planners.pmp.compiled.load_axis` has run in the process, else the Python
    function (the same numbers)."""
    if _compiled.axis_core() is None:
        norm, margin = _kernel.farkas_margin(ax.sig, ax.base, ax.d, ax.lo, ax.hi, cand)
        return norm, margin
    import numpy as np

    out: tuple[float, float] = jit.twin(_kernel.farkas_margin)(
        np.asarray(ax.sig, dtype=float), np.asarray(ax.base, dtype=float), np.asarray(ax.d, dtype=float),
        float(ax.lo), float(ax.hi), np.asarray(cand, dtype=float))
    return out


def _tuples(ps: list[float]) -> list[tuple[float, float, float, float, int]]:
    """The kernel's flat pieces as ``(τa, τb, wa, wb, kind)`` tuples."""
    return [(ps[q], ps[q + 1], ps[q + 2], ps[q + 3], int(ps[q + 4])) for q in range(0, len(ps), 5)]


def _raise_infeasible_or_stall(ax: _Axis, lam: list[float], F: list[float], res: float) -> None:
    """Check a Farkas certificate along the divergent multipliers (and along ``−F``)."""
    for cand in (lam, [-x for x in F]):
        norm, margin = _farkas_margin(ax, cand)
        if not norm > 0 or not math.isfinite(norm):
            continue
        direc = [x / norm for x in cand]
        if margin > 1e-9:
            T, ell = ax.T, ax.ell
            lam_phys = [x * ell / T**3 for x in direc[:-1]] + [direc[-1] * ell / T**2]
            raise AxisInfeasible("no input in the box meets the boundary and corner conditions "
                                 f"(Farkas margin {margin:.3g} in scaled units)", direc, margin,
                                 lam_phys, margin * ell * ell / T**3)
    raise AxisNoConvergence(f"the dual Newton method stalled at residual {res:.3g}")


def _axis_solution(ax: _Axis, lam: list[float], D: float, ps: list[tuple[float, float, float, float, int]],
                   it: int, res: float) -> AxisSolution:
    T, ell = ax.T, ax.ell
    ucon = ell / (T * T)
    knots = [0.0]
    u = [ax.clip(ps[0][2]) * ucon]
    switching: list[tuple[float, float, str, int]] = []
    cost = 0.0
    for k, (a, b, wa, wb, kind) in enumerate(ps):
        ua, ub = (wa, wb) if kind == 0 else ((ax.lo, ax.lo) if kind < 0 else (ax.hi, ax.hi))
        cost += (b - a) / 6 * (ua * ua + ua * ub + ub * ub)
        knots.append(b * T)
        u.append(ub * ucon)
        if k + 1 < len(ps) and ps[k + 1][4] != kind:
            nxt = ps[k + 1][4]
            side = kind if kind != 0 else nxt
            bound = ax.hi if side > 0 else ax.lo
            switching.append((b * T, bound * ucon, "upper" if side > 0 else "lower", 1 if nxt != 0 else -1))
    knots[-1] = T
    m = ax.m
    # v(σ_i) = v0 + ∫_0^{σ_i} ũ (the σ_i are piece ends), in physical units
    vcum = [0.0]
    ends = [0.0]
    for a, b, wa, wb, kind in ps:
        ua, ub = (wa, wb) if kind == 0 else ((ax.lo, ax.lo) if kind < 0 else (ax.hi, ax.hi))
        vcum.append(vcum[-1] + (b - a) * (ua + ub) / 2)
        ends.append(b)
    speeds = []
    for s_i in ax.sig:
        j = min(range(len(ends)), key=lambda q: abs(ends[q] - s_i))
        speeds.append(ax.v0 + vcum[j] * ell / T)
    lam_ramp = [x * ell / T**3 for x in lam[:m]]
    lam_lin = lam[m] * ell / T**3
    lam_c = lam[m + 1] * ell / T**2
    times = [s * T for s in ax.sig]
    a = sum(li * ti for li, ti in zip(lam_ramp, times)) + lam_lin * T + lam_c
    b = -sum(lam_ramp) - lam_lin
    cost_phys = cost * ell * ell / T**3  # cost accumulated ½∫ũ²
    return AxisSolution(knots=knots, u=u, a=a, b=b, jumps=[-x for x in lam_ramp], switching=switching,
                        cost=cost_phys, dual=D * ell * ell / T**3, iterations=it, newton_residual=res,
                        lam=list(lam), contact_speeds=speeds)
