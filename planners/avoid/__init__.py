"""The avoidance QP: true collision avoidance with linear inequalities (and its PMP side)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .planner import AvoidQPPlanner

__all__ = ["AvoidQPPlanner"]


def __getattr__(name: str) -> Any:
    """The planner on first use: importing :mod:`.options` (the registry does) must not import
    the solvers and :mod:`scipy.optimize` (issue 22 item 10: ``iamp plan`` with the PMP)."""
    if name == "AvoidQPPlanner":
        from .planner import AvoidQPPlanner

        return AvoidQPPlanner
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
