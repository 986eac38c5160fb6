"""The public Python API (SPEC §12): what a user imports, and that it tells the truth.

The README's "Python" example is executed here verbatim (extracted from README.md), so the
documentation cannot drift from the library.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import iamp
from iamp.cli.main import main as cli_main

README = Path(__file__).resolve().parents[1] / "README.md"


def test_all_names_exist_and_are_documented():
    assert iamp.__version__
    for name in iamp.__all__:
        obj = getattr(iamp, name)
        if callable(obj) and name != "__version__":
            assert (obj.__doc__ or "").strip(), f"iamp.{name} has no docstring"


def test_errors_derive_from_one_root():
    for cls in (iamp.ScenarioError, iamp.HistoryError, iamp.SolverError, iamp.MissingDependencyError):
        assert issubclass(cls, iamp.IampError)
    assert issubclass(iamp.ScenarioError, ValueError)


def test_one_import_name_per_module():
    """No second copy of a module: `iamp.iamp` does not exist, and the errors raised through
    any path are the very class exported at the top."""
    r = subprocess.run([sys.executable, "-c", "import iamp.iamp"], capture_output=True, text=True)
    assert r.returncode != 0 and "No module named 'iamp.iamp'" in r.stderr
    from iamp.core import errors

    assert errors.ScenarioError is iamp.ScenarioError
    with pytest.raises(iamp.ScenarioError):
        iamp.load_scenario("no-such-scenario-name")


def test_py_typed_is_shipped():
    assert (Path(iamp.__file__).parent / "py.typed").is_file()


def test_plan_matches_the_cli_json(capsys):
    """`Plan.to_json()` is exactly the object `iamp plan --json` prints (SPEC §12)."""
    prob = iamp.load_scenario("paper-1-poly")
    plan = iamp.plan(prob)
    assert cli_main(["plan", "paper-1-poly", "--json"]) == 0
    cli = json.loads(capsys.readouterr().out)
    mine = plan.to_json()
    cli.pop("solve_time_s"), mine.pop("solve_time_s")
    assert mine == cli


def test_plan_states_and_inputs_are_the_planned_motion():
    """states(t) integrates inputs(t): s(t) - s(0) - v(0) t = ∫∫u, checked by quadrature."""
    prob = iamp.load_scenario("paper-1-poly")
    plan = iamp.plan(prob)
    assert plan.status == "optimal" and plan.ok
    t = np.linspace(0.0, prob.tf, 20001)
    X, U = plan.states(t), plan.inputs(t)
    assert X.shape == (t.size, 4) and U.shape == (t.size, 2)
    # velocity = cumulative integral of the input (trapezoid, piecewise-linear input: exact)
    for vi, ui in ((1, 0), (3, 1)):
        v = X[0, vi] + np.concatenate([[0.0], np.cumsum((U[1:, ui] + U[:-1, ui]) / 2 * np.diff(t))])
        assert np.max(np.abs(v - X[:, vi])) < 1e-6
    # boundary conditions and the cost J = ½∫|u|²
    assert np.allclose(X[0], prob.ego.initial, atol=1e-9) and np.allclose(X[-1], prob.ego.final, atol=1e-9)
    J = 0.5 * np.trapezoid(np.sum(U**2, axis=1), t)
    assert J == pytest.approx(plan.cost, rel=1e-6)
    # the contact equality at t_i
    c = prob.corners(plan.contact_times)
    assert np.allclose(plan.states(plan.contact_times)[:, [0, 2]], c, atol=1e-8)


def test_qp_through_the_api_equals_the_pmp_at_its_own_optimum():
    """FOH + refine reaches the PMP's continuous optimum (SPEC §3.1/§3.4) through iamp.plan."""
    prob = iamp.load_scenario("paper-1-poly")
    pmp = iamp.plan(prob)
    qp = iamp.plan(prob, planner="qp", solver="clarabel", hold="foh", steps=50, contact="refine")
    assert qp.ok
    assert qp.cost == pytest.approx(pmp.cost, rel=1e-6)
    assert np.allclose(qp.contact_times, pmp.contact_times, atol=1e-3)


@pytest.mark.parametrize("kwargs, field", [
    ({"solver": "osqp"}, "solver"), ({"hold": "zoh"}, "hold"), ({"contact": "refine"}, "contact"),
    ({"planner": "rrt"}, "planner"), ({"steps": 0}, "steps"), ({"constraint": "soft"}, "constraint"),
])
def test_options_that_do_not_apply_are_refused(kwargs, field):
    prob = iamp.load_scenario("paper-1-poly")
    with pytest.raises(iamp.ScenarioError) as err:
        iamp.plan(prob, **kwargs)
    assert err.value.field == field


def test_compare_returns_the_spec_object():
    prob = iamp.load_scenario("paper-1-poly")
    comp = iamp.compare(prob, steps=(12,), solvers=("clarabel",), holds=("foh",), repeats=1)
    assert comp.all_agree and not comp.any_failed
    out = comp.to_json()
    (sc,) = out["scenarios"]
    # the typed object and its JSON tell the same numbers: the PMP run's cost is the plan's
    (pc,) = comp.scenarios
    assert pc.run("pmp").result.cost == pytest.approx(iamp.plan(prob).cost, rel=1e-12)
    assert sc["runs"][0]["cost"] == pc.run("pmp").result.cost
    labels = [r["label"] for r in sc["runs"]]
    assert labels[0] == "pmp" and any("clarabel-foh-12" in lab for lab in labels)
    pair = sc["agreement"][0]
    for key in ("a", "b", "cost_rel_gap", "contact_time_gap", "state_sup_gap", "jump_gap", "verdict"):
        assert key in pair
    assert pair["verdict"] == "agree"


def test_predictor_gives_the_cubic_of_a_constant_speed_history():
    t = np.linspace(-3.0, 0.0, 31)
    pred = iamp.Predictor.default().predict(iamp.History(t, -15.0 + 18.0 * t))
    c0, c1, c2, c3 = pred.x_poly
    assert c0 == pytest.approx(-15.0, abs=0.5) and c1 == pytest.approx(18.0, abs=1.0)
    # a constant-speed history is forecast as (nearly) constant speed: the cubic's curvature
    # terms move the 5 s position by well under a metre
    assert abs(c2) * 25 + abs(c3) * 125 < 1.0


def _readme_python_example() -> str:
    text = README.read_text(encoding="utf-8")
    m = re.search(r"## In ten lines of Python\n.*?```python\n(.*?)```", text, re.S)
    assert m, "README.md has no '## In ten lines of Python' section with a ```python block"
    return m.group(1)


def test_readme_python_example_runs(tmp_path):
    code = _readme_python_example()
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "optimal" in r.stdout
    assert "BlasKernelWarning" not in r.stderr  # iamp imported before numpy: the pinned kernels
    assert (tmp_path / "plan.gif").stat().st_size > 0  # the animation it writes
