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
    iamp.compare(prob).to_json()                  # the object of SPEC §5b's compare
    iamp.Predictor.default().predict(history)     # the cubic of SPEC §7

Sub-packages (dependencies flow one way): :mod:`iamp.core` (problem, scenario files, plan,
status, tolerances, errors, atomic output) <- :mod:`iamp.planners`, :mod:`iamp.prediction`
<- :mod:`iamp.comparison`, :mod:`iamp.simulation` <- :mod:`iamp.cli`.
"""

from typing import TYPE_CHECKING, Any

from iamp import status
from iamp._version import __version__
from iamp.api import compare, load_scenario, plan
from iamp.core.errors import (
    HistoryError,
    IampError,
    MissingDependencyError,
    OptionError,
    ScenarioError,
    SolverError,
)
from iamp.core.plan import Plan
from iamp.core.problem import EgoBoundary, Problem, SurroundingVehicle
from iamp.core.scenario import History, Scenario
from iamp.prediction.predictor import Prediction, Predictor

if TYPE_CHECKING:
    from iamp.comparison.agreement.judge import Comparison


def __getattr__(name: str) -> Any:
    """``iamp.Comparison`` (what :func:`iamp.compare` returns), imported on first use."""
    if name == "Comparison":
        from iamp.comparison.agreement.judge import Comparison

        return Comparison
    raise AttributeError(f"module 'iamp' has no attribute {name!r}")


__all__ = [
    "Comparison",
    "EgoBoundary",
    "History",
    "HistoryError",
    "IampError",
    "MissingDependencyError",
    "OptionError",
    "Plan",
    "Prediction",
    "Predictor",
    "Problem",
    "Scenario",
    "ScenarioError",
    "SolverError",
    "SurroundingVehicle",
    "__version__",
    "compare",
    "load_scenario",
    "plan",
    "status",
]
