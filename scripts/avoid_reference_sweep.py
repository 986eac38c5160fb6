"""Sweep ``qp-avoid`` (``safety="continuous"``) against the independent reference of
``tests/avoid_reference.py``: per generated problem (1-3 vehicles, N in {20, 30, 50}, FOH/ZOH,
with and without the passenger car's limits) the three backends' plans, the same call twice and a
fresh planner, the plans' dense safety, limits and cost, the reference at the plan's crossing times
and scanned over each vehicle's crossing time, and, for ``infeasible``, the reference's own box
search for a plan keeping every sampled half-plane by 5 cm.  One JSON line per problem.

usage: python scripts/avoid_reference_sweep.py START COUNT OUT.jsonl   (HARD=1: overtake variants)
       python scripts/avoid_reference_sweep.py summary OUT.jsonl ...      (the disagreements)
"""

import dataclasses
import json
import os
import sys
import time
import traceback
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
import iamp  # noqa: F401  (before numpy: the BLAS kernels iamp pins, iamp/_blas.py)

# isort: split
import numpy as np
from avoid_reference import Ref, cost_of, depth, feasible_search, integrate, limit_violation

from iamp.core.errors import IampError
from iamp.core.physical import PASSENGER_CAR
from iamp.planners import examples as ex
from iamp.planners import registry
from iamp.planners.avoid.check import crossing_orders

SOLVERS = ("clarabel", "osqp", "piqp")
HP = ("H_x", "H_y")
HARD = os.environ.get("HARD") == "1"


def case(i: int):
    rng = np.random.default_rng(1000 + i + (10**6 if HARD else 0))
    if HARD:
        return hard_case(rng)
    N = int(rng.choice([20, 30, 50]))
    hold = str(rng.choice(["foh", "zoh"]))
    lim = bool(rng.random() < 0.5)
    kind = rng.random()
    if kind < 0.5:
        m = int(rng.integers(1, 4))
        prob = ex.random_problem(int(rng.integers(0, 10**6)), m=m)
    elif kind < 0.9:
        prob = ex.overtake_problem(False) if rng.random() < 0.6 else ex.overtake_three_problem(False)
        e = prob.ego
        vs = list(prob.vehicles)
        vs[0] = dataclasses.replace(
            vs[0],
            x_poly=(vs[0].x_poly[0] + rng.uniform(-6, 6), vs[0].x_poly[1] + rng.uniform(-3, 3), rng.uniform(-0.3, 0.3)),
        )
        if len(vs) > 1:
            vs[1] = dataclasses.replace(vs[1], x_poly=(vs[1].x_poly[0] + rng.uniform(-6, 6), vs[1].x_poly[1]))
        prob = dataclasses.replace(
            prob,
            ego=dataclasses.replace(e, xf=e.xf + rng.uniform(-8, 8), vxf=e.vxf + rng.uniform(-3, 3)),
            vehicles=tuple(vs),
        )
    else:
        prob = ex.paper_problem(int(rng.integers(1, 4)))
        prob = prob.with_limits(None)
    limits = PASSENGER_CAR if hold == "foh" else dataclasses.replace(PASSENGER_CAR, jerk=None)
    prob = prob.with_limits(limits if lim else None)
    return prob, N, hold, lim


def hard_case(rng):
    N = int(rng.choice([20, 30, 50]))
    hold = str(rng.choice(["foh", "zoh"]))
    lim = bool(rng.random() < 0.6)
    prob = ex.overtake_three_problem(False)
    e = prob.ego
    vs = list(prob.vehicles)
    vs[0] = dataclasses.replace(
        vs[0],
        x_poly=(vs[0].x_poly[0] + rng.uniform(-8, 8), vs[0].x_poly[1] + rng.uniform(-4, 4), rng.uniform(-0.4, 0.4)),
    )
    vs[1] = dataclasses.replace(
        vs[1], x_poly=(vs[1].x_poly[0] + rng.uniform(-10, 10), vs[1].x_poly[1] + rng.uniform(-4, 4))
    )
    vs[2] = dataclasses.replace(
        vs[2], x_poly=(vs[2].x_poly[0] + rng.uniform(-10, 10), vs[2].x_poly[1] + rng.uniform(-4, 4))
    )
    m = int(rng.integers(1, 4))
    keep = [vs[0], vs[1], vs[2]][:m] if rng.random() < 0.7 else [vs[1], vs[0], vs[2]][:m]
    prob = dataclasses.replace(
        prob,
        ego=dataclasses.replace(
            e, xf=e.xf + rng.uniform(-10, 10), vxf=e.vxf + rng.uniform(-4, 4), tf=e.tf + rng.uniform(-0.5, 1.0)
        ),
        vehicles=tuple(keep),
    )
    limits = PASSENGER_CAR if hold == "foh" else dataclasses.replace(PASSENGER_CAR, jerk=None)
    return prob.with_limits(limits if lim else None), N, hold, lim


def orders_of(plan):
    return [(HP.index(v["first"]), HP.index(v["second"])) for v in plan.info["avoidance"]["vehicles"]]


def run(i: int) -> dict:
    prob, N, hold, lim = case(i)
    rec = {"i": i, "name": prob.name, "N": N, "hold": hold, "limits": lim, "m": len(prob.vehicles)}
    plans = {}
    for s in SOLVERS:
        pl = registry.make_planner("qp-avoid", steps=N, hold=hold, solver=s, safety="continuous")
        try:
            plans[s] = pl.plan(prob)
        except IampError as exc:
            rec["error"] = f"{type(exc).__name__}: {exc}"
            return rec
        if s == "clarabel":
            again = pl.plan(prob)
            fresh = registry.make_planner("qp-avoid", steps=N, hold=hold, solver=s, safety="continuous").plan(prob)
            same = []
            for q in (again, fresh):
                same.append(
                    q.status == plans[s].status
                    and q.cost == plans[s].cost
                    and (q.trajectory is None) == (plans[s].trajectory is None)
                    and (
                        q.trajectory is None
                        or (
                            np.array_equal(q.trajectory.X, plans[s].trajectory.X)
                            and np.array_equal(q.trajectory.U, plans[s].trajectory.U)
                        )
                    )
                )
            rec["repeat_same"], rec["fresh_same"] = same
    rec["status"] = {s: p.status for s, p in plans.items()}
    rec["cost"] = {s: p.cost for s, p in plans.items()}
    rec["solves"] = {s: p.info.get("n_solves") for s, p in plans.items()}
    c0 = plans["clarabel"]
    costs = [p.cost for p in plans.values() if p.cost is not None]
    rec["backends_agree"] = len({p.status for p in plans.values()}) == 1 and (
        not costs or (len(costs) == 3 and max(costs) - min(costs) <= 1e-6 * max(1.0, abs(min(costs))))
    )
    # the reference
    R = Ref(prob, N, hold, lim)
    h = prob.tf / N
    checks = {}
    t = np.linspace(0.0, prob.tf, 50 * N + 1)
    for s, p in plans.items():
        if p.trajectory is None or p.status not in ("optimal", "local"):
            continue
        U = np.asarray(p.trajectory.U)
        X = integrate(prob, U, N, hold, t)
        Xn = integrate(prob, U, N, hold, np.asarray(p.trajectory.t_nodes))
        end = np.abs(X[-1] - [prob.ego.xf, prob.ego.vxf, prob.ego.yf, prob.ego.vyf]).max()
        k = np.minimum(np.floor(t / h).astype(int), N - 1)
        r = (t - k * h) / h
        Ut = U[k] * (1 - r)[:, None] + U[np.minimum(k + 1, len(U) - 1)] * r[:, None] if hold == "foh" else U[k]
        du = np.diff(U, axis=0) / h if hold == "foh" else None
        checks[s] = {
            "depth": depth(prob, t, X),
            "end": float(end),
            "nodes": float(np.abs(Xn - p.trajectory.X).max()),
            "limviol": limit_violation(prob, t, X, Ut, du),
            "cost_err": abs(cost_of(U, h, hold) - p.cost) / max(1.0, p.cost),
        }
    rec["checks"] = checks
    if c0.status in ("optimal", "local"):
        orders = orders_of(c0)
        taus = list(map(float, c0.contact_times))
        at, _, _ = R.solve(orders, taus)
        rec["ref_at_tau"] = at
        # coordinate scans, each vehicle over both orders it may take
        all_orders, _ = crossing_orders(prob)
        best = (at, taus, orders)
        grid = np.unique(
            np.concatenate(
                [
                    np.linspace(0, prob.tf, 41),
                    np.clip(np.array(taus)[:, None] + h * np.arange(-4, 5)[None, :] / 2, 0, prob.tf).ravel(),
                ]
            )
        )
        for iv in range(len(prob.vehicles)):
            for o in all_orders[iv]:
                for tv in grid:
                    tt = list(taus)
                    tt[iv] = float(tv)
                    oo = list(orders)
                    oo[iv] = o
                    c, _, _ = R.solve(oo, tt)
                    if c < best[0]:
                        best = (c, tt, oo)
        rec["ref_best"] = best[0]
        rec["ref_best_tau"] = best[1]
        rec["ref_best_orders"] = best[2]
    elif c0.status == "infeasible":
        rec["reason"] = c0.info.get("reason")
        all_orders, why = crossing_orders(prob)
        if not why:
            feas, n, exhausted = feasible_search(R, all_orders, margin=0.05)
            rec["ref_feasible_margin5cm"] = feas
            rec["ref_feas_solves"], rec["ref_feas_exhausted"] = n, exhausted
    return rec


def summary(files: list[str]) -> None:
    """Print the disagreements of the sweep's JSON lines."""
    import statistics
    from collections import Counter

    recs = [json.loads(line) for f in files for line in open(f)]
    print("records", len(recs))
    print(
        Counter(
            tuple(sorted(set(r.get("status", {}).values())))
            if "status" in r
            else ("error" if "error" in r else "crash")
            for r in recs
        )
    )
    for r in recs:
        flags = []
        if "crash" in r:
            flags.append("crash")
        if "error" in r:
            flags.append("error:" + r["error"][:100])
        if r.get("repeat_same") is False or r.get("fresh_same") is False:
            flags.append("nondeterministic")
        if "status" in r and not r.get("backends_agree"):
            flags.append("backends")
        for s, c in r.get("checks", {}).items():
            if c["depth"] > 1e-7:
                flags.append(f"{s}:intrudes {c['depth']:.2e}")
            if c["limviol"] > 1e-7:
                flags.append(f"{s}:limits {c['limviol']:.2e}")
            if c["end"] > 1e-6 or c["nodes"] > 1e-6:
                flags.append(f"{s}:integration {c['end']:.1e} {c['nodes']:.1e}")
            if c["cost_err"] > 1e-9:
                flags.append(f"{s}:cost {c['cost_err']:.1e}")
        if r.get("ref_at_tau") is not None:
            J = r["cost"]["clarabel"]
            at = r["ref_at_tau"]
            best = r["ref_best"]
            cons = J - at
            if at > J + 1e-7 * max(1, J):
                flags.append(f"ref@tau above plan {at - J:.2e}")
            if J - best > 1e-4 * max(1, J) + 2 * max(cons, 0) + 1e-7:
                flags.append(
                    f"global? J-best={J - best:.3e} cons={cons:.2e} tau*={r['ref_best_tau']} o={r['ref_best_orders']}"
                )
        if r.get("ref_feasible_margin5cm"):
            flags.append(f"infeasible but ref feasible {r['ref_feasible_margin5cm']} reason={r.get('reason')}")
        if flags:
            print(
                r["i"], r.get("name"), r.get("N"), r.get("hold"), r.get("limits"), r.get("status"), r.get("cost"), flags
            )
    print("cpu median", statistics.median(r["cpu"] for r in recs))


if __name__ == "__main__":
    if sys.argv[1] == "summary":  # python scripts/avoid_reference_sweep.py summary OUT.jsonl ...
        summary(sys.argv[2:])
        sys.exit(0)
    start, count, out = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3]
    with open(out, "a") as f:
        for i in range(start, start + count):
            t0 = time.process_time()
            try:
                rec = run(i)
            except Exception:
                rec = {"i": i, "crash": traceback.format_exc()}
            rec["cpu"] = time.process_time() - t0
            f.write(json.dumps(rec, default=float) + "\n")
            f.flush()
