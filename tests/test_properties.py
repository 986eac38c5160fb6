"""Property-based tests of ``iamp plan`` over generated scenarios, valid and mutated (issue 9).

For every generated scenario file and option set:

* the exit status is 0, 2, 3 or 4 — never 1 (an internal error) or a traceback;
* a refusal (2) is exactly one line on standard error and nothing on standard output;
* a plan that exits 0 satisfies its own conditions, recomputed from its JSON independently of
  the planner (``scripts/fuzz.py::check_plan_json``): the boundary states at ``t = 0`` and
  ``t_f``; the trajectory equals the fixed-time optimum through the reported contact corners
  (the clamped cubic spline, which passes through every corner, so the contact equalities
  hold); and the cost is that optimum's ``½∫(s_x''² + s_y''²)`` (the tolerances are those of
  the check: 1e-6 relative for the PMP and Clarabel, 1e-4 for OSQP);
* the same holds through the Python API (``Plan.boundary_residual``, ``corner_residual``).

The CLI runs in-process (``iamp.cli.main.main``).  Few examples by default (CI); set
``HYPOTHESIS_PROFILE=dev`` (300 examples) or ``=long`` (3000) for a longer search.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import random
import sys
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from iamp.cli.main import main
from iamp.core.tolerances import TOLERANCES

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
from fuzz import check_plan_json, mutate

EXAMPLES = {"ci": 12, "dev": 300, "long": 3000}.get(os.environ.get("HYPOTHESIS_PROFILE", "ci"), 12)
SETTINGS = settings(max_examples=EXAMPLES, deadline=None, derandomize=os.environ.get("HYPOTHESIS_PROFILE") is None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])

VEHICLE = """
[[vehicles]]
name = "{name}"
corner = "{corner}"
y = {y!r}
length = {length!r}
width = {width!r}
safety_x = {sx!r}
safety_y = {sy!r}
x_poly = [{poly}]
"""


@st.composite
def scenarios(draw: st.DrawFn) -> str:
    """A plausible lane change: the ego changes lane by about one lane width; vehicle 1 in the
    target lane (front-lower, behind), optionally vehicle 2 ahead in the current lane
    (rear-upper)."""
    f = st.floats
    tf = draw(f(2.0, 8.0))
    vx0 = draw(f(8.0, 35.0))
    y0 = draw(f(-4.0, 0.0))
    yf = y0 + draw(f(3.0, 4.5))
    xf = vx0 * tf + draw(f(-20.0, 25.0))
    vxf = vx0 + draw(f(-4.0, 4.0))
    text = (f'name = "gen"\n[ego]\ntf = {tf!r}\nx0 = 0.0\ny0 = {y0!r}\nvx0 = {vx0!r}\nxf = {xf!r}\nyf = {yf!r}\n'
            f"vxf = {vxf!r}\n")
    geometry = {"length": draw(f(3.5, 6.0)), "width": draw(f(1.5, 2.2)), "sx": draw(f(0.0, 6.0)),
                "sy": draw(f(0.0, 0.6))}
    c = [draw(f(-40.0, -5.0)), vx0 + draw(f(-8.0, 3.0)), draw(f(-1.0, 1.0)), draw(f(-0.05, 0.05))]
    text += VEHICLE.format(name="sv1", corner="front-lower", y=yf, poly=", ".join(repr(x) for x in c), **geometry)
    if draw(st.booleans()):
        c2 = [draw(f(20.0, 70.0)), vx0 + draw(f(-6.0, 2.0)), draw(f(-0.5, 0.5)), 0.0]
        text += VEHICLE.format(name="sv2", corner="rear-upper", y=y0, poly=", ".join(repr(x) for x in c2),
                               **geometry)
    return text


@st.composite
def options(draw: st.DrawFn) -> list[str]:
    if draw(st.integers(0, 4)) == 0:
        return ["--planner", "qp", "--steps", str(draw(st.integers(8, 24))), "--solver",
                draw(st.sampled_from(["clarabel", "osqp"])), "--hold", draw(st.sampled_from(["foh", "zoh"]))]
    return ["--steps", str(draw(st.integers(1, 300)))]


def run_plan(text: str | bytes, opts: list[str]) -> tuple[int, str, str, Path, tempfile.TemporaryDirectory[str]]:
    tmp = tempfile.TemporaryDirectory(prefix="iamp-prop-")
    path = Path(tmp.name) / "s.toml"
    path.write_bytes(text.encode("utf-8", "surrogatepass") if isinstance(text, str) else text)
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(["plan", str(path), "--json", *opts])
        except SystemExit as exc:
            code = int(exc.code) if isinstance(exc.code, int) else 2
    return code, out.getvalue(), err.getvalue(), path, tmp


def assert_contract(code: int, out: str, err: str, path: Path) -> None:
    assert code in (0, 2, 3, 4), (code, err)
    assert "Traceback" not in err
    if code == 2:
        assert out == "" and len(err.strip().splitlines()) == 1, err
        return
    d = json.loads(out)  # exactly one JSON object
    if code == 3 and d["cost"] is None:
        assert d["status"] != "optimal"
        return
    assert d["status"] == ("optimal" if code in (0, 4) else "local"), d["status"]
    from iamp.prediction.resolve import load_problem

    _, problem, _ = load_problem(str(path))
    assert check_plan_json(d, problem) == []


@SETTINGS
@given(text=scenarios(), opts=options())
def test_generated_scenarios_plan_and_satisfy_their_conditions(text, opts):
    code, out, err, path, tmp = run_plan(text, opts)
    with tmp:
        assert_contract(code, out, err, path)


@SETTINGS
@given(text=scenarios(), seed=st.integers(0, 2**32 - 1), n=st.integers(1, 3), opts=options())
def test_mutated_scenarios_never_crash(text, seed, n, opts):
    rng = random.Random(seed)
    for _ in range(n):
        text, _ = mutate(text, rng)
    code, out, err, path, tmp = run_plan(text.replace("\udcff", ""), opts)
    with tmp:
        assert_contract(code, out, err, path)


@SETTINGS
@given(text=scenarios())
def test_api_plans_check_their_own_residuals(text):
    """Through the Python API: an optimal PMP plan meets its boundary conditions and contact
    equalities to the PMP's condition tolerance (scaled by the problem's magnitude)."""
    from iamp.core.scenario import loads_scenario
    from iamp.planners.pmp.planner import PMPPlanner

    problem, _ = loads_scenario(text, "generated").to_problem()
    plan = PMPPlanner().plan(problem)
    if not plan.is_optimal():
        assert plan.cost is None
        return
    scale = max(1.0, float(np.max(np.abs(np.concatenate([problem.ego.initial, problem.ego.final])))))
    tol = TOLERANCES["pmp_condition_residual"] * scale * 100
    assert plan.boundary_residual() <= tol
    assert plan.corner_residual() <= tol
    assert 0 < plan.contact_times.min() and plan.contact_times.max() < problem.tf


@pytest.mark.parametrize("base", ["paper-1-poly", "two-vehicle", "paper-2"])
def test_builtin_scenarios_satisfy_the_json_check(base):
    from iamp.core.scenario import builtin_text

    code, out, err, path, tmp = run_plan(builtin_text(base), ["--steps", "50"])
    with tmp:
        assert code in (0, 3), err
        assert_contract(code, out, err, path)
