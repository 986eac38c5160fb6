"""Check `iamp plan --json` (PMP) against an independent solution on scenarios no test uses.

The independent solution shares no code with the planner: per axis, the fixed-time optimum
is scipy's clamped cubic spline through the interior points (the minimum of ½∫s''²), its
cost integrated by Gauss–Legendre; the contact time(s) come from a dense grid plus a scipy
polish (bounded Brent for one vehicle, Nelder–Mead for two); the jumps are the jumps of the
spline's third derivative (u̇ = p1, so Φ = −Δs'''), read off the spline.

For ``m >= 3`` the grid is coarser and the eight best grid points are polished.

Usage: python scripts/check_independent.py [--seeds 1000 2000] [--m 1]  (m = 1..4)
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import iamp  # noqa: F401  (before numpy: the BLAS kernels iamp pins, iamp/_blas.py)

# isort: split
import numpy as np
from scipy import interpolate, optimize

from iamp.planners.examples import random_problem


def spline_parts(problem, times):
    times = np.asarray(times, float)
    order = np.argsort(times)
    corners = problem.corners(times)[order]
    t = np.r_[0.0, times[order], problem.tf]
    ego = problem.ego
    out = []
    for axis, (s0, v0, sf, vf) in enumerate([(ego.x0, ego.vx0, ego.xf, ego.vxf), (ego.y0, ego.vy0, ego.yf, ego.vyf)]):
        out.append(interpolate.CubicSpline(t, np.r_[s0, corners[:, axis], sf], bc_type=((1, v0), (1, vf))))
    return t, order, out


def spline_cost(problem, times):
    t, _, splines = spline_parts(problem, times)
    xg, wg = np.polynomial.legendre.leggauss(4)
    total = 0.0
    for cs in splines:
        for a, b in zip(t[:-1], t[1:]):
            tt = (b - a) / 2 * xg + (a + b) / 2
            total += 0.5 * (b - a) / 2 * np.sum(wg * cs(tt, 2) ** 2)
    return total


def independent(problem):
    tf, m = problem.tf, problem.m
    if m == 1:
        g = np.linspace(0, tf, 4001)[1:-1]
        J = np.array([spline_cost(problem, [x]) for x in g])
        k = int(np.argmin(J))
        res = optimize.minimize_scalar(lambda x: spline_cost(problem, [x]),
                                       bounds=(g[max(k - 1, 0)], g[min(k + 1, len(g) - 1)]),
                                       method="bounded", options={"xatol": 1e-12})
        t = np.array([res.x])
    else:
        import itertools

        n = {2: 122, 3: 22, 4: 10}.get(m, 6)
        g = np.linspace(0, tf, n)[1:-1]
        cands = sorted((spline_cost(problem, list(c)), c) for c in itertools.product(g, repeat=m)
                       if len(set(np.round(c, 12))) == m)

        def f(x):
            xs = np.sort(x)
            ok = np.all(np.diff(xs) > 1e-9) and np.all((x > 0) & (x < tf))
            return spline_cost(problem, x) if ok else np.inf

        best = None
        for _, c in cands[: 1 if m == 2 else 8]:  # polish the best grid points
            res = optimize.minimize(f, np.array(c), method="Nelder-Mead",
                                    options={"xatol": 1e-12, "fatol": 1e-14, "maxiter": 20000})
            if best is None or res.fun < best.fun:
                best = res
        t = best.x
    _, order, splines = spline_parts(problem, t)
    jumps = np.empty((m, 2))
    for axis, cs in enumerate(splines):
        third = 6 * cs.c[0]  # s''' on each piece
        d = third[:-1] - third[1:]  # −Δs''' at each interior knot = Φ
        jumps[order, axis] = d
    return t, spline_cost(problem, t), jumps


def to_toml(problem) -> str:
    e = problem.ego
    lines = [f'name = "{problem.name}"', "[ego]"] + [f"{k} = {getattr(e, k)!r}" for k in
                                                    ("tf", "x0", "y0", "vx0", "vy0", "xf", "yf", "vxf", "vyf")]
    for v in problem.vehicles:
        lines += ["[[vehicles]]", f'name = "{v.name}"', f'corner = "{v.corner}"'] + [
            f"{k} = {getattr(v, k)!r}" for k in ("y", "length", "width", "safety_x", "safety_y")] + [
            f"x_poly = {list(v.x_poly)!r}"]
    return "\n".join(lines) + "\n"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, nargs=2, default=(5000, 5040))
    ap.add_argument("--m", type=int, default=1)
    args = ap.parse_args()
    worst = {"cost_rel": 0.0, "contact_time_abs": 0.0, "jump_rel": 0.0}
    n = 0
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(*args.seeds):
            problem = random_problem(seed, m=args.m)
            path = Path(tmp) / "s.toml"
            path.write_text(to_toml(problem))
            out = json.loads(subprocess.run([sys.executable, "-m", "iamp", "plan", str(path), "--json"],
                                            capture_output=True, text=True, check=True).stdout)
            t, cost, jumps = independent(problem)
            worst["cost_rel"] = max(worst["cost_rel"], abs(out["cost"] - cost) / abs(cost))
            dt = float(np.max(np.abs(np.array(out["contact_times"]) - t)))
            dj = float(np.max(np.abs(np.array(out["jumps"]) - jumps) / np.maximum(1, np.abs(jumps))))
            worst["contact_time_abs"] = max(worst["contact_time_abs"], dt)
            worst["jump_rel"] = max(worst["jump_rel"], dj)
            n += 1
    print(json.dumps({"scenarios": n, "vehicles": args.m, "seeds": list(args.seeds), "worst": worst}))


if __name__ == "__main__":
    main()
