r"""The diagnostics of an equality-QP plan and of a bounded QP plan (SPEC §14): :class:`QPDiagnostics`.

A QP plan is ``optimal`` only after the KKT conditions of its best candidate were recomputed
from the QP data :math:`(P, q, A, l, u)` and the solver's primal/dual pair :math:`(z, y)`:
stationarity :math:`\|Pz + q + A^\top y\|_\infty`, primal feasibility and complementarity,
each relative and against the backend's tolerance (:attr:`~iamp.core.diagnostics.Diagnostics.checks`),
and after the sweep showed that no unverified candidate could beat the best.
"""

from __future__ import annotations

from dataclasses import dataclass

from iamp.core.diagnostics import Diagnostics, Record


@dataclass(frozen=True)
class QPDiagnostics(Diagnostics):
    """What the equality / bounded QP planner reports.

    Attributes
    ----------
    path : str or None
        The backend path (native solver or cvxpy).
    sweep : list of (nodes, cost) or None
        Every solved candidate of the contact-node sweep: the nodes and the cost [m²/s³].
    failures : list of (nodes, status) or None
        The candidates that did not solve to a verified optimum, with their status.
    candidates : mapping or None
        ``{"total", "solved", "failed"}``: how many node combinations were tried / verified.
    unpolished : int or None
        Verified candidates the solver could not polish.
    n_solves : int or None
        QP solves, the refine's included.
    grid_best : mapping or None
        The best sweep candidate: ``contact_times`` [s] and ``cost`` [m²/s³] (before a refine).
    refine_certificate : mapping or None
        Whether the refined contact times are the global optimum (``global``, ``reason``).
    could_beat : list of mapping or None
        Unverified candidates whose lower bound :math:`J_{PMP}` is below the best cost.
    best_unverified_search : mapping or None
        The best candidate of a sweep that could not be certified.
    limit_rows : mapping or None
        The bound rows of a bounded QP (SPEC §14): which bounds, how many rows.
    limits_between_nodes : mapping or None
        Per ``vx``/``y`` bound, the largest violation between the grid nodes (m/s, m).
    solver_time_s, polished, iterations, solver_status : optional
        One solve at given nodes/times: the backend's time [s], polish flag, iterations, raw status.
    """

    path: str | None = None
    sweep: list[tuple[tuple[int, ...], float]] | None = None
    failures: list[tuple[tuple[int, ...], str]] | None = None
    candidates: Record | None = None
    unpolished: int | None = None
    n_solves: int | None = None
    grid_best: Record | None = None
    refine_certificate: Record | None = None
    could_beat: list[Record] | None = None
    best_unverified_search: Record | None = None
    limit_rows: Record | None = None
    limits_between_nodes: Record | None = None
    solver_time_s: float | None = None
    polished: bool | None = None
    iterations: int | None = None
    solver_status: str | None = None
