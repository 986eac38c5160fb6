"""
Compare the PMP with the QP
===========================

Compare the PMP with the discretised QP on one scenario and read the verdicts.

Run: ``python examples/compare_pmp_qp.py``
"""

from __future__ import annotations

import json

import iamp


def main() -> iamp.Comparison:
    problem = iamp.load_scenario("paper-1-poly")
    comparison = iamp.compare(problem, steps=(50,), solvers=("clarabel",), holds=("foh", "zoh"), repeats=1)
    (one,) = comparison.scenarios
    for run in one.runs:
        print(f"{run.label:24s} {run.result.status:8s} J = {run.result.cost:.6f}")
    for pair in one.agreement:
        print(f"{pair['a']} vs {pair['b']}: {pair['verdict']} (cost gap {pair['cost_rel_gap']:.2e})")
    print("all agree:", comparison.all_agree)
    print(json.dumps(comparison.to_json())[:200] + " ...")  # the `iamp compare --json` object
    return comparison


if __name__ == "__main__":
    main()
