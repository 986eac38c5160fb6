"""One status vocabulary for every planner and every solver path (SPEC §5).

A plan is :data:`OPTIMAL` only after it checked itself: the residual of every condition it
solved, recomputed from its own solution, is inside the tolerance table
(:mod:`iamp.core.tolerances`).  Anything else is a named failure; a failed plan never
reports a cost.
"""

from __future__ import annotations

from typing import Final

#: Every condition solved and verified; for a contact-time search, the global optimum.
OPTIMAL: Final = "optimal"
#: Verified at its contact times, but the contact-time search could not certify that the
#: minimum is global (SPEC §1 asks for the global minimiser).
LOCAL: Final = "local"
#: A solution exists but a recomputed residual exceeds its tolerance.
INACCURATE: Final = "inaccurate"
#: No feasible plan exists (e.g. the ego starts or ends inside a safety region, SPEC §10).
INFEASIBLE: Final = "infeasible"
#: The solver stopped at its iteration limit.
MAX_ITER: Final = "maximum_iterations_reached"
#: The solver stopped at its time limit.
TIME_LIMIT: Final = "time_limit_reached"
#: The linear algebra broke down (singular system, overflow, NaN).
NUMERICAL_ERROR: Final = "numerical_error"
#: A verified plan that exceeds a given physical bound its planner cannot impose (SPEC §14;
#: the peaks are in ``info["limits"]``).
LIMITS_VIOLATED: Final = "limits_violated"
#: Any other solver failure.
SOLVER_ERROR: Final = "solver_error"
#: A verified solution of the problem as posed whose own safety report (SPEC §9) finds an
#: intrusion (SPEC §14: node-only avoidance, ``--constraint active`` that could not make the
#: plan safe).  The plan and its cost are reported; exit status 3.
UNSAFE: Final = "unsafe"

STATUSES: Final = (OPTIMAL, LOCAL, INACCURATE, INFEASIBLE, MAX_ITER, TIME_LIMIT, NUMERICAL_ERROR, SOLVER_ERROR,
                   UNSAFE, LIMITS_VIOLATED)

#: Statuses that carry a verified plan (a cost is reported).
SUCCESS: Final = frozenset({OPTIMAL, LOCAL})
