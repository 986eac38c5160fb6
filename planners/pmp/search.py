r"""The global contact-time search: the minimiser of :math:`J(t)` over :math:`(0, t_f)^m`.

All work is in scaled units (``σ = t/t_f``, :mod:`iamp.planners.pmp.scale`).

One vehicle (exact)
-------------------
With :math:`N(\sigma) = \tilde e_x^2 + \tilde e_y^2` and :math:`\tilde K = \sigma^3(1-\sigma)^3/3`,
:math:`\tilde J = \tilde J_0 + \tfrac12 N/\tilde K` and :math:`d\tilde J/d\sigma = 0` exactly where

.. math::  P(\sigma) = N'(\sigma)\,\sigma(1-\sigma) - 3N(\sigma)(1-2\sigma) = 0 .

Every root of ``P`` in ``(0, 1)`` is isolated (:func:`iamp.planners.pmp.roots.unit_roots`) and
the global minimiser is the root with the least ``N/K̃`` (``J → ∞`` at both ends when the
corner is not on the ego's start or end state).

Several vehicles
----------------
Starts from every combination of the one-vehicle stationary points (each vehicle alone),
polished by Newton's method on the Hamiltonian-jump residuals ``r = ∇J`` (closed form,
:meth:`ValueFunction.gradient_sigma`), then certified by branch and bound
(:mod:`iamp.planners.pmp.bound`) which also reveals and polishes any better basin it finds.
Every polished minimiser contributes a *basin box* (:mod:`iamp.planners.pmp.basin`): a
rigorous lower bound of ``q`` on a whole neighbourhood, so the certificate does not refine
down to ``√ε`` around it.  A start inside a known basin box is not polished again, and
:func:`trusted_q` (which solves the jump system) runs only for would-be incumbents.
If the bound cannot close within its budget the result is only *local*.

This is the one implementation of the search (its numba copy was removed, issue 32); its
kernels (value function, gradient, Newton, box bounds, basin boxes, split) are written once in
:mod:`iamp.planners.pmp.search_kernels`, run as Python, or compiled from the same code by
:func:`iamp.planners.pmp.compiled.load_search` with the same numbers bit for bit.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from itertools import permutations, product

import numpy as np
import numpy.typing as npt

from . import search_kernels as sk
from .fixed import ValueFunction
from .jit import compilable
from .scale import Scaled
from .stationary import stationarity_poly as stationarity_poly
from .stationary import stationary_sigmas as stationary_sigmas

FloatArray = npt.NDArray[np.float64]


@compilable
def _q_one(ex: Sequence[float], ey: Sequence[float], s: float) -> float:
    """``N(σ)/K̃(σ)`` for one vehicle (scalar Horner)."""
    px = 0.0
    for k in range(len(ex) - 1, -1, -1):
        px = px * s + ex[k]
    py = 0.0
    for k in range(len(ey) - 1, -1, -1):
        py = py * s + ey[k]
    w = 1.0 - s
    return (px * px + py * py) * 3.0 / (s * s * s * w * w * w)


@compilable
def one_vehicle_sigma(ex: Sequence[float], ey: Sequence[float]) -> tuple[float, float]:
    """``(σ*, q*)``: the global minimiser of ``q = N/K̃`` over ``(0, 1)`` and its value;
    ``(nan, inf)`` if ``J`` has no interior stationary point."""
    best_s, best_q = float("nan"), float("inf")
    for s in stationary_sigmas(ex, ey):
        q = _q_one(ex, ey, s)
        if q < best_q:
            best_s, best_q = s, q
    return best_s, best_q


def newton_sigma(vf: ValueFunction, s0: FloatArray, max_iter: int = 60) -> tuple[FloatArray, float]:
    """Damped Newton on ``∇J̃(σ) = 0`` from ``s0`` with backtracking on ``J̃`` (stays a descent
    method, inside ``(0, 1)``); the Hessian is the central difference of the closed-form
    gradient (:func:`iamp.planners.pmp.search_kernels.newton`).  Returns ``(σ, q(σ))``."""
    s0 = np.ascontiguousarray(s0, dtype=np.float64).reshape(-1)
    with np.errstate(all="ignore"):
        s, q = sk.kernel("newton")(vf._EX, vf._EY, vf._DEX, vf._DEY, s0, int(max_iter))
    return np.asarray(s, dtype=np.float64), float(q)


def trusted_q(vf: ValueFunction, s: FloatArray) -> float:
    """``q(σ)`` if it can be trusted as an incumbent of the branch and bound, else ``inf``:
    the times are distinct (``|σ_i − σ_j| > 1e-6``, below that ``K`` is too ill-conditioned
    for the closed form) and the closed form agrees with the exact integral of ``|u|²`` of
    the solved trajectory (``pmp_cost_consistency_rel``)."""
    from iamp.core.tolerances import TOLERANCES

    from .fixed import solution_from_sigma, solve_sigma

    ss = np.sort(s)
    if ss.size > 1 and float(np.min(np.diff(ss))) <= 1e-6:
        return float("inf")
    q = float(vf.quad_sigma(s[None, :])[0])
    try:
        with np.errstate(all="ignore"):
            sol = solution_from_sigma(vf.problem, vf.scaled, s, solve_sigma(vf.scaled, s))
            J_traj = sol.cost() / vf.units.cost
    except Exception:  # any failure of the check disqualifies the candidate
        return float("inf")
    J = vf.scaled.jbar + 0.5 * q
    if not (np.isfinite(J) and abs(J - J_traj) <= TOLERANCES["pmp_cost_consistency_rel"] * max(abs(J_traj), 1e-300)):
        return float("inf")
    return q


@dataclass
class SearchResult:
    """Outcome of :func:`global_search` (scaled units)."""

    sigma: FloatArray
    q: float
    certified: bool
    boxes: int
    starts: int


def start_points(S: Scaled, max_starts: int = 32) -> list[FloatArray]:
    """Every combination of the one-vehicle stationary points (each vehicle alone) and one
    evenly spaced start per ordering of the contact times (sampled beyond ``m = 5``); the
    caller keeps the best ``max_starts`` by ``J``."""
    per = []
    for i in range(S.m):
        roots = stationary_sigmas(S.EX[i].tolist(), S.EY[i].tolist())
        per.append(roots if roots else [0.5])
    combos = [np.array(c) for c in product(*per)]
    # every ordering of the contact times, evenly spaced (capped at 4·max_starts orderings)
    m = S.m
    spaced = (np.arange(m) + 1.0) / (m + 1.0)
    orders = list(permutations(range(m))) if m <= 5 else []
    rng = np.random.default_rng(0)
    if not orders or len(orders) > 4 * max_starts:
        orders = [tuple(rng.permutation(m)) for _ in range(4 * max_starts)]
    for perm in orders:
        start = np.empty(m)
        start[list(perm)] = spaced
        combos.append(start)
    if len(combos) > 8 * max_starts:
        combos = [combos[k] for k in rng.choice(len(combos), 8 * max_starts, replace=False)]
    return combos


def global_search(vf: ValueFunction, max_starts: int = 32, max_boxes: int = 200_000,
                  progress: Callable[[int, int], None] | None = None) -> SearchResult:
    """The global minimiser of ``J̃`` over ``(0, 1)^m`` (module docstring).  ``max_boxes = 0``
    skips the branch and bound: the best polished start, not certified (a start for the
    bounded search, :meth:`~iamp.planners.pmp.planner.PMPPlanner._plan_limited`)."""
    from .basin import Basin, add_basin, in_basins
    from .bound import branch_and_bound

    S = vf.scaled
    starts = start_points(S, max_starts)
    vals = vf.quad_sigma(np.array(starts))
    order = np.argsort(vals)[:max_starts]

    basins: list[Basin] = []
    best_q = float("inf")

    def polish(s0: FloatArray) -> tuple[FloatArray, float]:
        """Newton, then ``q`` — checked by :func:`trusted_q` only if it would improve the
        incumbent (an untrusted or worse point is never the incumbent either way)."""
        s, q = newton_sigma(vf, s0)
        return s, (trusted_q(vf, s) if q < best_q else float("inf"))

    best_s = starts[int(order[0])]
    for k in order:
        if in_basins(basins, starts[int(k)], np.zeros(S.m)):
            continue  # Newton would return to that basin's minimiser
        s, q = polish(starts[int(k)])
        if max_boxes:  # the basins serve the certificate
            add_basin(vf, basins, s)
        if q < best_q:
            best_s, best_q = s, q

    if max_boxes == 0:
        return SearchResult(np.asarray(best_s, dtype=float), best_q, False, 0, len(order))
    bb = branch_and_bound(vf, best_s, best_q, polish, max_boxes=max_boxes, progress=progress, basins=basins)
    return SearchResult(bb.sigma, bb.q, bb.certified, bb.boxes, len(order))
