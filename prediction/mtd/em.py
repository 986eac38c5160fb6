r"""EM algorithms of the MTD fit: ML lag weights for fixed ``Q_i``, and joint EM with SQUAREM.

Notation: the scored tuples ``(x_t, x_{t-1}, …, x_{t-n})`` are the rows ``r`` of a lag
table (:func:`~iamp.prediction.mtd.counts.lag_table`), de-duplicated with weights ``w_r``
(``N = Σ_r w_r``), and ``P[r, i] = q^{(i)}_{x_t x_{t-i}}``.  The average log-likelihood is

.. math::

    \bar\ell(λ, Q) = \frac1N \sum_r w_r \log \sum_{i=1}^{n} λ_i P[r, i].

EM step (latent lag ``z_t``, ``P(z_t = i) = λ_i``): responsibilities
``ρ_{ri} = λ_i P[r, i] / Σ_l λ_l P[r, l]``, then

.. math::

    λ_i' = \frac1N \sum_r w_r ρ_{ri}, \qquad
    q'^{(i)}_{jk} = \frac{\sum_{r: x_t=j, x_{t-i}=k} w_r ρ_{ri}}{\sum_{r: x_{t-i}=k} w_r ρ_{ri}}

(the second normalises every **column** ``k`` of ``Q_i``, i.e. over ``j`` = axis 1 of the
``(n, m, m)`` array).  Each EM step never decreases ``\bar\ell``.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from iamp.prediction._typing import FloatArray, IntArray

from .counts import _normalise_columns

__all__ = ["em_joint", "em_lambda", "squarem_cycle", "squarem_extrapolate"]

#: Floor of a mixture probability before ``log`` and division: a guard only, since every observed
#: transition keeps a positive probability under EM (its responsibilities, hence counts, are > 0).
_LOG_FLOOR = 1e-300

#: One EM map: ``(λ, Q) -> (λ', Q', \bar\ell(λ, Q))``.
EMMap = Callable[[FloatArray, FloatArray], tuple[FloatArray, FloatArray, float]]


def em_lambda(P: FloatArray, w: FloatArray, lam0: FloatArray, tol: float,
              max_iter: int) -> tuple[FloatArray, dict[str, object]]:
    r"""Maximise ``Σ_r w_r log(P_r · λ)`` over the simplex (concave) by EM updates.

    The update is ``λ_i ← λ_i g_i`` with ``g_i = \frac1N Σ_r w_r P[r, i] / (P_r · λ)`` the
    gradient of ``\bar\ell``; since ``Σ_i λ_i g_i = 1`` and ``\bar\ell`` is concave,
    ``max_i g_i - 1 >= \bar\ell^* - \bar\ell`` certifies the gap and stops the loop below ``tol``.
    """
    N = w.sum()
    lam = lam0.copy()
    gap = np.inf
    it = 0
    converged = False
    while it < max_iter:
        it += 1
        mix = np.maximum(P @ lam, _LOG_FLOOR)
        g = (w / mix) @ P / N  # gradient of ℓ/N
        gap = float(g.max() - 1.0)
        if gap < tol:
            converged = True
            break
        lam = lam * g  # stays on the simplex: Σ_i λ_i g_i = 1 (no renormalisation needed)
    return lam, {"iterations": it, "tolerance": tol, "certificate_max_grad_minus_1": gap,
                 "converged": converged}


def squarem_extrapolate(lam0: FloatArray, Q0: FloatArray, lam1: FloatArray, Q1: FloatArray,
                        lam2: FloatArray, Q2: FloatArray) -> tuple[FloatArray, FloatArray] | None:
    r"""SQUAREM (Varadhan & Roland 2008, scheme S3) extrapolation from three EM iterates.

    With ``r = θ_1 - θ_0``, ``v = θ_2 - 2θ_1 + θ_0`` and ``α = \min(-\|r\|/\|v\|, -1)``,

    .. math::

        θ' = θ_0 - 2α r + α^2 v = (1+α)^2 θ_0 - 2α(1+α) θ_1 + α^2 θ_2 ,

    whose coefficients add to 1, so every column sum of ``Q`` and ``Σ λ`` are kept.  For a
    linear iteration ``θ_{k+1} - θ^* = ρ (θ_k - θ^*)`` it lands on ``θ^*`` exactly.  Entries
    are then floored at half their value in ``θ_2`` (an exact 0 never revives under EM) and
    ``λ`` and every column of every ``Q_i`` (axis 1) renormalised.  ``α = -1`` gives ``θ_2``.

    Returns ``None`` when ``v = 0`` (nothing to extrapolate).
    """
    r = np.concatenate([lam1 - lam0, (Q1 - Q0).ravel()])
    v = np.concatenate([lam2 - 2 * lam1 + lam0, (Q2 - 2 * Q1 + Q0).ravel()])
    nv = float(np.linalg.norm(v))
    if nv == 0.0:
        return None
    alpha = min(-float(np.linalg.norm(r)) / nv, -1.0)
    c0, c1, c2 = (1 + alpha) ** 2, -2 * alpha * (1 + alpha), alpha * alpha
    lam_e = np.maximum(c0 * lam0 + c1 * lam1 + c2 * lam2, 0.5 * lam2)
    Q_e = np.maximum(c0 * Q0 + c1 * Q1 + c2 * Q2, 0.5 * Q2)
    return lam_e / lam_e.sum(), Q_e / Q_e.sum(axis=1, keepdims=True)


def squarem_cycle(em: EMMap, lam: FloatArray,
                  Q: FloatArray) -> tuple[FloatArray, FloatArray, float, int, bool]:
    r"""One safeguarded SQUAREM cycle from ``θ_0 = (λ, Q)``.

    Two EM steps give ``θ_1, θ_2`` (and ``\bar\ell(θ_0)``, ``\bar\ell(θ_1)``); the extrapolated
    point (:func:`squarem_extrapolate`) is stabilised by one EM step ``θ_3 = EM(θ')``, which
    is accepted only if ``\bar\ell(θ') >= \bar\ell(θ_1)`` (the monotonicity safeguard; EM from
    ``θ'`` then gives ``\bar\ell(θ_3) >= \bar\ell(θ') >= \bar\ell(θ_1)``); otherwise the cycle
    returns the plain EM iterate ``θ_2``, with ``\bar\ell(θ_2) >= \bar\ell(θ_1)``.

    Returns
    -------
    lam, Q, ll0, evals, accepted
        The next iterate, ``\bar\ell(θ_0)``, the number of EM evaluations (2 or 3) and
        whether the extrapolation was accepted.
    """
    lam1, Q1, ll0 = em(lam, Q)
    lam2, Q2, ll1 = em(lam1, Q1)
    ext = squarem_extrapolate(lam, Q, lam1, Q1, lam2, Q2)
    if ext is None:
        return lam2, Q2, ll0, 2, False
    lam3, Q3, ll_e = em(*ext)
    if ll_e >= ll1:  # safeguard: never worse than the plain EM step
        return lam3, Q3, ll0, 3, True
    return lam2, Q2, ll0, 3, False


def em_joint(rows: IntArray, w: FloatArray, Q: FloatArray, lam: FloatArray, m: int, pseudocount: float,
             empty: str, tol: float, max_iter: int,
             trace: list[float] | None = None) -> tuple[FloatArray, FloatArray, dict[str, object]]:
    r"""Joint EM for ``(λ, Q_i)`` accelerated with :func:`squarem_cycle`.

    Stops when the increase of ``\bar\ell`` over one cycle, ``\bar\ell(θ_0^{(c)}) -
    \bar\ell(θ_0^{(c-1)})``, falls below ``tol``, or after ``max_iter`` EM evaluations.  The
    values ``\bar\ell(θ_0^{(c)})`` of every cycle are appended to ``trace`` when given (they
    never decrease).  Returns ``(Q, λ, info)``.
    """
    n = Q.shape[0]
    N = w.sum()
    idx = [rows[:, 0] * m + rows[:, i + 1] for i in range(n)]

    def lag_probs(Q: FloatArray) -> FloatArray:
        return np.column_stack([Q[i].ravel()[idx[i]] for i in range(n)])

    def em(lam: FloatArray, Q: FloatArray) -> tuple[FloatArray, FloatArray, float]:
        P = lag_probs(Q)
        mix = np.maximum(P @ lam, _LOG_FLOOR)
        ll = float(np.sum(w * np.log(mix))) / N
        R = P * lam * (w / mix)[:, None]  # weighted responsibilities r_ti
        lam2 = R.sum(axis=0) / N  # on the simplex: every row of responsibilities sums to 1
        C = np.stack([np.bincount(idx[i], weights=R[:, i], minlength=m * m).reshape(m, m)
                      for i in range(n)]).astype(np.float64, copy=False)
        return lam2, _normalise_columns(C, pseudocount, empty), ll

    evals = 0
    prev = -np.inf
    delta = np.inf
    accepted = 0
    converged = False
    while evals < max_iter:
        lam_n, Q_n, ll0, used, acc = squarem_cycle(em, lam, Q)
        evals += used
        if trace is not None:
            trace.append(ll0)
        delta = ll0 - prev
        if delta < tol:
            converged = True
            break
        prev = ll0
        accepted += int(acc)
        lam, Q = lam_n, Q_n
    P = lag_probs(Q)
    ll = float(np.sum(w * np.log(np.maximum(P @ lam, _LOG_FLOOR)))) / N
    return Q, lam, {"iterations": evals, "tolerance": tol, "accelerated_steps": accepted,
                                "last_increase_avg_loglik": float(delta), "avg_loglik": ll,
                                "converged": converged, "method": "EM + SQUAREM (S3)"}
