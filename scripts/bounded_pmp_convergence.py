"""The bounded FOH QP converges to the bounded PMP as N grows (docs/bounded-pmp.md).

    PYTHONPATH=. python scripts/bounded_pmp_convergence.py

Prints, for the paper's scenario 1 with a passenger car's input box (ax [-6, 3], ay [-2, 2]):
(a) the fixed contact time t = 3.35 s (a node of every grid): the bounded PMP cost and the
relative gap (J_QP(N) - J_PMP) / J_PMP of the bounded FOH QP (cvxpy + Clarabel, the reference
of tests/test_pmp_bounded.py) at N = 100, 200, 400, 800; (b) the free contact time: the
bounded PMP's J* against the QP's best node within +-4 nodes of t*.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from test_pmp_bounded import BOX, bounded_foh_qp

from iamp.api import load_scenario
from iamp.planners.pmp import PMPPlanner
from iamp.planners.pmp.bounded import solve_bounded_fixed


def main() -> None:
    problem = load_scenario("paper-1").with_limits(BOX)
    t = 3.35
    j_fixed = solve_bounded_fixed(problem, [t]).cost
    plan = PMPPlanner().plan(problem)
    t_star, j_star = float(plan.contact_times[0]), float(plan.cost)
    print(f"paper-1, box ax [-6, 3], ay [-2, 2]; fixed t = {t}: J_PMP = {j_fixed:.12g}; "
          f"free: t* = {t_star:.9f}, J* = {j_star:.12g} ({plan.status})")
    print("| N | gap at t = 3.35 (J_QP - J_PMP)/J_PMP | ratio | free: best node t | gap (min_k J_QP(k) - J*)/J* |")
    print("|---|---|---|---|---|")
    prev = None
    for steps in (100, 200, 400, 800):
        h = problem.tf / steps
        _status, j_qp = bounded_foh_qp(problem, [round(t / h)], steps)
        gap = (j_qp - j_fixed) / j_fixed if j_qp is not None else float("nan")
        k0 = round(t_star / h)
        best = min((bounded_foh_qp(problem, [k], steps)[1] or float("inf"), k) for k in range(k0 - 4, k0 + 5))
        ratio = f"{prev / gap:.2f}" if prev else ""
        prev = gap
        print(f"| {steps} | {gap:.3e} | {ratio} | {best[1] * h:.4f} | {(best[0] - j_star) / j_star:.3e} |")


if __name__ == "__main__":
    main()
