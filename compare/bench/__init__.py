"""``iamp bench``: the speed numbers, their peers, and the text report."""

from __future__ import annotations

from .run import osqp_tuning, run_bench
from .text import format_bench

__all__ = ["format_bench", "osqp_tuning", "run_bench"]
