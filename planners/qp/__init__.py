"""The convex baseline: the lane change discretised as a QP (FOH/ZOH holds), its contact-time
sweep, its exact continuous-time trajectory and the QP backends (:mod:`.backends`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .planner import HOLDS, CandidateResult, DiscretisedQP, HoldTrajectory, QPPlanner, SweepResult, aligned_grid

__all__ = ["HOLDS", "CandidateResult", "DiscretisedQP", "HoldTrajectory", "QPPlanner", "SweepResult", "aligned_grid"]


def __getattr__(name: str) -> Any:
    """The planner's names on first use: importing :mod:`.options` or :mod:`.hold` (the registry
    and ``iamp plan``'s parser do) must not import :mod:`scipy.optimize` and the QP backends
    (issue 22 item 10)."""
    if name in __all__:
        from . import planner

        return getattr(planner, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
