"""An independent reference for the continuous-time avoidance QP (no iamp planner code: the
dynamics, cost, half-planes and limits are derived here from the problem's fields and solved by
Clarabel directly), shared by ``tests/test_avoid_reference.py``.

Double integrator per axis, nodal s, v and inputs (FOH: N+1 linear pieces, ZOH: N constants),
cost 1/2 int |u|^2 exactly.  Safety: vehicle i's first half-plane at every sample t <= tau_i,
the second at every sample t >= tau_i, both at tau_i (a sampled relaxation of the continuous
constraint).  Limits exactly (friction circle as an SOC at the input nodes, speed and lateral
position at the samples, jerk per axis for FOH).  Solved by Clarabel directly.
"""

from __future__ import annotations

import itertools

import clarabel
import numpy as np
import scipy.sparse as sp


def sigma_c(v, axis: str, t):
    """sigma, c(t) of the half-plane sigma*s <= c(t) (own derivation from the corner)."""
    t = np.asarray(t, float)
    if axis == "x":
        ax = v.length / 2 + v.safety_x
        xs = np.polynomial.polynomial.polyval(t, np.asarray(v.x_poly, float))
        if v.corner.startswith("front"):  # ego in front: s_x >= xs + ax
            return -1.0, -(xs + ax)
        return 1.0, xs - ax               # ego behind: s_x <= xs - ax
    ay = v.width / 2 + v.safety_y
    if v.corner.endswith("lower"):        # ego below: s_y <= y - ay
        return 1.0, np.full(t.shape, v.y - ay)
    return -1.0, np.full(t.shape, -(v.y + ay))


class Ref:
    def __init__(self, problem, N: int, hold: str, limits: bool, spp: int = 20):
        self.p, self.N, self.hold, self.spp = problem, N, hold, spp
        self.lim = problem.limits if limits else None
        T = problem.tf
        self.h = T / N
        self.nu = N + 1 if hold == "foh" else N
        n1 = N + 1
        # layout per axis: s (N+1), v (N+1), u (nu)
        self.na = 2 * n1 + self.nu
        self.nz = 2 * self.na
        self.ts = np.unique(np.concatenate([np.linspace(k * self.h, (k + 1) * self.h, spp + 1) for k in range(N)]))
        self.ts[-1] = T
        self._build_base()
        self.S = [np.array([self.row(a, "s", t) for t in self.ts]) for a in (0, 1)]

    def idx(self, a: int, kind: str, k: int) -> int:
        n1 = self.N + 1
        off = a * self.na
        return off + {"s": 0, "v": n1, "u": 2 * n1}[kind] + k

    def row(self, a: int, what: str, t: float, k: int | None = None) -> np.ndarray:
        """Coefficients of s_a(t) or v_a(t) (what = 's'|'v') in z, on piece ``k`` (default: the
        piece holding ``t``)."""
        N, h = self.N, self.h
        if k is None:
            k = min(int(np.floor(t / h)), N - 1)
        r = t - k * h
        out = np.zeros(self.nz)
        if what == "s":
            out[self.idx(a, "s", k)] = 1.0
            out[self.idx(a, "v", k)] = r
            if self.hold == "foh":
                out[self.idx(a, "u", k)] += r**2 / 2 - r**3 / (6 * h)
                out[self.idx(a, "u", k + 1)] += r**3 / (6 * h)
            else:
                out[self.idx(a, "u", k)] += r**2 / 2
        else:
            out[self.idx(a, "v", k)] = 1.0
            if self.hold == "foh":
                out[self.idx(a, "u", k)] += r - r**2 / (2 * h)
                out[self.idx(a, "u", k + 1)] += r**2 / (2 * h)
            else:
                out[self.idx(a, "u", k)] += r
        return out

    def _build_base(self):
        N, h, e = self.N, self.h, self.p.ego
        # cost
        P = sp.lil_matrix((self.nz, self.nz))
        for a in (0, 1):
            for k in range(N):
                if self.hold == "foh":
                    i, j = self.idx(a, "u", k), self.idx(a, "u", k + 1)
                    # 1/2 * h/3 (ui^2 + ui uj + uj^2) = 1/2 z^T P z with P
                    P[i, i] += 2 * h / 6
                    P[j, j] += 2 * h / 6
                    P[i, j] += h / 6
                    P[j, i] += h / 6
                else:
                    i = self.idx(a, "u", k)
                    P[i, i] += h
        self.P = sp.csc_matrix(P)
        # equalities: dynamics at t_{k+1} and the boundary
        eqA, eqb = [], []
        for a in (0, 1):
            for k in range(N):
                for what in ("s", "v"):
                    r = self._end_row(a, what, k)
                    r = r.copy()
                    r[self.idx(a, what, k + 1)] -= 1.0
                    eqA.append(r)
                    eqb.append(0.0)
        bc = [(0, "s", 0, e.x0), (0, "v", 0, e.vx0), (0, "s", N, e.xf), (0, "v", N, e.vxf),
              (1, "s", 0, e.y0), (1, "v", 0, e.vy0), (1, "s", N, e.yf), (1, "v", N, e.vyf)]
        for a, what, k, val in bc:
            r = np.zeros(self.nz)
            r[self.idx(a, what, k)] = 1.0
            eqA.append(r)
            eqb.append(val)
        self.eqA, self.eqb = np.array(eqA), np.array(eqb)
        # limits (exact, sampled where they are not convex combinations of nodes)
        G, g, soc = [], [], []
        L = self.lim
        if L is not None:
            for a, name in ((0, "ax"), (1, "ay")):
                rng = getattr(L, name)
                if rng is not None:
                    for k in range(self.nu):
                        r = np.zeros(self.nz)
                        r[self.idx(a, "u", k)] = 1.0
                        G += [r, -r]
                        g += [rng[1], -rng[0]]
            if L.vx is not None:
                for t in self.ts:
                    r = self.row(0, "v", t)
                    G += [r, -r]
                    g += [L.vx[1], -L.vx[0]]
            if L.y is not None:
                for t in self.ts:
                    r = self.row(1, "s", t)
                    G += [r, -r]
                    g += [L.y[1], -L.y[0]]
            if L.jerk is not None and self.hold == "foh":
                for a in (0, 1):
                    for k in range(N):
                        r = np.zeros(self.nz)
                        r[self.idx(a, "u", k + 1)] = 1.0
                        r[self.idx(a, "u", k)] = -1.0
                        G += [r, -r]
                        g += [L.jerk * h, L.jerk * h]
            if L.a_total is not None:
                for k in range(self.nu):
                    soc.append(k)
        self.limG = np.array(G).reshape(-1, self.nz)
        self.limg = np.array(g)
        self.soc = soc

    def _end_row(self, a, what, k):
        # row at the end of piece k (t = (k + 1) h: the last piece's end is t = T exactly)
        return self.row(a, what, (k + 1) * self.h, k)

    def safety_rows(self, orders, taus, margin: float = 0.0, box=None):
        """Rows sigma*s(t) <= c(t) - margin.  ``box``: per vehicle (lo, hi) to relax over a box
        (first half-plane on t <= lo, second on t >= hi): a lower bound over the box."""
        G, g = [], []
        for i, (v, (f, s)) in enumerate(zip(self.p.vehicles, orders)):
            lo, hi = (taus[i], taus[i]) if box is None else box[i]
            for axis_i, mask in ((f, self.ts <= lo + 1e-12), (s, self.ts >= hi - 1e-12)):
                axis = "xy"[axis_i]
                sg, c = sigma_c(v, axis, self.ts[mask])
                G.append(sg * self.S[axis_i][mask])
                g.append(c - margin)
                if box is None:
                    sg, c = sigma_c(v, axis, taus[i])
                    G.append(sg * self.row(axis_i, "s", min(taus[i], self.p.tf))[None, :])
                    g.append(np.atleast_1d(c) - margin)
        return np.vstack(G), np.concatenate(g)

    def solve(self, orders, taus, margin: float = 0.0, box=None):
        G1, g1 = self.safety_rows(orders, taus, margin, box)
        G = np.vstack([G1, self.limG]) if self.limG.size else G1
        g = np.concatenate([g1, self.limg])
        blocks = [self.eqA, G]
        b = [self.eqb, g]
        cones = [clarabel.ZeroConeT(len(self.eqb)), clarabel.NonnegativeConeT(len(g))]
        if self.soc:
            A_total = self.lim.a_total
            for k in self.soc:
                r = np.zeros((3, self.nz))
                r[1, self.idx(0, "u", k)] = -1.0
                r[2, self.idx(1, "u", k)] = -1.0
                blocks.append(r)
                b.append(np.array([A_total, 0.0, 0.0]))
                cones.append(clarabel.SecondOrderConeT(3))
        A = sp.csc_matrix(np.vstack(blocks))
        settings = clarabel.DefaultSettings()
        settings.verbose = False
        settings.tol_gap_abs = 1e-10
        settings.tol_gap_rel = 1e-10
        settings.tol_feas = 1e-10
        solver = clarabel.DefaultSolver(sp.triu(self.P).tocsc(), np.zeros(self.nz), A, np.concatenate(b), cones,
                                        settings)
        sol = solver.solve()
        st = str(sol.status)
        if st in ("Solved", "AlmostSolved"):
            return float(sol.obj_val), np.array(sol.x), st
        return np.inf, None, st


def cost_of(U: np.ndarray, h: float, hold: str) -> float:
    """1/2 int |u|^2 of nodal inputs (FOH linear, ZOH constant)."""
    U = np.asarray(U, float)
    if hold == "foh":
        a, b = U[:-1], U[1:]
        return float(0.5 * np.sum(h / 3 * (a * a + a * b + b * b)))
    return float(0.5 * np.sum(h * U[: len(U)] ** 2))


def integrate(problem, U: np.ndarray, N: int, hold: str, t: np.ndarray) -> np.ndarray:
    """States (s_x, v_x, s_y, v_y) at times t from the boundary's start and the nodal inputs."""
    e, h = problem.ego, problem.tf / N
    U = np.asarray(U, float)
    out = np.zeros((len(t), 4))
    for a, (s0, v0) in enumerate(((e.x0, e.vx0), (e.y0, e.vy0))):
        s, v = [s0], [v0]
        for k in range(N):
            uk = U[k, a]
            uk1 = U[k + 1, a] if hold == "foh" else uk
            v.append(v[-1] + h * (uk + uk1) / 2)
            s.append(s[-1] + h * v[-2] + h * h * (2 * uk + uk1) / 6)
        s, v = np.array(s), np.array(v)
        k = np.minimum(np.floor(t / h).astype(int), N - 1)
        r = t - k * h
        uk = U[k, a]
        uk1 = U[np.minimum(k + 1, len(U) - 1), a] if hold == "foh" else uk
        out[:, 2 * a] = s[k] + v[k] * r + uk * r**2 / 2 + (uk1 - uk) * r**3 / (6 * h)
        out[:, 2 * a + 1] = v[k] + uk * r + (uk1 - uk) * r**2 / (2 * h)
    return out


def depth(problem, t: np.ndarray, X: np.ndarray) -> float:
    """Largest depth of the ego point inside any safety rectangle (> 0: inside)."""
    worst = -np.inf
    for v in problem.vehicles:
        xs = np.polynomial.polynomial.polyval(t, np.asarray(v.x_poly, float))
        d = np.minimum(v.length / 2 + v.safety_x - np.abs(X[:, 0] - xs),
                       v.width / 2 + v.safety_y - np.abs(X[:, 2] - v.y))
        worst = max(worst, float(d.max()))
    return worst


def limit_violation(problem, t, X, U_t, du=None) -> float:
    L = problem.limits
    if L is None:
        return 0.0
    worst = 0.0
    if L.ax is not None:
        worst = max(worst, float(np.max(U_t[:, 0] - L.ax[1])), float(np.max(L.ax[0] - U_t[:, 0])))
    if L.ay is not None:
        worst = max(worst, float(np.max(U_t[:, 1] - L.ay[1])), float(np.max(L.ay[0] - U_t[:, 1])))
    if L.a_total is not None:
        worst = max(worst, float(np.max(np.hypot(U_t[:, 0], U_t[:, 1]) - L.a_total)))
    if L.vx is not None:
        worst = max(worst, float(np.max(X[:, 1] - L.vx[1])), float(np.max(L.vx[0] - X[:, 1])))
    if L.y is not None:
        worst = max(worst, float(np.max(X[:, 2] - L.y[1])), float(np.max(L.y[0] - X[:, 2])))
    if L.jerk is not None and du is not None:
        worst = max(worst, float(np.max(np.abs(du) - L.jerk)))
    return worst


def feasible_search(R: Ref, orders_all, margin: float = 0.05, max_solves: int = 600, min_width: float | None = None):
    """Branch over crossing-time boxes for a plan of the sampled problem with every safety row
    tightened by ``margin``: a box whose relaxation (rows outside the box only) is infeasible is
    pruned; a narrow box is tried at its midpoint.  Returns (cost, taus, orders) or None, and
    the number of solves; ``exhausted`` if the budget ran out."""
    T = R.p.tf
    min_width = min_width or R.h / 4
    solves = 0
    for orders in itertools.product(*orders_all):
        stack = [[(0.0, T)] * len(orders)]
        while stack:
            box = stack.pop()
            if solves >= max_solves:
                return None, solves, True
            c, _, _ = R.solve(list(orders), [0.5 * (a + b) for a, b in box], margin, box=box)
            solves += 1
            if not np.isfinite(c):
                continue
            widths = [b - a for a, b in box]
            if max(widths) <= min_width:
                taus = [0.5 * (a + b) for a, b in box]
                c2, _, _ = R.solve(list(orders), taus, margin)
                solves += 1
                if np.isfinite(c2):
                    return (c2, taus, list(orders)), solves, False
                continue
            i = int(np.argmax(widths))
            a, b = box[i]
            for half in ((a, 0.5 * (a + b)), (0.5 * (a + b), b)):
                nb = list(box)
                nb[i] = half
                stack.append(nb)
    return None, solves, False
