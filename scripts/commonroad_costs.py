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

    python scripts/commonroad_costs.py --compare BENCH_DIR

(any Python, no CommonRoad package needed) prints, per cost function, how iamp's costs in
``BENCH_DIR/bench.json`` compare with ``BENCH_DIR/costs-crosscheck.json`` (rows matched by
``solutions/<planner>/<scenario>.solution.xml`` and ``peers/<folder>/<scenario>.solution.xml``,
the peer's label read from its ``peer.json``).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

COST_FUNCTIONS = ("WX1", "SM1", "TR1")


def compare(folder: Path) -> int:
    bench = json.loads((folder / "bench.json").read_text())
    ref = json.loads((folder / "costs-crosscheck.json").read_text())
    rows = {(r["planner"], r["scenario"]): r for r in bench["rows"]}
    labels = {}
    for peer in (folder / "peers").glob("*/peer.json"):
        entries = json.loads(peer.read_text())
        labels[peer.parent.name] = next((e["planner"] for e in entries if e.get("planner")), peer.parent.name)
    for cf in COST_FUNCTIONS:
        rel: list[tuple[float, str]] = []
        for key, entry in ref.items():
            parts = Path(key).parts
            planner = labels.get(parts[1], parts[1]) if parts[0] == "peers" else parts[1]
            row = rows.get((planner, Path(key).name.removesuffix(".solution.xml")))
            theirs = entry.get(cf, {}).get("total")
            mine = None if row is None else row["costs"].get(cf)
            if theirs is not None and mine is not None:
                rel.append((abs(mine - theirs) / abs(theirs), key))
        rel.sort()
        if rel:
            med = rel[len(rel) // 2][0]
            sys.stdout.write(f"{cf}: {len(rel)} solutions, relative difference median {100 * med:.3f} %, "
                             f"largest {100 * rel[-1][0]:.3f} % ({rel[-1][1]})\n")
    return 0


def main() -> int:
    if sys.argv[1] == "--compare":
        return compare(Path(sys.argv[2]))
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
