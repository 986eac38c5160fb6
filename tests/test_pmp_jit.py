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


CACHE_SCRIPT = r"""
import os, numba
from iamp.core import jit
from iamp.core import polyroots_kernel as kernel
import numpy as np
C = np.array([[-0.25, 0.0, 1.0]])
M = np.zeros((1, 3))
nb = np.zeros(1, dtype=np.int64)
jit.twin(kernel.root_degrees, cache=True)(C, M, 1e-6, True, nb)
print(numba.config.CACHE_DIR)
"""


def test_the_twins_machine_code_goes_to_the_user_cache_not_into_the_package(tmp_path) -> None:
    """``jit.twin(..., cache=True)`` keeps numba's cache in ``$XDG_CACHE_HOME/iamp/numba`` (unless
    ``NUMBA_CACHE_DIR`` is set): numba's default, ``__pycache__`` beside the source, wrote files into
    an installed package that pip does not remove, and after ``pip install .`` the README's
    ``pip install -e .`` left ``site-packages/iamp`` behind as a namespace package that hid the
    editable install (``module 'iamp' has no attribute 'load_scenario'``)."""
    pytest.importorskip("numba")
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "NUMBA_DISABLE_JIT")}
    env["XDG_CACHE_HOME"] = str(tmp_path)
    r = subprocess.run([sys.executable, "-c", CACHE_SCRIPT], capture_output=True, text=True, env=env, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    target = tmp_path / "iamp" / "numba"
    assert r.stdout.strip() == str(target)
    assert any(p.suffix == ".nbi" and "root_degrees" in p.name for p in target.rglob("*"))
    env["NUMBA_CACHE_DIR"] = str(tmp_path / "mine")  # the user's own choice wins
    r = subprocess.run([sys.executable, "-c", CACHE_SCRIPT], capture_output=True, text=True, env=env, timeout=300)
    assert r.returncode == 0 and r.stdout.strip() == str(tmp_path / "mine")


def test_inlined_helpers_are_small_leaves_and_compile_inline() -> None:
    """:func:`iamp.core.jit.inlined` marks small helpers that their compiled callers inline: each
    calls no compilable function (an inlined caller copies its callees' code into every caller:
    every kernel function inlined took 9 min 22 s to compile instead of 77 s), is compilable, and
    its twin carries ``inline="always"`` while an entry kernel's does not.  The numbers stay those
    of the Python path (the same operations in the same order: ``tests/test_avoid_schur_kernel.py``,
    ``tests/test_avoid_search_kernel.py``, ``tests/test_polyroots_kernel.py`` compare them)."""
    import types

    from iamp.core import (
        jit,
        polyroots_kernel,  # noqa: F401  (registers its helpers)
    )
    from iamp.planners.avoid import schur_kernel, search_kernel

    inlined = set(jit._INLINE)
    assert {schur_kernel._row_dot, search_kernel.plane_margin, search_kernel.held_position} <= inlined
    for fn in inlined:
        src = jit._SOURCE[fn]
        callees = [n for n in src.__code__.co_names
                   if isinstance(src.__globals__.get(n), types.FunctionType) and src.__globals__[n] in jit._SOURCE]
        assert not callees, (fn.__name__, callees)
    if not jit.available():
        pytest.skip("numba is not installed: no twins to inspect")
    assert jit.twin(schur_kernel._row_dot, cache=True).targetoptions["inline"] == "always"
    assert jit.twin(schur_kernel.active_set, cache=True).targetoptions["inline"] == "never"
