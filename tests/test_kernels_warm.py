"""``warm_kernels`` makes the compiled kernels ready (benches call it before timing) and changes no
plan."""

from __future__ import annotations

import subprocess
import sys

import pytest

from iamp.planners.pmp import jit

SCRIPT = """
import json, sys
from iamp.planners.examples import paper_problem
from iamp.planners import registry
from iamp.planners.pmp import compiled
from iamp.comparison.bench.limits import bounded_pmp_problems
warm = sys.argv[1] == "warm"
if warm:
    from iamp.planners.kernels import warm_kernels
    assert warm_kernels()
    assert compiled.axis_core() is not None
else:
    assert compiled.axis_core() is None
out = []
for name, prob in bounded_pmp_problems().items():
    p = registry.make_planner("pmp", diagnostics=False).plan(prob)
    out.append([name, str(p.status), None if p.cost is None else p.cost.hex(),
                [float(t).hex() for t in (p.contact_times if p.contact_times is not None else [])]])
print(json.dumps(out))
"""


@pytest.mark.skipif(not jit.available(), reason="numba is not installed (pip install 'iamp[fast]')")
def test_warm_kernels_loads_the_compiled_path_and_changes_no_plan() -> None:
    runs = [subprocess.run([sys.executable, "-c", SCRIPT, mode], capture_output=True, text=True, check=True).stdout
            for mode in ("cold", "warm")]
    assert runs[0] == runs[1]
    assert '"optimal"' in runs[0] and '"infeasible"' in runs[0]
