r"""The diagnostics of an avoidance plan (node-only or continuous-time safety, or the avoidance
PMP): :class:`AvoidDiagnostics`.

An avoidance QP plan is ``optimal`` only after the KKT conditions of its final QP were recomputed
from :math:`(P, q, A, l, u)` and :math:`(z, y)` (``kkt``, each relative, against ``kkt_tol``),
no relaxed row binds, and its own §9 safety report is intrusion-free.
"""

from __future__ import annotations

from dataclasses import dataclass

from iamp.core.diagnostics import Record
from iamp.planners.qp.diagnostics import QPDiagnostics


@dataclass(frozen=True)
class AvoidDiagnostics(QPDiagnostics):
    """What the avoidance planners report (besides the QP sweep fields they share).

    Attributes
    ----------
    safety_mode : str or None
        ``"continuous"`` for the continuous-time safety (branch and bound over crossing times).
    search : mapping or None
        The crossing-time search record (method, boxes, bounds, closed).
    avoidance : mapping or None
        The JSON ``avoidance`` object: per vehicle the half-planes, crossing time [s] and
        binding rows, the KKT residuals and their tolerance.
    kkt : mapping of str to float or None
        The relative KKT residuals of the final QP (stationarity, primal, dual, complementarity).
    kkt_tol : float or None
        The backend's tolerance they are judged against.
    failed_checks : list of str or None
        Every failed check (``failed_check`` is the first).
    solver_iterations : int or None
        Iterations of the final solve.
    complete_sweep, pruned : bool or None
        Whether the crossing-time sweep covered every candidate / was pruned by the certificate.
    certificate : str or None
        Why the unconstrained optimum is the global optimum (every inequality holds).
    qp_solution : object or None
        The final QP and its primal/dual pair (for independent checks).
    """

    safety_mode: str | None = None
    search: Record | None = None
    avoidance: Record | None = None
    kkt: Record | None = None
    kkt_tol: float | None = None
    failed_checks: list[str] | None = None
    solver_iterations: int | None = None
    complete_sweep: bool | None = None
    pruned: bool | None = None
    certificate: str | None = None
    qp_solution: object = None
