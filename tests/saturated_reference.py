"""The saturated axis solve as it was before the scalar kernel (commit 46fdb28): the
reference of tests/test_bounded_speed.py, which asserts that the kernel returns the same
numbers bit for bit.  Copied verbatim (the Newton loop, ``_solve``, ``_Axis.pieces`` and
``_Axis.evaluate``); only the return is new: ``(converged, lam, F, D, res, it, pieces)``."""

from __future__ import annotations

import math
from typing import Any

from iamp.planners.pmp.saturated import MAX_NEWTON, _Axis


def _solve(A: list[list[float]], r: list[float]) -> list[float] | None:
    """Gaussian elimination with partial pivoting (small dense systems); None if singular."""
    n = len(r)
    M = [row[:] + [r[i]] for i, row in enumerate(A)]
    for c in range(n):
        p = max(range(c, n), key=lambda i: abs(M[i][c]))
        if M[p][c] == 0.0:
            return None
        if p != c:
            M[c], M[p] = M[p], M[c]
        pc = M[c]
        inv = 1.0 / pc[c]
        for i in range(c + 1, n):
            f = M[i][c] * inv
            if f != 0.0:
                row = M[i]
                for j in range(c, n + 1):
                    row[j] -= f * pc[j]
    x = [0.0] * n
    for i in range(n - 1, -1, -1):
        acc = M[i][n]
        for j in range(i + 1, n):
            acc -= M[i][j] * x[j]
        x[i] = acc / M[i][i]
    return x


class _RefAxis(_Axis):
    def g(self, tau: float) -> list[float]:
        """``g̃(τ)``: ramps ``(σ_i − τ)_+``, then ``1 − τ`` and ``1``."""
        return [max(s - tau, 0.0) for s in self.sig] + [1.0 - tau, 1.0]

    def pieces(self, lam: list[float]) -> list[tuple[float, float, float, float, int]]:
        """Sub-pieces ``(τa, τb, wa, wb, kind)`` with kind 0 free, −1 lower, +1 upper."""
        out: list[tuple[float, float, float, float, int]] = []
        lo, hi = self.lo, self.hi
        base = self.base
        wvals = [sum(lk * gk for lk, gk in zip(lam, self.g(tau))) for tau in base]
        for j in range(len(base) - 1):
            ta, tb, wa, wb = base[j], base[j + 1], wvals[j], wvals[j + 1]
            cuts = [ta]
            for bnd in (lo, hi):
                if (wa - bnd) * (wb - bnd) < 0.0:
                    cuts.append(ta + (tb - ta) * (bnd - wa) / (wb - wa))
            cuts.sort()
            cuts.append(tb)
            for k in range(len(cuts) - 1):
                a, b = cuts[k], cuts[k + 1]
                if b <= a:
                    continue
                fa = wa + (wb - wa) * (a - ta) / (tb - ta)
                fb = wa + (wb - wa) * (b - ta) / (tb - ta)
                mid = 0.5 * (fa + fb)
                kind = -1 if mid <= lo else (1 if mid >= hi else 0)
                out.append((a, b, fa, fb, kind))
        return out

    def clip(self, w: float) -> float:
        return self.lo if w < self.lo else (self.hi if w > self.hi else w)

    def evaluate(self, lam: list[float], hessian: bool
                 ) -> tuple[list[float], float, list[list[float]], list[tuple[float, float, float, float, int]]]:
        """``(F, D, G_free, pieces)``: residuals ``∫g u − d̃``, dual value, free Gram matrix."""
        n = self.n
        F = [-x for x in self.d]
        D = sum(lk * dk for lk, dk in zip(lam, self.d))
        G = [[0.0] * n for _ in range(n)] if hessian else []
        ps = self.pieces(lam)
        for a, b, wa, wb, kind in ps:
            h = b - a
            ua, ub = (wa, wb) if kind == 0 else ((self.lo, self.lo) if kind < 0 else (self.hi, self.hi))
            ga, gb = self.g(a), self.g(b)
            # ∫ (½u² − wu) for linear u, w (Simpson, exact)
            um = 0.5 * (ua + ub)
            wm = 0.5 * (wa + wb)
            D += h / 6 * ((0.5 * ua * ua - wa * ua) + 4 * (0.5 * um * um - wm * um) + (0.5 * ub * ub - wb * ub))
            for k in range(n):
                F[k] += h / 6 * (2 * ga[k] * ua + ga[k] * ub + gb[k] * ua + 2 * gb[k] * ub)
            if hessian and kind == 0:
                for k in range(n):
                    for l in range(k, n):
                        v = h / 6 * (2 * ga[k] * ga[l] + ga[k] * gb[l] + gb[k] * ga[l] + 2 * gb[k] * gb[l])
                        G[k][l] += v
                        if l != k:
                            G[l][k] += v
        return F, D, G, ps



def reference_newton(times: list[float], T: float, s0: float, v0: float, sf: float, vf: float,
                     corners: list[float], lo: float, hi: float, lam0: list[float] | None = None,
                     tol_residual: float = 1e-12) -> Any:
    ax = _RefAxis(times, T, s0, v0, sf, vf, corners, lo, hi)
    n = ax.n
    if lam0 is None:
        # unbounded optimum: the full Gram system ∫ g gᵀ λ = d̃ (closed form per piece)
        G = [[0.0] * n for _ in range(n)]
        for j in range(len(ax.base) - 1):
            a, b = ax.base[j], ax.base[j + 1]
            ga, gb = ax.g(a), ax.g(b)
            h = b - a
            for k in range(n):
                for l in range(n):
                    G[k][l] += h / 6 * (2 * ga[k] * ga[l] + ga[k] * gb[l] + gb[k] * ga[l] + 2 * gb[k] * gb[l])
        lam_opt = _solve(G, ax.d)
        if lam_opt is None:
            return None
        lam = lam_opt
    else:
        lam = list(lam0)
    F, D, G, ps = ax.evaluate(lam, True)
    it = 0
    res = max(abs(x) for x in F)
    while res > tol_residual:
        if it >= MAX_NEWTON:
            break
        it += 1
        trace = sum(G[k][k] for k in range(n))
        reg = 1e-14 * max(trace, 1e-300)
        A = [[G[k][l] + (reg if k == l else 0.0) for l in range(n)] for k in range(n)]
        step = _solve(A, [-x for x in F])
        if step is None or not all(math.isfinite(x) for x in step):
            step = [-x for x in F]  # gradient ascent direction of D
        slope = -sum(s * f for s, f in zip(step, F))  # ∇Dᵀ step = −Fᵀ step  (> 0)
        alpha = 1.0
        accepted = False
        for _ in range(40):
            trial = [lk + alpha * sk for lk, sk in zip(lam, step)]
            F2, D2, G2, ps2 = ax.evaluate(trial, True)
            res2 = max(abs(x) for x in F2)
            if D2 >= D + 1e-4 * alpha * slope or res2 <= tol_residual:
                accepted = True
                break
            alpha *= 0.5
        if not accepted:
            break
        lam, F, D, G, ps, res = trial, F2, D2, G2, ps2, res2
        norm = max(abs(x) for x in lam)
        if norm > 1e12:
            break
    return res <= tol_residual, lam, F, D, res, it, ps
