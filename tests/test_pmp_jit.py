"""One source for each scalar kernel (issue 32 item 1): the one-vehicle kernel and the saturated
axis solve run as Python by default and, opt-in, compiled by numba from the same code objects
(:mod:`iamp.planners.pmp.jit`).  The same source is run here in a subprocess as compiled by
numba and with ``NUMBA_DISABLE_JIT=1``, on a grid of problems, and every number must equal the
default (Python) path's bit for bit: no result depends on whether numba is installed or loaded."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from iamp.planners.pmp import compiled

SCRIPT = r"""
import json, sys
import numpy as np
from iamp.core.physical import PhysicalLimits
from iamp.planners.examples import paper_problem, random_problem, two_minima_problem
from iamp.planners.pmp import compiled
from iamp.planners.pmp.bounded import solve_bounded_fixed
from iamp.planners.pmp.one import one_vehicle_data, one_vehicle_kernel
from iamp.planners.pmp.planner import PMPPlanner

use_twin = sys.argv[1] == "twin"
kernel = compiled.compiled_kernel() if use_twin else one_vehicle_kernel
if use_twin:
    assert compiled.load_axis(), compiled._STATE.get("error")
problems = [paper_problem(k) for k in (1, 2, 3)] + [two_minima_problem()] + [random_problem(s) for s in range(40)]
out = {"kernel": [], "axis": []}
for p in problems:
    _, _, ego, ex, ey, cx, cy = one_vehicle_data(p)
    out["kernel"].append([float(x).hex() for x in kernel(ego, ex, ey, cx, cy)])
for p in problems[:12]:  # an input box at 85 % of the unbounded plan's peaks: active, mostly feasible
    plan = PMPPlanner().plan(p, diagnostics=False)
    mx, my = np.abs(plan.trajectory.inputs(np.linspace(0.0, p.tf, 401))).max(axis=0)
    b = p.with_limits(PhysicalLimits(ax=(-0.85 * mx, 0.85 * mx), ay=(-0.85 * my, 0.85 * my)))
    for frac in (0.9, 0.95, 1.0, 1.05, 1.1):
        try:
            sol = solve_bounded_fixed(b, [min(frac * plan.contact_times[0], 0.99 * p.tf)])
            out["axis"].append([sol.cost.hex()] + [float(x).hex() for x in sol.jumps.ravel()]
                               + [float(x).hex() for ax in sol.axes for x in ax.knots])
        except Exception as exc:
            out["axis"].append([type(exc).__name__])
print(json.dumps(out))
"""


def _run(mode: str, disable_jit: bool) -> dict[str, list[list[str]]]:
    env = {**os.environ, "NUMBA_DISABLE_JIT": "1" if disable_jit else "0"}
    res = subprocess.run([sys.executable, "-c", SCRIPT, mode], capture_output=True, text=True, env=env, timeout=600)
    assert res.returncode == 0, res.stderr[-2000:]
    out: dict[str, list[list[str]]] = json.loads(res.stdout)
    return out


needs_numba = pytest.mark.skipif(not compiled.numba_available(), reason="numba is not installed")


@needs_numba
def test_the_twin_as_python_equals_the_default_path_bit_for_bit() -> None:
    """``NUMBA_DISABLE_JIT=1``: the twin built by :func:`iamp.planners.pmp.jit.twin` (the code
    objects with their globals swapped) runs as Python and equals the planner's path."""
    ref = _run("pure", disable_jit=True)
    assert len(ref["kernel"]) == 44 and sum(len(r) > 1 for r in ref["axis"]) >= 50  # solved (not an exception name)
    assert _run("twin", disable_jit=True) == ref


@pytest.mark.slow
@needs_numba
def test_the_compiled_twin_equals_the_python_source_bit_for_bit() -> None:
    """numba's machine code (compiled in the subprocess) against the same source run as Python."""
    assert _run("twin", disable_jit=False) == _run("pure", disable_jit=True)
