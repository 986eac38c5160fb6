"""The status vocabulary of every plan (re-exported from :mod:`iamp.core.status`)."""

from iamp.core.status import (
    INACCURATE,
    INFEASIBLE,
    LOCAL,
    MAX_ITER,
    NUMERICAL_ERROR,
    OPTIMAL,
    SOLVER_ERROR,
    STATUSES,
    SUCCESS,
    TIME_LIMIT,
    UNSAFE,
)

__all__ = ["INACCURATE", "INFEASIBLE", "LOCAL", "MAX_ITER", "NUMERICAL_ERROR", "OPTIMAL", "SOLVER_ERROR",
           "STATUSES", "SUCCESS", "TIME_LIMIT", "UNSAFE"]
