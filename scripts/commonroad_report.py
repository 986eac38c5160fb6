"""Combine an ``iamp commonroad bench --out DIR`` run with the peer's solutions into one report.

    python scripts/commonroad_report.py BENCH_DIR/bench.json SCENARIO_DIR PEER_DIR OUT_DIR

``BENCH_DIR/bench.json`` is the bench's own output (its rows are reused as they are); the peer's
rows are judged here (:func:`iamp.commonroad.bench.peer_rows`, the same checks).  Equivalent to
``iamp commonroad bench SCENARIO_DIR --planners ... --peer PEER_DIR --out OUT_DIR`` without
planning the iamp rows a second time.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from iamp.commonroad.bench import PEER_LABEL, Row, peer_rows, summary, write_reports


def main() -> int:
    bench_json, scenarios, peer, out = (Path(a) for a in sys.argv[1:5])
    data = json.loads(bench_json.read_text())
    rows = [Row(**r) for r in data["rows"]]
    planners = [e["planner"] for e in data["summary"] if e["planner"] != PEER_LABEL]
    rows = [r for r in rows if r.planner != PEER_LABEL] + peer_rows(scenarios, peer)
    planners.append(PEER_LABEL)
    command = (f"{data['command']}; peer: scripts/commonroad_peer.py {scenarios} {peer} (own venv); "
               f"combined: python scripts/commonroad_report.py {bench_json} {scenarios} {peer} {out}")
    write_reports(rows, planners, out, command)
    for e in summary(rows, planners):
        sys.stdout.write(f"{e['planner']:14s} valid {e['valid']}/{e['scenarios']}\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
