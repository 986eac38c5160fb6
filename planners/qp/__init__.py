"""The convex baseline: the lane change discretised as a QP (FOH/ZOH holds), its contact-time
sweep, its exact continuous-time trajectory and the QP backends (:mod:`.backends`).
"""

from __future__ import annotations

from .planner import HOLDS, CandidateResult, DiscretisedQP, HoldTrajectory, QPPlanner, SweepResult, aligned_grid

__all__ = ["HOLDS", "CandidateResult", "DiscretisedQP", "HoldTrajectory", "QPPlanner", "SweepResult", "aligned_grid"]
