r"""Exact references of the discretised QP at given grid contact times (SPEC §3).

* FOH is exact: its sweep cost at a candidate is the PMP's value function :math:`J(t)`.
* ZOH with the contacts on nodes is the moment problem
  :math:`\min \tfrac12\int u^2` s.t. :math:`\int \varphi_j u = c_j` over piecewise-constant
  ``u``, with :math:`\varphi \in \{1,\ t_f-\tau,\ (t_i-\tau)_+\}`.  Its solution is
  :math:`u = \sum_j \mu_j \Pi_h\varphi_j` with :math:`(G - E)\mu = c`, where
  :math:`G_{jk} = \int\varphi_j\varphi_k` is the continuous Gram matrix and
  :math:`E_{jk} = \sum_k \tfrac{h_k^3}{12}\varphi_j'\varphi_k'`; so
  :math:`J_{ZOH} = \tfrac12\sum_{axes} c^\top (G-E)^{-1} c` and :math:`\nu_i = -\mu_i`
  (derivation and the :math:`O(h^2)` bracket in :mod:`iamp.comparison.agreement.judge`).
"""

from __future__ import annotations

import itertools

import numpy as np
from numpy.typing import ArrayLike, NDArray

from iamp.core.problem import Problem
from iamp.planners.pmp.planner import ValueFunction

from .records import ZohReference

__all__ = ["candidate_table", "grid_cost_table", "zoh_reference"]

FloatArray = NDArray[np.float64]


def _gram(t: ArrayLike, T: float) -> FloatArray:
    """``G`` and ``D = ∫φ'φ'`` for contact times ``t`` of shape ``(..., m)``."""
    t = np.asarray(t, dtype=float)
    m = t.shape[-1]
    shp = t.shape[:-1]
    G = np.empty(shp + (m + 2, m + 2))
    G[..., 0, 0] = T
    G[..., 0, 1] = G[..., 1, 0] = T**2 / 2
    G[..., 1, 1] = T**3 / 3
    G[..., 0, 2:] = G[..., 2:, 0] = t**2 / 2
    G[..., 1, 2:] = G[..., 2:, 1] = T * t**2 / 2 - t**3 / 6
    ti, tj = t[..., :, None], t[..., None, :]
    a = np.minimum(ti, tj)
    G[..., 2:, 2:] = ti * tj * a - (ti + tj) * a**2 / 2 + a**3 / 3
    return G


def _rhs(problem: Problem, t: ArrayLike) -> FloatArray:
    """``c`` of shape ``(..., m+2, 2)``: final speed, final position, contact positions."""
    t = np.asarray(t, dtype=float)
    e, T = problem.ego, problem.tf
    c = np.empty(t.shape[:-1] + (t.shape[-1] + 2, 2))
    c[..., 0, :] = [e.vxf - e.vx0, e.vyf - e.vy0]
    c[..., 1, :] = [e.xf - e.x0 - e.vx0 * T, e.yf - e.y0 - e.vy0 * T]
    for i, v in enumerate(problem.vehicles):
        c[..., 2 + i, 0] = v.corner_x(t[..., i]) - e.x0 - e.vx0 * t[..., i]
        c[..., 2 + i, 1] = v.corner_y - e.y0 - e.vy0 * t[..., i]
    return c


def _e_matrix(node_idx: ArrayLike, cw: FloatArray) -> FloatArray:
    """``E`` from the cumulative interval weights ``cw[k] = Σ_{intervals < k} h³/12``."""
    node_idx = np.asarray(node_idx)
    m = node_idx.shape[-1]
    E = np.zeros(node_idx.shape[:-1] + (m + 2, m + 2))
    E[..., 1, 1] = cw[-1]
    E[..., 1, 2:] = E[..., 2:, 1] = cw[node_idx]
    E[..., 2:, 2:] = cw[np.minimum(node_idx[..., :, None], node_idx[..., None, :])]
    return E


def zoh_reference(problem: Problem, t_nodes: ArrayLike, nodes: ArrayLike) -> ZohReference:
    r"""The exact ZOH optimum with the contacts at grid nodes ``nodes`` of ``t_nodes``.

    Returns ``cost``, nodal states ``X`` ``(N+1, 4)``, inputs ``U`` ``(N, 2)``, multipliers
    ``nu`` ``(m, 2)``, the continuous cost ``J_continuous`` (= the PMP's, from the same
    Gram matrix), the leading gap term ``gap_leading`` :math:`\Delta_1` and
    :math:`\rho = \lambda_{\max}(G^{-1}E)`; see the module docstring.
    """
    from scipy.linalg import eigh

    t_nodes = np.asarray(t_nodes, dtype=float)
    nodes = np.asarray(nodes, dtype=int)
    T = problem.tf
    t = t_nodes[nodes]
    h = np.diff(t_nodes)
    cw = np.r_[0.0, np.cumsum(h**3 / 12)]
    G = _gram(t, T)
    E = _e_matrix(nodes, cw)
    c = _rhs(problem, t)
    mu = np.linalg.solve(G - E, c)
    lam = np.linalg.solve(G, c)
    cost = 0.5 * float(np.sum(c * mu))
    j_cont = 0.5 * float(np.sum(c * lam))
    gap_leading = 0.5 * float(np.sum(lam * (E @ lam)))
    rho = float(eigh(E, G, eigvals_only=True)[-1])
    mids = 0.5 * (t_nodes[:-1] + t_nodes[1:])
    phi = np.column_stack([np.ones_like(mids), T - mids] + [np.maximum(ti - mids, 0.0) for ti in t])
    U = phi @ mu  # (N, 2)
    e = problem.ego
    X = np.empty((len(t_nodes), 4))
    X[0] = [e.x0, e.vx0, e.y0, e.vy0]
    for k in range(len(h)):
        for ax in range(2):
            s, v = X[k, 2 * ax], X[k, 2 * ax + 1]
            X[k + 1, 2 * ax] = s + h[k] * v + h[k] ** 2 / 2 * U[k, ax]
            X[k + 1, 2 * ax + 1] = v + h[k] * U[k, ax]
    return {"cost": cost, "X": X, "U": U, "nu": np.asarray(-mu[2:], dtype=np.float64), "J_continuous": j_cont,
            "gap_leading": gap_leading, "rho": rho}


def candidate_table(problem: Problem, steps: int) -> NDArray[np.int_]:
    """Every ordered combination of distinct interior nodes, ``(K, m)``."""
    return np.array(list(itertools.permutations(range(1, steps), problem.m)), dtype=int).reshape(-1, problem.m)


def grid_cost_table(problem: Problem, steps: int, hold: str) -> tuple[NDArray[np.int_], FloatArray]:
    """The exact sweep cost at every candidate of the uniform grid: ``(candidates, J)``.

    FOH: the PMP's value function :math:`J(t)`.  ZOH: :math:`\\tfrac12\\sum c^\\top(G-E)^{-1}c`.
    """
    cands = candidate_table(problem, steps)
    h = problem.tf / steps
    t = cands * h
    if hold == "foh":
        J = ValueFunction(problem)(t)
    else:
        cw = np.arange(steps + 1) * h**3 / 12
        G = _gram(t, problem.tf)
        E = _e_matrix(cands, cw)
        c = _rhs(problem, t)
        with np.errstate(all="ignore"):
            try:
                mu = np.linalg.solve(G - E, c)
                J = 0.5 * np.sum(c * mu, axis=(-1, -2))
            except np.linalg.LinAlgError:
                J = np.full(len(cands), np.inf)
                for k in range(len(cands)):
                    try:
                        J[k] = 0.5 * np.sum(c[k] * np.linalg.solve(G[k] - E[k], c[k]))
                    except np.linalg.LinAlgError:
                        pass
    J = np.where(np.isfinite(J), J, np.inf)
    return cands, J
