"""The avoidance QP: true collision avoidance with linear inequalities (and its PMP side)."""

from __future__ import annotations

from .planner import AvoidQPPlanner

__all__ = ["AvoidQPPlanner"]
