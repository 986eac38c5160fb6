"""iamp — interaction-aware optimal lane-change planning.

A lane-change planner built on Pontryagin's minimum principle, in which each surrounding
vehicle's predicted trajectory enters as an interior-point equality constraint at a free
contact time (co-state and Hamiltonian jump conditions); a convex QP/MPC baseline with the
same constraints (and a true avoidance QP); and a high-order Markov-chain (MTD) predictor.

The public API (SPEC §12)::

    import iamp
    prob = iamp.load_scenario("paper-2")          # a built-in name or a TOML path
    plan = iamp.plan(prob)                        # PMP by default -> iamp.Plan
    plan.status, plan.cost, plan.contact_times, plan.jumps, plan.safety
    plan.states(t), plan.inputs(t)                # at any times in [0, tf]
    plan.to_json()                                # the object of SPEC §5 and §9
    iamp.plan_batch([prob1, prob2, ...])          # many one-vehicle plans at once (arrays)
    iamp.PMPPlanner(max_boxes=5000).plan(prob)    # the PMP planner with its options
    iamp.compare(prob).to_json()                  # an iamp.Comparison; the object of SPEC §5b
    iamp.Predictor.default().predict(history)     # the cubic of SPEC §7
    iamp.animate_plan(plan, "plan.gif")           # the plan moving among its vehicles (also
                                                  # animate_episode, animate_commonroad)

Sub-packages (dependencies flow one way): :mod:`iamp.core` (problem, scenario files, plan,
status, tolerances, errors, atomic output) <- :mod:`iamp.planners`, :mod:`iamp.prediction`
<- :mod:`iamp.comparison`, :mod:`iamp.simulation` <- :mod:`iamp.cli`.
"""

from typing import TYPE_CHECKING, Any

from iamp import (
    _blas,  # first: one BLAS kernel on every x86-64 machine, before numpy loads
    status,
)
from iamp._version import __version__
from iamp.core.errors import (
    HistoryError,
    IampError,
    MissingDependencyError,
    OptionError,
    ScenarioError,
    SolverError,
)

# numpy imported before iamp with other kernels than the pinned ones: say so (iamp/_blas.py)
_blas.warn_if_unpinned()

if TYPE_CHECKING:
    from iamp.api import compare, load_scenario, plan
    from iamp.core.plan import Plan
    from iamp.core.problem import EgoBoundary, Problem, SurroundingVehicle
    from iamp.core.scenario import History, Scenario
    from iamp.planners.pmp import PMPPlanner
    from iamp.planners.pmp.batch import plan_batch
    from iamp.prediction.predictor import Prediction, Predictor

#: Public names imported on first use (PEP 562): ``import iamp`` -- which every ``iamp``
#: command runs -- costs almost nothing (issue 22 item 10).
_LAZY = {"compare": "iamp.api", "load_scenario": "iamp.api", "plan": "iamp.api", "Plan": "iamp.core.plan",
         "EgoBoundary": "iamp.core.problem", "Problem": "iamp.core.problem",
         "SurroundingVehicle": "iamp.core.problem", "History": "iamp.core.scenario",
         "Scenario": "iamp.core.scenario", "PMPPlanner": "iamp.planners.pmp",
         "plan_batch": "iamp.planners.pmp.batch", "Prediction": "iamp.prediction.predictor",
         "Predictor": "iamp.prediction.predictor", "Comparison": "iamp.comparison.agreement.judge",
         "animate_plan": "iamp.comparison.figures.animation", "animate_episode": "iamp.comparison.figures.animation",
         "animate_commonroad": "iamp.comparison.figures.animation"}

if TYPE_CHECKING:
    from iamp.comparison.agreement.judge import Comparison
    from iamp.comparison.figures.animation import animate_commonroad, animate_episode, animate_plan


__all__ = [
    "Comparison",
    "EgoBoundary",
    "History",
    "HistoryError",
    "IampError",
    "MissingDependencyError",
    "OptionError",
    "PMPPlanner",
    "Plan",
    "Prediction",
    "Predictor",
    "Problem",
    "Scenario",
    "ScenarioError",
    "SolverError",
    "SurroundingVehicle",
    "__version__",
    "animate_commonroad",
    "animate_episode",
    "animate_plan",
    "compare",
    "load_scenario",
    "plan",
    "plan_batch",
    "status",
]



def __getattr__(name: str) -> Any:
    """The names of :data:`_LAZY`, imported on first use."""
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'iamp' has no attribute {name!r}")
    import importlib

    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))
