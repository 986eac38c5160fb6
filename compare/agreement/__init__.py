"""Agreement of the PMP and the QP baselines on one problem: runs, fingerprints, gaps, signs and
the verdict rules.
"""

from __future__ import annotations

from .judge import (
    VERDICT_AGREE,
    VERDICT_DISAGREE,
    ProblemComparison,
    QPConfig,
    Run,
    compare_pmp_qp,
    compare_problem,
    compare_qp_qp,
    default_configs,
    run_pmp,
    run_qp,
)

__all__ = [
    "VERDICT_AGREE",
    "VERDICT_DISAGREE",
    "ProblemComparison",
    "QPConfig",
    "Run",
    "compare_pmp_qp",
    "compare_problem",
    "compare_qp_qp",
    "default_configs",
    "run_pmp",
    "run_qp",
]
