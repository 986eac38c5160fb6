"""The walk of a plan through the code (issue 18): ``scripts/walk.py``'s stack metric.

A module is *left* when no frame of it remains on the call stack; a *return* is a call that
enters a module left earlier; an *upward* call goes from a lower layer into a higher one.
The metric is tested on synthetic call sequences (against an independent count), then the
PMP's walk from ``PMPPlanner.plan`` to its ``Plan`` is required to have no return and no upward
call, and the command line's walk (``iamp plan S --json``, PMP and QP) no upward call.
"""

from __future__ import annotations

import sys
from collections import Counter
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))

from walk import StackWalk, rank, walk_cli, walk_planner

ONE_VEHICLE = ("paper-1", "paper-2", "paper-3", "paper-1-poly")


def run(events: list[str | None]) -> StackWalk:
    """Feed ``events``: a module name (or ``None``, a frame outside iamp) is a call, ``"<"`` a return."""
    walk = StackWalk()
    for e in events:
        if e == "<":
            walk.ret()
        else:
            walk.call(e, "f")
    return walk


def test_a_module_entered_again_after_it_was_left_is_a_return() -> None:
    a, b = "iamp.planners.pmp.planner", "iamp.core.problem"
    walk = run([a, b, "<", b, "<", "<"])  # a calls b twice: b is left in between
    assert [m for m, _, _ in walk.returns] == [b]
    assert walk.returns[0][2] == a  # named with its caller
    assert walk.stretches[b] == 2 and walk.stretches[a] == 1


def test_a_callee_returning_to_its_caller_does_not_leave_the_caller() -> None:
    a, b, c = "iamp.cli.plan", "iamp.planners.registry", "iamp.planners.pmp.planner"
    walk = run([a, b, "<", c, "<", "<"])  # a calls b, then c: a never left
    assert walk.returns == [] and walk.entered == [a, b, c]
    # a module calling into itself again while a frame of it is still on the stack: one stretch
    walk = run([a, b, a, "<", "<", a, "<", "<"])
    assert walk.returns == []


def test_a_module_called_again_after_its_caller_returned_is_a_return() -> None:
    a, b = "iamp.cli.plan", "iamp.core.plan"
    walk = run([a, b, "<", "<", None, b, "<", "<"])  # top level calls b again (through a non-iamp frame)
    assert [m for m, _, _ in walk.returns] == [b]


def test_upward_calls_go_from_a_lower_layer_to_a_higher_one_through_foreign_frames() -> None:
    core, pmp, cli = "iamp.core.plan", "iamp.planners.pmp.solution", "iamp.cli.progress"
    walk = run([pmp, core, None, pmp, "<", "<", "<", cli, "<", "<"])
    assert walk.upward == Counter({(core, f"{pmp}.f"): 1, (pmp, f"{cli}.f"): 1})
    assert rank("iamp.core.x") < rank("iamp.planners.x") == rank("iamp.prediction.x") < rank("iamp.cli.x")
    assert run([cli, pmp, "<", core, "<", "<"]).upward == Counter()  # downward only


@st.composite
def call_sequences(draw: st.DrawFn) -> list[str | None]:
    """Balanced call/return sequences over a few modules (and foreign frames)."""
    mods = st.sampled_from(["iamp.core.a", "iamp.core.b", "iamp.planners.c", "iamp.cli.d", None])
    events: list[str | None] = []
    depth = 0
    for _ in range(draw(st.integers(0, 40))):
        if depth and draw(st.booleans()):
            events.append("<")
            depth -= 1
        else:
            events.append(draw(mods))
            depth += 1
    return events + ["<"] * depth


@settings(max_examples=300, deadline=None)
@given(call_sequences())
def test_returns_are_the_extra_stretches_of_each_module(events: list[str | None]) -> None:
    """Independent count: replay the stack, mark at every step which modules have a frame on it,
    and count each module's maximal runs of steps with a frame; every run after the first is one
    return."""
    stack: list[str | None] = []
    runs: Counter[str] = Counter()
    active_before: set[str] = set()
    for e in events:
        if e == "<":
            stack.pop()
        else:
            stack.append(e)
        active = {m for m in stack if m is not None}
        for m in active - active_before:
            runs[m] += 1
        active_before = active
    walk = run(events)
    assert len(walk.returns) == sum(n - 1 for n in runs.values())
    assert Counter(m for m, _, _ in walk.returns) == Counter({m: n - 1 for m, n in runs.items() if n > 1})


@pytest.mark.parametrize("scenario", ONE_VEHICLE)
def test_the_one_vehicle_pmp_walk_goes_down_without_returning(scenario: str) -> None:
    """``PMPPlanner().plan(problem)``: each module in one contiguous stretch, nothing called upward."""
    stack, _ = walk_planner(scenario)
    assert stack.returns == [], stack.returns
    assert not stack.upward, stack.upward
    assert "iamp.planners.pmp.planner" == stack.entered[0] and "iamp.core.plan" in stack.entered


def test_the_walk_is_the_same_with_the_compiled_kernels_loaded() -> None:
    """A kernel is a leaf of the walk (``scripts/walk.py``), so the walk does not depend on whether
    an earlier call in the process loaded the compiled kernels (it did, before: run alone this
    file's walks met ``search_kernels`` again and again, after the suite's warm-up they did not)."""
    from iamp.planners.kernels import warm_kernels

    before = walk_planner("paper-1")[0]
    warm_kernels()
    after = walk_planner("paper-1")[0]
    assert (before.entered, before.returns, before.upward) == (after.entered, after.returns, after.upward)


@pytest.mark.parametrize(("scenario", "planner"), [(s, "pmp") for s in (*ONE_VEHICLE, "two-vehicle")]
                         + [("paper-1", "qp"), ("paper-1-poly", "qp")])
def test_the_command_line_walk_calls_nothing_upward(scenario: str, planner: str) -> None:
    """``iamp plan S --json``: the core evaluates the PMP's and the QP's trajectories itself
    (:class:`iamp.core.jump_trajectory.JumpTrajectory`,
    :class:`iamp.core.hold_trajectory.HoldTrajectory`), reads the histories' predictions made
    before (:class:`iamp.core.scenario.Predicted`), and no progress callback goes to the planner
    without a bar."""
    stack, _ = walk_cli(scenario, planner)
    assert not stack.upward, stack.upward
    assert stack.entered[0] == "iamp.cli.plan"


@pytest.mark.parametrize("scenario", ONE_VEHICLE)
def test_the_command_line_walk_from_the_planner_selection_to_the_plan_returns_nowhere(scenario: str) -> None:
    """``iamp plan S --json`` (PMP, one vehicle), from the first call into the planners layer (the
    registry, asked once: :func:`iamp.planners.registry.prepare`) to the moment the planner hands
    its ``Plan`` to the command: every module in one contiguous stretch (the planner is built and
    plans in one call, the corners are read through :mod:`iamp.core.contact`)."""
    stack, _ = walk_cli(scenario, "pmp")
    assert stack.planning_from is not None and stack.plan_made is not None
    planning = stack.returns[stack.planning_from:stack.plan_made]
    assert planning == [], planning
    entered = stack.entered
    assert entered.index("iamp.planners.registry") < entered.index("iamp.planners.pmp.planner")
    assert entered.index("iamp.planners.pmp.options") < entered.index("iamp.planners.pmp.planner")


def test_the_planning_stage_counts_returns_between_the_first_planner_call_and_the_plan() -> None:
    """The stage bookkeeping of :class:`StackWalk` on a synthetic sequence: returns before the
    first planners-layer call are loading, those after it planning."""
    core, pmp, cli = "iamp.core.problem", "iamp.planners.pmp.planner", "iamp.cli.plan"
    walk = StackWalk()
    walk.call(cli)
    for _ in range(2):  # the core entered twice from the command: one loading return
        walk.call(core)
        walk.ret()
    walk.call(pmp)
    walk.ret()
    walk.call(pmp)  # the planner entered again: a planning return
    walk.ret()
    walk.plan_made = len(walk.returns)
    summary = walk.summary()
    assert (summary["returns_loading"], summary["returns_planning"]) == (1, 1)


def test_loading_a_polynomial_scenario_validates_each_object_in_one_call() -> None:
    """``iamp plan paper-1-poly``'s loading stage: every object of :mod:`iamp.core.problem` checks its
    fields against the bounds table in one call (:func:`iamp.core.limits.first_refusal`), and the
    scenario says whether it needs a predictor as a plain attribute. What stays: the parser's
    probe vehicle, the problem's vehicles and the problem itself are three constructions from
    :mod:`iamp.core.scenario` (each one call into ``core.problem`` and one into ``core.limits``),
    the parser's polynomial check, and ``to_problem`` after the parse (8 returns; was 25)."""
    stack, _ = walk_cli("paper-1-poly", "pmp")
    loading = stack.returns[:stack.planning_from]
    assert len(loading) <= 8, loading
    per_field = [r for r in loading if r[1] in ("bound_message", "abs_message")]
    assert per_field == [], per_field
    assert not any(r[1] == "needs_prediction" for r in loading)
