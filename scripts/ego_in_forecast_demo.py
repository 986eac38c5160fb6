"""The ego in the forecast on one merge, offline: plan <-> the target-lane follower's reaction.

The scenario (written by this script to OUT.toml): the target-lane follower sv1 at x = -15 m and
18 m/s behind sv2 at x = 10 m and 12 m/s, both given by 3-s histories; the ego at x = 0, 20 m/s
changes into their lane (tf = 5 s, the paper's PMP planner).  Printed: the follower's cubic from the
MTD, from the leader-aware predictor (sv2 as its leader), and iterated with the ego's plan as its
leader (iamp.prediction.leader.ego), with the plans' status, cost and contact times.

Usage: ``python scripts/ego_in_forecast_demo.py [--iterations N]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
from pathlib import Path

import iamp  # noqa: F401  (before numpy: the BLAS kernels iamp pins, iamp/_blas.py)

# isort: split
import numpy as np

from iamp.core.scenario import load_scenario
from iamp.planners.pmp import PMPPlanner
from iamp.prediction.leader.ego import follower_poly_for_plan, iterate_with_planner
from iamp.prediction.leader.model import LeaderPredictor, default_leader_model, predict_scenario
from iamp.prediction.resolve import problem_from_scenario

P = np.polynomial.polynomial


def scenario_text() -> str:
    t = np.round(np.linspace(-3.0, 0.0, 31), 4)
    veh = []
    for name, corner, x0, v in (("sv1", "front-lower", -15.0, 18.0), ("sv2", "rear-lower", 10.0, 12.0)):
        xs = ", ".join(f"{z:.4f}" for z in x0 + v * t)
        ts = ", ".join(f"{z:.4f}" for z in t)
        veh.append(f'[[vehicles]]\nname = "{name}"\ncorner = "{corner}"\ny = 3.75\nlength = 4.8\nwidth = 1.8\n'
                   f"safety_x = 5.0\nsafety_y = 0.5\n\n[vehicles.history]\nt = [{ts}]\nx = [{xs}]\n")
    return ('name = "merge-platoon"\n\n[ego]\ntf = 5.0\nx0 = 0.0\ny0 = -2.0\nvx0 = 20.0\nvy0 = 0.0\n'
            "xf = 85.0\nyf = 3.75\nvxf = 20.0\nvyf = 0.0\n\n" + "\n".join(veh))


def describe(label: str, poly: tuple[float, ...]) -> str:
    tt = np.linspace(0.0, 5.0, 51)
    acc = P.polyval(tt, P.polyder(poly, 2))
    return f"{label:34s} x(5) = {P.polyval(5.0, poly):6.1f} m, min acceleration {acc.min():+.2f} m/s^2"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--iterations", type=int, default=6)
    a = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "merge-platoon.toml"
        path.write_text(scenario_text())
        sc = load_scenario(str(path))
    _, prob, _ = problem_from_scenario(sc)
    lp = LeaderPredictor(default_leader_model())
    planner = PMPPlanner()
    f, lead = sc.vehicles[0], sc.vehicles[1]

    def plan_fn(poly: tuple[float, ...]) -> tuple[object, object]:
        vs = list(prob.vehicles)
        vs[0] = dataclasses.replace(vs[0], x_poly=tuple(poly))
        p2 = prob.with_vehicles(vs)
        return planner.plan(p2), p2

    def predict_fn(plan: object, p2: object) -> tuple[float, ...]:
        return follower_poly_for_plan(lp, (f.history.t, f.history.x), plan.trajectory.states,  # a Plan
                                      5.0, target_y=3.75, ego_length=4.8, ego_width=1.8, follower_length=4.8,
                                      leader_hist=(lead.history.t, lead.history.x), leader_length=4.8)

    mtd = tuple(prob.vehicles[0].x_poly)
    aware = predict_scenario(lp, sc.vehicles, 5.0)[0][0]
    print(describe("follower, MTD:", mtd))
    print(describe("follower, leader-aware (sv2):", aware))
    for label, poly in (("plan against the MTD follower", mtd), ("plan against the leader-aware one", aware)):
        p = plan_fn(poly)[0]
        print(f"{label}: {p.status}, cost {p.cost:.1f}, contact times {np.round(p.contact_times, 2).tolist()}")
    res = iterate_with_planner(plan_fn, predict_fn, aware, max_iter=a.iterations, tol_m=0.1, tf=5.0)
    p = res["plan"][0]
    print(describe("follower, reacting to the plan:", res["x_poly"]))
    print(f"{res['iterations']} predictions against {res['iterations']} plans, converged {res['converged']}, "
          "residuals [m] " + " ".join(f"{c:.2f}" for c in res["changes_m"]))
    print(f"plan with the ego in the forecast: {p.status}, cost {p.cost:.1f}, "
          f"contact times {np.round(p.contact_times, 2).tolist()}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
