"""The bounded PMP's compiled path (:func:`iamp.planners.pmp.compiled.load_axis`: the axis solve,
the batched contact points, the Farkas margin and the certificate's unbounded bound, each
compiled from its one source) plans exactly as the Python path, bit for bit: whole plans
(search, global certificate, certified infeasibility by projection and cover) and the Farkas
margins of infeasible axes, in a subprocess compiled by numba and with ``NUMBA_DISABLE_JIT=1``."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from iamp.planners.pmp import compiled

SCRIPT = r"""
import json, sys
from iamp.comparison.bench.limits import bounded_pmp_problems
from iamp.planners.examples import boxed_problem, random_problem
from iamp.planners.pmp import compiled
from iamp.planners.pmp.planner import PMPPlanner
from iamp.planners.pmp.saturated import AxisInfeasible, solve_axis

if sys.argv[1] == "twin":
    assert compiled.load_axis(), compiled._STATE.get("error")
problems = list(bounded_pmp_problems().values())
problems += [boxed_problem(random_problem(s), f) for s in (1, 2, 3) for f in (0.5, 0.8)]
out = {"plans": [], "farkas": []}
for p in problems:
    plan = PMPPlanner(diagnostics=False).plan(p)
    d = plan.diagnostics
    out["plans"].append([plan.status, None if plan.cost is None else float(plan.cost).hex(),
                         [float(t).hex() for t in plan.contact_times],
                         json.dumps(getattr(d, "global_certificate", None), sort_keys=True, default=str),
                         json.dumps(getattr(d, "search", None), sort_keys=True, default=str)])
for k in range(40):  # one axis: the corner further off the straight path each time
    t = 0.3 + 0.4 * (k % 5) / 4
    try:
        solve_axis([t], 1.0, 0.0, 1.0, 1.1, 1.0, [t + 0.02 * k * t * (1 - t)], -1.0, 1.5)
        out["farkas"].append(["solved"])
    except AxisInfeasible as exc:
        out["farkas"].append([float(exc.margin).hex()] + [float(x).hex() for x in exc.certificate])
print(json.dumps(out))
"""


def _run(mode: str, disable_jit: bool) -> dict[str, list[list[object]]]:
    env = {**os.environ, "NUMBA_DISABLE_JIT": "1" if disable_jit else "0"}
    res = subprocess.run([sys.executable, "-c", SCRIPT, mode], capture_output=True, text=True, env=env, timeout=900)
    assert res.returncode == 0, res.stderr[-2000:]
    out: dict[str, list[list[object]]] = json.loads(res.stdout)
    return out


needs_numba = pytest.mark.skipif(not compiled.numba_available(), reason="numba is not installed")


@needs_numba
def test_the_bounded_twins_as_python_plan_as_the_default_path() -> None:
    ref = _run("pure", disable_jit=True)
    assert sum(p[0] == "infeasible" for p in ref["plans"]) >= 1 and sum(p[0] == "optimal" for p in ref["plans"]) >= 1
    assert sum(len(f) > 1 for f in ref["farkas"]) >= 5 and sum(f == ["solved"] for f in ref["farkas"]) >= 5
    assert _run("twin", disable_jit=True) == ref


@pytest.mark.slow
@needs_numba
def test_the_compiled_bounded_path_plans_as_the_python_source() -> None:
    assert _run("twin", disable_jit=False) == _run("pure", disable_jit=True)
