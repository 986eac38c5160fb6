"""
Plan within the car's limits
============================

The template scenario carries a ``[limits]`` table (SPEC §14): the longitudinal and lateral
acceleration ranges, a friction circle and a speed range. The bounded PMP saturates its input
(:math:`u = \\operatorname{sat}(-p_2, -p_4)`), the QP imposes every bound at each grid node;
both report their exact peaks against the bounds.

Run: ``python examples/plan_bounded.py``
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
from pathlib import Path

import iamp
from iamp.cli.plot import plan_figure


def main() -> dict[str, iamp.Plan]:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "bounded.toml"
        # the commented scenario `iamp template` prints: it has a [limits] table
        path.write_text(subprocess.run([sys.executable, "-m", "iamp", "template"], check=True, capture_output=True,
                                       text=True, encoding="utf-8").stdout)
        problem = iamp.load_scenario(str(path))
    print("limits:", problem.limits)
    plans = {"pmp": iamp.plan(problem), "qp": iamp.plan(problem, "qp", solver="clarabel", steps=100)}
    for name, plan in plans.items():
        print(f"{name:4s} {plan.status:8s} J = {plan.cost:.6f}")
        print("     peaks:", plan.peaks.line())
    # drawn through pyplot, so that the gallery shows it
    plan_figure(plans["pmp"], title="the template scenario with its limits: bounded PMP", pyplot=True)
    return plans


if __name__ == "__main__":
    main()
