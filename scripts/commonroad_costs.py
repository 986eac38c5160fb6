"""CommonRoad's own cost evaluator on solution files, for cross-checking :mod:`iamp.commonroad.costs`.

The drivability checker's ``CostFunctionEvaluator`` (``commonroad_dc.costs.evaluation``) needs
``commonroad-clcs``, which pins ``osqp < 1`` (iamp's cvxpy needs ``osqp >= 1``), so it runs in the
peer's OWN environment (see ``scripts/commonroad_peer.py``):

    /tmp/venv-crpeer/bin/python scripts/commonroad_costs.py SCENARIO_DIR OUT.json SOLUTION.xml...

For every solution it writes the total and the partial (unweighted) costs of ``WX1``, ``SM1`` and
``TR1`` (an error, with its message, where the evaluator raises), keyed by the solution's path
as given (run it from the bench folder with relative paths: ``reports/commonroad/
costs-crosscheck.json`` is made so, and ``tests/test_commonroad_bench.py`` compares iamp's costs
with it).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

COST_FUNCTIONS = ("WX1", "SM1", "TR1")


def main() -> int:
    from commonroad.common.file_reader import CommonRoadFileReader
    from commonroad.common.solution import CommonRoadSolutionReader, CostFunction
    from commonroad_dc.costs.evaluation import CostFunctionEvaluator

    folder, out = Path(sys.argv[1]), Path(sys.argv[2])
    result: dict[str, dict[str, object]] = {}
    for name in sys.argv[3:]:
        sol = CommonRoadSolutionReader.open(name)
        pps = sol.planning_problem_solutions[0]
        scenario, problems = CommonRoadFileReader(str(folder / f"{sol.scenario_id}.xml")).open()
        pp = problems.planning_problem_dict[pps.planning_problem_id]
        row: dict[str, object] = {"benchmark_id": sol.benchmark_id}
        for cf in COST_FUNCTIONS:
            try:
                ev = CostFunctionEvaluator(CostFunction[cf], pps.vehicle_type)
                res = ev.evaluate_pp_solution(scenario, pp, pps.trajectory)
                row[cf] = {"total": float(res.total_costs),
                           "partial": {p.value: float(c) for p, c in res.partial_costs.items()}}
            except Exception as exc:  # the evaluator's failure is a result here
                row[cf] = {"error": f"{exc.__class__.__name__}: {exc}"[:300]}
        result[name] = row
        sys.stderr.write(f"{name}: " + ", ".join(
            f"{cf} {row[cf].get('total', 'error')}" for cf in COST_FUNCTIONS) + "\n")  # type: ignore[union-attr]
    out.write_text(json.dumps(result, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
