"""SPEC §10: the avoidance QP's ``info["n_solves"]`` is the number of QPs it actually solved —
every backend solve of the free optimum's certificate, the pruning relaxations, the sweep's
candidates, the coarse sweep with coordinate descent, and the ``refine`` search off the grid
(counted here by wrapping the backend's ``solve``)."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from iamp.core import status as st
from iamp.core.problem import EgoBoundary, Problem, SurroundingVehicle
from iamp.planners.avoid.planner import AvoidQPPlanner
from iamp.planners.avoid.solve import BoundSolver
from iamp.planners.examples import builtin_problem, paper_problem


def binding_problem() -> Problem:
    """One vehicle whose inequalities bind (the free optimum cuts through its safety box)."""
    ego = EgoBoundary(tf=5.0, x0=0.0, y0=-2.0, vx0=20.0, xf=118.0, yf=3.75, vxf=24.0)
    v = SurroundingVehicle(x_poly=(5.0, 20.0), corner="front-lower", y=3.75, length=4.8, width=1.8,
                           safety_x=5.0, safety_y=0.5, name="sv1")
    return Problem(ego, (v,), "binding")


@pytest.fixture
def backend_solves(monkeypatch: pytest.MonkeyPatch) -> Iterator[list[int]]:
    """``[n]``: the number of ``BoundSolver.solve`` calls made since the fixture started."""
    calls = [0]
    original = BoundSolver.solve

    def counted(self: BoundSolver) -> object:
        calls[0] += 1
        return original(self)

    monkeypatch.setattr(BoundSolver, "solve", counted)
    yield calls


CASES = {
    # one vehicle, binding: the free solve (no certificate), seeds, bisection relaxations, survivors
    "pruned-foh-clarabel": (binding_problem, dict(steps=30)),
    "pruned-zoh-osqp": (binding_problem, dict(steps=30, hold="zoh", solver="osqp")),
    "full-sweep": (binding_problem, dict(steps=30, prune=False)),
    "refine-one-vehicle": (binding_problem, dict(steps=20, contact="refine")),
    # paper 1: the free optimum is certified (one solve, then the refine search)
    "certified": (lambda: paper_problem(1), dict(steps=40)),
    "certified-refine": (lambda: paper_problem(1), dict(steps=40, contact="refine")),
    # two vehicles: every combination; coarse sweep + coordinate descent; refine twice over the vehicles
    "two-vehicle-complete": (lambda: builtin_problem("two-vehicle"), dict(steps=10)),
    "two-vehicle-coarse": (lambda: builtin_problem("two-vehicle"), dict(steps=12, max_combinations=50, coarse=5)),
    "two-vehicle-refine": (lambda: builtin_problem("two-vehicle"), dict(steps=10, contact="refine")),
}


@pytest.mark.parametrize("case", list(CASES))
def test_n_solves_counts_every_backend_solve(case: str, backend_solves: list[int]) -> None:
    make, kwargs = CASES[case]
    problem = make()
    backend_solves[0] = 0
    plan = AvoidQPPlanner(safety="nodes", **kwargs).plan(problem)
    assert plan.status in st.SUCCESS | {st.UNSAFE}  # node-only plans that cut a corner are unsafe
    n = plan.info["n_solves"]
    assert n == backend_solves[0]
    assert plan.info["avoidance"]["n_solves"] == n
    sweep = plan.info["sweep"]
    if plan.info["certificate"] is None:
        # every candidate of the sweep plus at least the free solve (certificate attempt)
        assert n >= len(sweep) + 1
    if kwargs.get("contact") == "refine":
        # the refine search solves on aligned grids beyond the grid search
        grid = AvoidQPPlanner(safety="nodes", **{**kwargs, "contact": "grid"})
        backend_solves[0] = 0
        grid_plan = grid.plan(problem)
        assert grid_plan.info["n_solves"] == backend_solves[0]
        assert n > grid_plan.info["n_solves"]


def test_plan_at_times_is_one_solve(backend_solves: list[int]) -> None:
    plan = AvoidQPPlanner(safety="nodes", steps=30).plan_at_times(binding_problem(), [2.5])
    assert plan.ok
    assert plan.info["n_solves"] == backend_solves[0] == 1
